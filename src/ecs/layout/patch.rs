//! Patching a cut into the layout: the particles a cut removed are frozen in their dense
//! slots, the clusters it despawned free their slots and the clusters it rebuilt take
//! slots of their own — every other particle and cluster keeps its place, so nothing
//! derived from the dense indices has to be rebuilt.

use super::rebuild::{dense_members, solver_compliance};
use super::{
    BodyDense, BodyItem, ClusterItem, ClusterSlots, LayoutChanges, SolverLayout, dense_owner,
};
use crate::body::lattice::Lattice;
use crate::config::{SolverMode, Yield};
use crate::ecs::components::ParticleClusters;
use crate::ecs::resources::BodyCutReport;
use crate::solver::clusters::plastic::PlasticSpec;
use crate::solver::clusters::term::ClusterSpec;
use crate::solver::particles::Particles;
use crate::solver::solve::Solver;
use bevy_ecs::prelude::*;
use glam::Quat;
use std::ops::Range;

/// The clusters a patch lays out again, their members in one flat array.
struct ChangedClusters {
    flat: Vec<u32>,
    entries: Vec<ChangedCluster>,
}

/// One cluster a patch lays out again.
struct ChangedCluster {
    entity: Entity,
    /// Its members' range in the flat array.
    members: Range<usize>,
    compliance: f32,
    /// Its warm-start rotation (kept from its old slot, if it had one).
    rotation: Quat,
    /// Its body's plasticity.
    yielding: Option<Yield>,
}

impl ChangedClusters {
    /// The clusters as the solver takes them (a changed cluster starts again from its
    /// lattice shape).
    fn specs(&self) -> Vec<ClusterSpec<'_>> {
        (self.entries.iter())
            .map(|c| ClusterSpec {
                members: &self.flat[c.members.clone()],
                compliance: c.compliance,
                rotation: c.rotation,
                plastic: c.yielding.map(|yielding| PlasticSpec {
                    yielding,
                    shift: &[],
                }),
            })
            .collect()
    }
}

impl SolverLayout {
    /// Patches the changed clusters and cut particles into the layout, `solver` and
    /// `particles`; false when a full rebuild is needed (a body the layout does not
    /// know, or the colouring overflows).
    pub(super) fn patch(
        &mut self,
        solver: &mut Solver,
        particles: &mut Particles,
        bodies: &Query<BodyItem>,
        changes: LayoutChanges,
    ) -> bool {
        let LayoutChanges {
            bodies: changed_bodies,
            cut,
            clusters: changed,
            removed,
            indices,
        } = changes;
        if !solver.clusters.can_patch() {
            return false;
        }
        let Some(retired) = self.retired(bodies, changed_bodies, cut) else {
            return false;
        };
        let mut freed: Vec<u32> = removed
            .iter()
            .filter_map(|e| self.slot_of.remove(*e, &self.clusters))
            .collect();
        let Some(changed) = self.changed_clusters(solver, bodies, changed, &mut freed) else {
            return false;
        };
        let Some(slots) = self.patch_clusters(solver, &freed, &changed, &indices) else {
            self.clusters.clear(); // warm starts no longer match their slots
            return false;
        };
        // cut particles stay in their slots, frozen (no entity loads them again)
        for &d in &retired {
            self.live[d as usize] = false;
            particles.inv_mass[d as usize] = 0.0;
        }
        for &slot in &freed {
            self.clusters[slot as usize] = Entity::PLACEHOLDER;
        }
        for (c, slot) in changed.entries.iter().zip(slots) {
            if slot == u32::MAX {
                continue;
            }
            if self.clusters.len() <= slot as usize {
                self.clusters.resize(slot as usize + 1, Entity::PLACEHOLDER);
            }
            self.clusters[slot as usize] = c.entity;
            self.slot_of.insert(c.entity, slot);
        }
        true
    }

    /// The body of `body` in the layout, by its index.
    fn body_index(&self, body: Entity) -> Option<usize> {
        self.bodies.binary_search_by_key(&body, |b| b.body).ok()
    }

    /// The dense particles the changed bodies lost (frozen, and no longer offered to
    /// detect), each body's live count brought up to date; `None` when a body is not
    /// the layout's or its lattice was replaced rather than cut.
    fn retired(
        &mut self,
        bodies: &Query<BodyItem>,
        changed_bodies: &[Entity],
        cut: &[BodyCutReport],
    ) -> Option<Vec<u32>> {
        let mut retired = Vec::new();
        for &body in changed_bodies {
            let (Some(b), Ok((_, lattice, _))) = (self.body_index(body), bodies.get(body)) else {
                return None;
            };
            let lattice = &lattice.lattice;
            let entry = &self.bodies[b];
            if entry.dense.len() != lattice.len() {
                return None; // a replaced lattice: not a cut
            }
            if !retired_from_report(entry, lattice, cut, &self.live, &mut retired)
                && !retired_by_scan(entry, lattice, &self.live, &mut retired)
            {
                return None;
            }
            self.bodies[b].live = lattice.live_count();
        }
        Some(retired)
    }

    /// The changed clusters, in the order of their body and key (not of their entities'
    /// ids); the slots of those the layout had are added to `freed` (each keeps its
    /// warm-start rotation). `None` when one's body is not the layout's.
    fn changed_clusters(
        &mut self,
        solver: &Solver,
        bodies: &Query<BodyItem>,
        mut changed: Vec<ClusterItem>,
        freed: &mut Vec<u32>,
    ) -> Option<ChangedClusters> {
        changed.sort_unstable_by_key(|(_, _, of, _)| (of.body, of.key));
        let mut out = ChangedClusters {
            flat: Vec::new(),
            entries: Vec::with_capacity(changed.len()),
        };
        for (e, members, of, compliance) in changed {
            let (Some(b), Ok((_, _, body))) = (self.body_index(of.body), bodies.get(of.body))
            else {
                return None;
            };
            let rotation = match self.slot_of.remove(e, &self.clusters) {
                Some(slot) => {
                    freed.push(slot);
                    solver.clusters.rotations()[slot as usize]
                }
                None => Quat::IDENTITY,
            };
            let start = out.flat.len();
            dense_members(&self.bodies[b].dense, &members.0, &mut out.flat);
            out.entries.push(ChangedCluster {
                entity: e,
                members: start..out.flat.len(),
                compliance: solver_compliance(compliance),
                rotation,
                yielding: body.material.yielding(),
            });
        }
        Some(out)
    }

    /// Frees the `freed` slots of the solver's clusters and lays the `changed` ones in;
    /// the slot each took, or `None` when the colouring overflowed.
    fn patch_clusters(
        &self,
        solver: &mut Solver,
        freed: &[u32],
        changed: &ChangedClusters,
        indices: &[(Entity, &ParticleClusters)],
    ) -> Option<Vec<u32>> {
        let specs = changed.specs();
        // Reading the neighbours off the index costs ≈ 18 instructions per membership of
        // a removed or added cluster, the layout's pass ≈ 7.6 per membership of the
        // layout; but the index is read at random (cache misses) on one thread and the
        // pass streams on all, so the index is only chosen for cuts well below a
        // twelfth of the layout.
        let clusters = &mut solver.clusters;
        let touched: usize = freed
            .iter()
            .map(|k| clusters.cluster_members(*k as usize).len())
            .sum::<usize>()
            + changed.flat.len();
        if clusters.mode() == SolverMode::Jacobi && touched * 12 < clusters.membership_count() {
            let kept = KeptClusters {
                layout: self,
                indices,
            };
            clusters.patch_with_neighbours(freed, &specs, |particles| kept.holding(particles))
        } else {
            clusters.patch(freed, &specs)
        }
    }
}

/// What finds the kept clusters of particles: the layout (its clusters are being
/// patched in the solver meanwhile) and the bodies' particle → clusters indices.
struct KeptClusters<'a> {
    layout: &'a SolverLayout,
    indices: &'a [(Entity, &'a ParticleClusters)],
}

impl KeptClusters<'_> {
    /// The slots of the kept clusters (those still in the slot table) that hold one of
    /// the dense `particles`, read off the indices. A slot may appear more than once
    /// (the patch sorts and deduplicates the list, so no flag vector over all clusters
    /// is cleared here for every cut).
    fn holding(&self, particles: &[u32]) -> Vec<u32> {
        let SolverLayout {
            locals,
            bodies,
            clusters,
            slot_of,
            ..
        } = self.layout;
        let slot_of: &ClusterSlots = slot_of;
        let mut found = Vec::new();
        // (a cut touches one body, or a few: its index is looked up again only on a change)
        let mut body_index: Option<(Entity, &ParticleClusters)> = None;
        for &d in particles {
            let Some((body, local)) = dense_owner(locals, bodies, d as usize) else {
                continue;
            };
            if body_index.is_none_or(|(b, _)| b != body) {
                body_index = self
                    .indices
                    .binary_search_by_key(&body, |(b, _)| *b)
                    .ok()
                    .map(|i| self.indices[i]);
            }
            let Some((_, index)) = body_index else {
                continue;
            };
            found.extend(
                index
                    .clusters_of(local)
                    .filter_map(|e| slot_of.get(e, clusters)),
            );
        }
        found
    }
}

/// Appends to `retired` the dense particles of `entry`'s body that the cut report lists
/// and that the layout still has live while the lattice does not, when they are all the
/// particles the body lost since the layout last counted (a lattice only ever loses
/// particles); otherwise appends nothing and returns false.
fn retired_from_report(
    entry: &BodyDense,
    lattice: &Lattice,
    cut: &[BodyCutReport],
    live: &[bool],
    retired: &mut Vec<u32>,
) -> bool {
    let mut found: Vec<u32> = cut
        .iter()
        .filter(|r| r.body == entry.body)
        .flat_map(|r| &r.removed)
        .filter_map(|&local| {
            let d = *entry.dense.get(local as usize)?;
            (d != u32::MAX && live[d as usize] && !lattice.is_live(local)).then_some(d)
        })
        .collect();
    found.sort_unstable();
    found.dedup();
    if entry.live.checked_sub(lattice.live_count()) != Some(found.len()) {
        return false;
    }
    retired.extend(found);
    true
}

/// Appends to `retired` every dense particle of `entry`'s body that the layout has live
/// and the lattice does not, by a pass over all the body's particles; false when the
/// lattice has a live particle the layout never had.
fn retired_by_scan(
    entry: &BodyDense,
    lattice: &Lattice,
    live: &[bool],
    retired: &mut Vec<u32>,
) -> bool {
    for (local, &d) in entry.dense.iter().enumerate() {
        let is_live = lattice.is_live(local as u32);
        if d == u32::MAX {
            if is_live {
                return false; // a particle the layout never had
            }
        } else if live[d as usize] && !is_live {
            retired.push(d);
        }
    }
    true
}
