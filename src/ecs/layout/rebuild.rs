//! Laying the solver out afresh from every body and cluster: bodies in entity order,
//! each body's particles in Morton order, clusters in the order of their first member —
//! keeping the clusters' warm-start rotations and plastic shifts by cluster entity.

use super::{BodyDense, BodyItem, ClusterItem, ClusterSlots, SolverLayout};
use crate::config::{SolverMode, Yield};
use crate::ecs::components::Compliance;
use crate::solver::clusters::plastic::PlasticSpec;
use crate::solver::clusters::term::{ClusterSpec, ClusterTerm};
use crate::solver::particles::Particles;
use crate::solver::solve::Solver;
use bevy_ecs::prelude::Entity;
use glam::Quat;

/// One cluster while the layout is rebuilt.
struct ClusterEntry {
    /// Sort key: body, first dense member, key.
    order: (Entity, u32, u32),
    entity: Entity,
    /// Its members' range in the flat member array.
    range: std::ops::Range<usize>,
    compliance: f32,
    /// Its body's plasticity.
    yielding: Option<Yield>,
}

impl SolverLayout {
    /// Lays the layout, `solver` (its clusters and schemes' state; the terms stay and
    /// hear of the new layout) and `particles` out afresh from `bodies` and `clusters`.
    #[inline(never)]
    pub fn rebuild<'b, 'c>(
        &mut self,
        solver: &mut Solver,
        particles: &mut Particles,
        bodies: impl Iterator<Item = BodyItem<'b>>,
        clusters: impl Iterator<Item = ClusterItem<'c>>,
        mode: SolverMode,
    ) {
        let old = std::mem::take(&mut solver.clusters);
        let mut body_list: Vec<BodyItem> = bodies.collect();
        body_list.sort_unstable_by_key(|(e, ..)| *e);
        // sized up front: grown by doubling, they would keep up to twice their length
        let total: usize = body_list
            .iter()
            .map(|(_, b, _)| b.lattice.live_count())
            .sum();
        let mut rest = Vec::with_capacity(total);
        let mut entities = Vec::with_capacity(total);
        let mut locals = Vec::with_capacity(total);
        let mut body_dense = Vec::with_capacity(body_list.len());
        for (body, lattice, _) in &body_list {
            let l = &lattice.lattice;
            let mut map = vec![u32::MAX; l.len()];
            let first = rest.len() as u32;
            // Morton order keeps the members of a cluster, and the clusters of a
            // particle, close in memory.
            for i in l.live_in_morton_order() {
                map[i as usize] = rest.len() as u32;
                rest.push(l.rest_position(i));
                entities.push(lattice.particles[i as usize]);
                locals.push(i);
            }
            body_dense.push(BodyDense {
                body: *body,
                first,
                dense: map,
                live: l.live_count(),
            });
        }
        // Every cluster's dense members in one flat array (no allocation per cluster).
        let mut flat: Vec<u32> = Vec::new();
        let mut cluster_list: Vec<ClusterEntry> = Vec::new();
        for (e, members, of, compliance) in clusters {
            let Ok(b) = body_dense.binary_search_by_key(&of.body, |b| b.body) else {
                continue;
            };
            let start = flat.len();
            dense_members(&body_dense[b].dense, &members.0, &mut flat);
            if let Some(&first) = flat[start..].iter().min() {
                cluster_list.push(ClusterEntry {
                    order: (of.body, first, of.key),
                    entity: e,
                    range: start..flat.len(),
                    compliance: solver_compliance(compliance),
                    yielding: body_list[b].2.material.yielding(),
                });
            }
        }
        // Clusters in the order of their first member (then key, for determinism).
        cluster_list.sort_unstable_by_key(|c| c.order);
        // (each cluster's old slot, by the layout's table of them: no map to build)
        let (old_slots, old_clusters) = (&self.slot_of, &self.clusters);
        let specs = cluster_list.iter().map(|c| {
            let slot = (old_slots.get(c.entity, old_clusters)).map(|k| k as usize);
            ClusterSpec {
                members: &flat[c.range.clone()],
                compliance: c.compliance,
                rotation: slot
                    .and_then(|k| old.rotations().get(k).copied())
                    .unwrap_or(Quat::IDENTITY),
                plastic: c.yielding.map(|yielding| PlasticSpec {
                    yielding,
                    shift: slot.and_then(|k| old.plastic_shift(k)).unwrap_or(&[]),
                }),
            }
        });
        // the terms stay (they hear of the new layout); the schemes' state goes with the
        // clusters it belonged to
        let terms = std::mem::take(&mut solver.terms);
        *solver = Solver::new(ClusterTerm::new(&rest, specs, mode), terms);
        particles.reset_at_rest(&rest);
        let max_index = entities
            .iter()
            .map(|e| e.index_u32() as usize + 1)
            .max()
            .unwrap_or(0);
        self.dense_of = vec![u32::MAX; max_index];
        for (d, e) in entities.iter().enumerate() {
            self.dense_of[e.index_u32() as usize] = d as u32;
        }
        self.live = vec![true; entities.len()];
        self.entities = entities;
        self.locals = locals;
        self.bodies = body_dense;
        // (collected from a borrow: `into_iter` would reuse the entries' allocation, six
        // times the size the entities need, and keep it)
        self.clusters = cluster_list.iter().map(|c| c.entity).collect();
        self.slot_of = ClusterSlots::from_clusters(&self.clusters);
        self.valid = true;
        self.version += 1;
        self.stamp = super::fresh_stamp();
    }
}

/// Appends the dense members of a cluster to `out`, given its body's dense index per
/// body-local particle (particles cut from the body are dropped).
pub(super) fn dense_members(map: &[u32], members: &[u32], out: &mut Vec<u32>) {
    out.extend(
        members
            .iter()
            .filter_map(|m| map.get(*m as usize).copied().filter(|d| *d != u32::MAX)),
    );
}

/// A cluster's compliance as the solver takes it: a negative or non-finite value
/// (written into the component by hand) counts as 0, a rigid cluster.
pub(super) fn solver_compliance(c: &Compliance) -> f32 {
    if c.0.is_finite() && c.0 > 0.0 {
        c.0
    } else {
        0.0
    }
}
