//! Patching a cut into the layout: the particles a cut removed are frozen in their dense
//! slots, the clusters it despawned free their slots and the clusters it rebuilt take
//! slots of their own — every other particle and cluster keeps its place, so nothing
//! derived from the dense indices has to be rebuilt.

use super::rebuild::{dense_members, solver_compliance};
use super::{BodyDense, BodyItem, ClusterSlots, LayoutChanges, SolverLayout, dense_owner};
use crate::body::lattice::Lattice;
use crate::config::SolverMode;
use crate::ecs::components::ParticleClusters;
use crate::ecs::resources::BodyCutReport;
use crate::solver::clusters::plastic::PlasticSpec;
use crate::solver::clusters::term::ClusterSpec;
use crate::solver::particles::Particles;
use crate::solver::solve::Solver;
use bevy_ecs::prelude::*;
use glam::Quat;

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
            clusters: mut changed,
            removed,
            indices,
        } = changes;
        if !solver.clusters.can_patch() {
            return false;
        }
        let body_index = |layout: &Self, body: Entity| {
            layout.bodies.binary_search_by_key(&body, |b| b.body).ok()
        };
        // Particles cut from their bodies: frozen, and no longer offered to detect.
        let mut retired = Vec::new();
        for &body in changed_bodies {
            let (Some(b), Ok((_, lattice, _))) = (body_index(self, body), bodies.get(body)) else {
                return false;
            };
            let lattice = &lattice.lattice;
            let entry = &self.bodies[b];
            if entry.dense.len() != lattice.len() {
                return false; // a replaced lattice: not a cut
            }
            if !retired_from_report(entry, lattice, cut, &self.live, &mut retired)
                && !retired_by_scan(entry, lattice, &self.live, &mut retired)
            {
                return false;
            }
            self.bodies[b].live = lattice.live_count();
        }
        let mut removed_slots: Vec<u32> = removed
            .iter()
            .filter_map(|e| self.slot_of.remove(*e, &self.clusters))
            .collect();
        // (by body and key: an order that does not depend on the entities' ids)
        changed.sort_unstable_by_key(|(_, _, of, _)| (of.body, of.key));
        let mut flat = Vec::new();
        let mut entries = Vec::with_capacity(changed.len());
        for (e, members, of, compliance) in changed {
            let (Some(b), Ok((_, _, body))) = (body_index(self, of.body), bodies.get(of.body))
            else {
                return false;
            };
            let rotation = match self.slot_of.remove(e, &self.clusters) {
                Some(slot) => {
                    removed_slots.push(slot);
                    solver.clusters.rotations()[slot as usize]
                }
                None => Quat::IDENTITY,
            };
            let start = flat.len();
            dense_members(&self.bodies[b].dense, &members.0, &mut flat);
            entries.push((
                e,
                start..flat.len(),
                solver_compliance(compliance),
                rotation,
                body.material.yielding(),
            ));
        }
        // (a changed cluster starts again from its lattice shape)
        let specs: Vec<ClusterSpec> = entries
            .iter()
            .map(|(_, range, compliance, rotation, yielding)| ClusterSpec {
                members: &flat[range.clone()],
                compliance: *compliance,
                rotation: *rotation,
                plastic: yielding.map(|yielding| PlasticSpec {
                    yielding,
                    shift: &[],
                }),
            })
            .collect();
        // Reading the neighbours off the index costs ≈ 18 instructions per membership of
        // a removed or added cluster, the layout's pass ≈ 7.6 per membership of the
        // layout; but the index is read at random (cache misses) on one thread and the
        // pass streams on all, so the index is only chosen for cuts well below a
        // twelfth of the layout.
        let touched: usize = removed_slots
            .iter()
            .map(|k| solver.clusters.cluster_members(*k as usize).len())
            .sum::<usize>()
            + flat.len();
        let clusters_of = &mut solver.clusters;
        let patched = if clusters_of.mode() == SolverMode::Jacobi
            && touched * 12 < clusters_of.membership_count()
        {
            let kept = KeptClusters {
                layout: self,
                indices: &indices,
            };
            clusters_of
                .patch_with_neighbours(&removed_slots, &specs, |particles| kept.holding(particles))
        } else {
            clusters_of.patch(&removed_slots, &specs)
        };
        let Some(slots) = patched else {
            self.clusters.clear(); // warm starts no longer match their slots
            return false;
        };
        // cut particles stay in their slots, frozen (no entity loads them again)
        for &d in &retired {
            self.live[d as usize] = false;
            particles.inv_mass[d as usize] = 0.0;
        }
        for &slot in &removed_slots {
            self.clusters[slot as usize] = Entity::PLACEHOLDER;
        }
        for ((e, ..), slot) in entries.iter().zip(slots) {
            if slot == u32::MAX {
                continue;
            }
            if self.clusters.len() <= slot as usize {
                self.clusters.resize(slot as usize + 1, Entity::PLACEHOLDER);
            }
            self.clusters[slot as usize] = *e;
            self.slot_of.insert(*e, slot);
        }
        true
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
