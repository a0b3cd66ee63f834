//! Keeps the solver's dense layout in step with the ECS, once at the start of each
//! frame ([`sync_solver`], in its own [`crate::systems::SyncSchedule`] so that saving a
//! simulation can bring the layout up to date the same way): a full rebuild when
//! bodies appear or vanish, otherwise a patch of only the clusters that changed (after a
//! cut) and the particles that were cut. What changed is left for the terms
//! ([`super::term_sync`]) to hear.

use crate::body::lattice::Lattice;
use crate::config::SolverMode;
use crate::config::Yield;
use crate::ecs::components::*;
use crate::ecs::resources::{
    BodyCutReport, BodyDense, ClusterSlots, CutReport, LayoutUpdate, PendingTopology, SimSettings,
    SolverCache, dense_owner,
};
use crate::solver::clusters::plastic::PlasticSpec;
use crate::solver::clusters::term::{ClusterSpec, ClusterTerm};
use crate::solver::particles::Particles;
use crate::solver::solve::Solver;
use bevy_ecs::prelude::*;
use glam::Quat;
use std::collections::HashMap;
use std::time::Instant;

/// Clusters that changed (or appeared) since the last run (any body).
type ChangedClusters<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static ClusterMembers,
        &'static ClusterOf,
        &'static Compliance,
    ),
    Or<(Changed<ClusterMembers>, Changed<Compliance>)>,
>;

/// Brings the solver layout up to date with what changed in the ECS since the last run:
/// cuts, rebuilt clusters, bodies spawned or despawned, a solver setting changed; records
/// what changed for the terms. Writes the solver cache only.
///
/// After a simulation is loaded, its restored layout already matches the ECS: the first
/// run only takes note of the loaded entities as seen ([`SolverCache::adopt_changes`]).
#[allow(clippy::too_many_arguments)]
pub fn sync_solver(
    settings: Res<SimSettings>,
    mut cache: ResMut<SolverCache>,
    cut: Res<CutReport>,
    bodies: Query<BodyItem>,
    indices: Query<(Entity, &ParticleClusters)>,
    changed_bodies: Query<Entity, Changed<BodyLattice>>,
    clusters: Query<ClusterItem>,
    changed_clusters: ChangedClusters,
    mut removed_clusters: RemovedComponents<ClusterMembers>,
    mut removed_bodies: RemovedComponents<BodyLattice>,
) {
    let config = &settings.0;
    let removed: Vec<Entity> = removed_clusters.read().collect();
    let bodies_removed = removed_bodies.read().count() > 0;
    if !std::mem::take(&mut cache.adopt_changes) {
        if bodies_removed {
            cache.valid = false;
        }
        let changed_bodies: Vec<Entity> = changed_bodies.iter().collect();
        if !cache.valid
            || cache.solver.mode() != config.solver
            || !removed.is_empty()
            || !changed_bodies.is_empty()
            || !changed_clusters.is_empty()
        {
            let changes = LayoutChanges {
                bodies: &changed_bodies,
                cut: &cut.bodies,
                clusters: changed_clusters.iter().collect(),
                removed: &removed,
                indices: {
                    let mut list: Vec<_> = indices.iter().collect();
                    list.sort_unstable_by_key(|(b, _)| *b);
                    list
                },
            };
            sync_layout(&mut cache, &bodies, changes, clusters.iter(), config.solver);
        }
    }
    // (a rebuilt or a loaded solver starts from the default)
    cache.solver.projective.budget_bytes = config.memory_budget_bytes();
}

/// Body data as the layout reads it: the lattice, and the material (plasticity).
pub type BodyItem<'a> = (Entity, &'a BodyLattice, &'a Body);

/// Cluster data as the shape-match stage reads it.
pub type ClusterItem<'a> = (Entity, &'a ClusterMembers, &'a ClusterOf, &'a Compliance);

/// What changed since the layout was last brought up to date.
pub struct LayoutChanges<'a, 'c> {
    /// Bodies whose lattice changed (lost particles).
    pub bodies: &'a [Entity],
    /// The last cut's report: the particles each body lost. A hint, checked against the
    /// lattices; without it (or when it does not account for every lost particle) every
    /// particle of a changed body is looked at.
    pub cut: &'a [BodyCutReport],
    /// Clusters whose members or compliance changed, or that are new.
    pub clusters: Vec<ClusterItem<'c>>,
    /// Cluster entities that lost their members (despawned).
    pub removed: &'a [Entity],
    /// Each body's particle → clusters index, sorted by body: the clusters whose Jacobi
    /// weights a patch changes are found from it instead of by a pass over every
    /// membership of the layout.
    pub indices: Vec<(Entity, &'c ParticleClusters)>,
}

/// Brings the layout up to date: patches in the `changes` when that is possible, else
/// rebuilds it from all bodies and clusters.
pub fn sync_layout<'a>(
    cache: &mut SolverCache,
    bodies: &Query<BodyItem>,
    changes: LayoutChanges<'_, 'a>,
    all_clusters: impl Iterator<Item = ClusterItem<'a>>,
    mode: SolverMode,
) {
    let start = Instant::now();
    let changed_bodies = changes.bodies.to_vec();
    let patched = cache.valid && cache.solver.mode() == mode && patch(cache, bodies, changes);
    if !patched {
        rebuild_cache(cache, bodies.iter(), all_clusters, mode);
    }
    let pending = cache
        .pending_topology
        .get_or_insert_with(PendingTopology::default);
    pending.relaid |= !patched;
    pending.bodies.extend(changed_bodies);
    if !patched {
        cache.layout_version += 1;
    }
    cache.last_update = Some(LayoutUpdate {
        patched,
        ms: start.elapsed().as_secs_f64() * 1e3,
    });
}

/// Dense members of a cluster of `body` (dead particles dropped).
fn dense_members(map: &[u32], members: &[u32], out: &mut Vec<u32>) {
    out.extend(
        members
            .iter()
            .filter_map(|m| map.get(*m as usize).copied().filter(|d| *d != u32::MAX)),
    );
}

/// Patches the changed clusters and cut particles into the layout; false when a full
/// rebuild is needed (a body the layout does not know, or the colouring overflows).
fn patch(cache: &mut SolverCache, bodies: &Query<BodyItem>, changes: LayoutChanges) -> bool {
    let LayoutChanges {
        bodies: changed_bodies,
        cut,
        clusters: mut changed,
        removed,
        indices,
    } = changes;
    if !cache.solver.clusters.can_patch() {
        return false;
    }
    let body_index = |cache: &SolverCache, body: Entity| {
        cache
            .body_dense
            .binary_search_by_key(&body, |b| b.body)
            .ok()
    };
    // Particles cut from their bodies: frozen, and no longer offered to detect.
    let mut retired = Vec::new();
    for &body in changed_bodies {
        let (Some(b), Ok((_, lattice, _))) = (body_index(cache, body), bodies.get(body)) else {
            return false;
        };
        let lattice = &lattice.lattice;
        let entry = &cache.body_dense[b];
        if entry.dense.len() != lattice.len() {
            return false; // a replaced lattice: not a cut
        }
        if !retired_from_report(entry, lattice, cut, &cache.live, &mut retired)
            && !retired_by_scan(entry, lattice, &cache.live, &mut retired)
        {
            return false;
        }
        cache.body_dense[b].live = lattice.live_count();
    }
    let mut removed_slots: Vec<u32> = removed
        .iter()
        .filter_map(|e| cache.slot_of.remove(*e, &cache.clusters))
        .collect();
    // (by body and key: an order that does not depend on the entities' ids)
    changed.sort_unstable_by_key(|(_, _, of, _)| (of.body, of.key));
    let mut flat = Vec::new();
    let mut entries = Vec::with_capacity(changed.len());
    for (e, members, of, compliance) in changed {
        let (Some(b), Ok((_, _, body))) = (body_index(cache, of.body), bodies.get(of.body)) else {
            return false;
        };
        let rotation = match cache.slot_of.remove(e, &cache.clusters) {
            Some(slot) => {
                removed_slots.push(slot);
                cache.solver.clusters.rotations()[slot as usize]
            }
            None => Quat::IDENTITY,
        };
        let start = flat.len();
        dense_members(&cache.body_dense[b].dense, &members.0, &mut flat);
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
    // Reading the neighbours off the index costs ≈ 18 instructions per membership of a
    // removed or added cluster, the layout's pass ≈ 7.6 per membership of the layout;
    // but the index is read at random (cache misses) on one thread and the pass streams
    // on all. On the 64³ bench slice (touched ≈ memberships / 7.5) the index took 6 M
    // fewer instructions yet as long on one thread and ~25 % longer on two, so it is
    // only chosen for cuts well below that size.
    let touched: usize = removed_slots
        .iter()
        .map(|k| cache.solver.clusters.cluster_members(*k as usize).len())
        .sum::<usize>()
        + flat.len();
    let clusters_of = &mut cache.solver.clusters;
    let patched = if clusters_of.mode() == SolverMode::Jacobi
        && touched * 12 < clusters_of.membership_count()
    {
        let SolverCache {
            solver,
            locals,
            body_dense,
            clusters,
            slot_of,
            ..
        } = &mut *cache;
        let kept = KeptClusters {
            locals,
            body_dense,
            clusters,
            slot_of,
            indices: &indices,
        };
        solver
            .clusters
            .patch_with_neighbours(&removed_slots, &specs, |particles| kept.holding(particles))
    } else {
        cache.solver.clusters.patch(&removed_slots, &specs)
    };
    let Some(slots) = patched else {
        cache.clusters.clear(); // warm starts no longer match their slots
        return false;
    };
    // cut particles stay in their slots, frozen (no entity loads them again)
    for &d in &retired {
        cache.live[d as usize] = false;
        cache.particles.inv_mass[d as usize] = 0.0;
    }
    for &slot in &removed_slots {
        cache.clusters[slot as usize] = Entity::PLACEHOLDER;
    }
    for ((e, ..), slot) in entries.iter().zip(slots) {
        if slot == u32::MAX {
            continue;
        }
        if cache.clusters.len() <= slot as usize {
            cache
                .clusters
                .resize(slot as usize + 1, Entity::PLACEHOLDER);
        }
        cache.clusters[slot as usize] = *e;
        cache.slot_of.insert(*e, slot);
    }
    true
}

/// What finds the kept clusters of particles: the cache's fields it reads (the layout
/// itself is being patched meanwhile) and the bodies' particle → clusters indices.
struct KeptClusters<'a> {
    locals: &'a [u32],
    body_dense: &'a [BodyDense],
    clusters: &'a [Entity],
    slot_of: &'a ClusterSlots,
    indices: &'a [(Entity, &'a ParticleClusters)],
}

impl KeptClusters<'_> {
    /// The slots of the kept clusters (those still in `slot_of`) that hold one of the
    /// dense `particles`, read off the indices. A slot may appear more than once (the
    /// patch sorts and deduplicates the list, so no flag vector over all clusters is
    /// cleared here for every cut).
    fn holding(&self, particles: &[u32]) -> Vec<u32> {
        let mut found = Vec::new();
        // (a cut touches one body, or a few: its index is looked up again only on a change)
        let mut body_index: Option<(Entity, &ParticleClusters)> = None;
        for &d in particles {
            let Some((body, local)) = dense_owner(self.locals, self.body_dense, d as usize) else {
                continue;
            };
            if body_index.is_none_or(|(b, _)| b != body) {
                body_index = self
                    .indices
                    .binary_search_by_key(&body, |(b, _)| *b)
                    .ok()
                    .map(|i| self.indices[i]);
            }
            let Some((_, clusters)) = body_index else {
                continue;
            };
            found.extend(
                clusters
                    .clusters_of(local)
                    .filter_map(|e| self.slot_of.get(e, self.clusters)),
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

/// One cluster while the layout is rebuilt: sort key `(body, first dense member, key)`,
/// its entity, its members' range in the flat member array, its compliance and its
/// body's plasticity.
struct ClusterEntry {
    /// Body, first dense member, key.
    order: (Entity, u32, u32),
    entity: Entity,
    range: std::ops::Range<usize>,
    compliance: f32,
    yielding: Option<Yield>,
}

/// Rebuilds the dense layout from the bodies and clusters, keeping warm-start rotations
/// and plastic shifts by cluster entity.
#[inline(never)]
pub fn rebuild_cache<'b, 'c>(
    cache: &mut SolverCache,
    bodies: impl Iterator<Item = BodyItem<'b>>,
    clusters: impl Iterator<Item = ClusterItem<'c>>,
    mode: SolverMode,
) {
    let old = std::mem::take(&mut cache.solver.clusters);
    let old_slot: HashMap<Entity, usize> = (cache.clusters.iter().enumerate())
        .map(|(k, e)| (*e, k))
        .collect();
    let mut body_list: Vec<BodyItem> = bodies.collect();
    body_list.sort_unstable_by_key(|(e, ..)| *e);
    // sized up front: grown by doubling, they would keep up to twice their length
    let total: usize = body_list
        .iter()
        .map(|(_, b, _)| b.lattice.live_count())
        .sum();
    let mut rest = Vec::with_capacity(total);
    let mut particles = Vec::with_capacity(total);
    let mut locals = Vec::with_capacity(total);
    let mut body_dense = Vec::with_capacity(body_list.len());
    for (body, lattice, _) in &body_list {
        let l = &lattice.lattice;
        let mut map = vec![u32::MAX; l.len()];
        let first = rest.len() as u32;
        // Morton order keeps the members of a cluster, and the clusters of a particle,
        // close in memory.
        for i in l.live_in_morton_order() {
            map[i as usize] = rest.len() as u32;
            rest.push(l.rest_position(i));
            particles.push(lattice.particles[i as usize]);
            locals.push(i);
        }
        let live = l.live_count();
        body_dense.push(BodyDense {
            body: *body,
            first,
            dense: map,
            live,
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
    let specs = cluster_list.iter().map(|c| {
        let slot = old_slot.get(&c.entity).copied();
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
    let terms = std::mem::take(&mut cache.solver.terms);
    cache.solver = Solver::new(ClusterTerm::new(&rest, specs, mode), terms);
    cache.particles = Particles::at_rest(&rest);
    let max_index = particles
        .iter()
        .map(|e| e.index_u32() as usize + 1)
        .max()
        .unwrap_or(0);
    cache.dense_of = vec![u32::MAX; max_index];
    for (d, e) in particles.iter().enumerate() {
        cache.dense_of[e.index_u32() as usize] = d as u32;
    }
    cache.live = vec![true; particles.len()];
    cache.entities = particles;
    cache.locals = locals;
    cache.body_dense = body_dense;
    // (collected from a borrow: `into_iter` would reuse the entries' allocation, six
    // times the size the entities need, and keep it)
    cache.clusters = cluster_list.iter().map(|c| c.entity).collect();
    cache.slot_of = ClusterSlots::from_clusters(&cache.clusters);
    cache.valid = true;
}

/// A cluster's compliance as the solver takes it: a negative or non-finite value
/// (written into the component by hand) counts as 0, a rigid cluster.
fn solver_compliance(c: &Compliance) -> f32 {
    if c.0.is_finite() && c.0 > 0.0 {
        c.0
    } else {
        0.0
    }
}
