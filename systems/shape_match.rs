//! Stage shape-match (SPEC §2.2): gathers particles into the dense solver layout
//! (rebuilt only when topology changes), runs the iterations with colliders, derives
//! velocities, and scatters back. Writes particle data and its own cache only.

use crate::components::*;
use crate::config::SolverMode;
use crate::resources::{SimSettings, SolverCache};
use crate::solver::{ClusterSpec, Colliders, SolverLayout};
use bevy_ecs::prelude::*;
use glam::{Quat, Vec3, Vec3A};
use std::collections::HashMap;

/// Clusters that changed since the last run (any body).
type TopologyChanged<'w, 's> = Query<
    'w,
    's,
    (),
    Or<(
        Changed<ClusterMembers>,
        Changed<Stiffness>,
        Changed<BodyLattice>,
    )>,
>;

/// One solver substep over all bodies.
#[allow(clippy::too_many_arguments)]
pub fn shape_match(
    settings: Res<SimSettings>,
    mut cache: ResMut<SolverCache>,
    bodies: Query<(Entity, &BodyLattice)>,
    clusters: Query<(Entity, &ClusterMembers, &ClusterOf, &Stiffness)>,
    changed: TopologyChanged,
    mut removed_clusters: RemovedComponents<ClusterMembers>,
    mut removed_bodies: RemovedComponents<BodyLattice>,
    mut particles: Query<(
        Entity,
        &mut Position,
        &mut Velocity,
        &PrevPosition,
        &InvMass,
    )>,
) {
    let removed = removed_clusters.read().count() + removed_bodies.read().count() > 0;
    let config = &settings.0;
    if !cache.valid || removed || !changed.is_empty() || cache.layout.mode() != config.solver {
        rebuild(&mut cache, &bodies, &clusters, config.solver);
    }
    let cache = &mut *cache;
    for (e, x, v, prev, inv_mass) in &particles {
        if let Some(&d) = cache.dense_of.get(e.index_u32() as usize)
            && d != u32::MAX
        {
            cache.layout.positions[d as usize] = Vec3A::from(x.0);
            cache.layout.previous[d as usize] = Vec3A::from(prev.0);
            cache.layout.velocities[d as usize] = Vec3A::from(v.0);
            cache.layout.inv_mass[d as usize] = inv_mass.0;
        }
    }
    let colliders = Colliders {
        ground: config.ground,
        boxes: config.boxes.clone(),
    };
    cache.layout.solve(config.iterations, &colliders);
    cache
        .layout
        .update_velocities(config.substeps as f32 / config.dt);
    for (e, mut x, mut v, _, _) in &mut particles {
        if let Some(&d) = cache.dense_of.get(e.index_u32() as usize)
            && d != u32::MAX
        {
            x.0 = Vec3::from(cache.layout.positions[d as usize]);
            v.0 = Vec3::from(cache.layout.velocities[d as usize]);
        }
    }
}

/// One cluster while the layout is rebuilt: sort key `(body, first dense member,
/// entity)`, its members' range in the flat member array, and its stiffness.
struct ClusterEntry {
    order: (Entity, u32, Entity),
    range: std::ops::Range<usize>,
    stiffness: f32,
}

/// Rebuilds the dense layout from the ECS, keeping warm-start rotations by cluster.
#[inline(never)]
fn rebuild(
    cache: &mut SolverCache,
    bodies: &Query<(Entity, &BodyLattice)>,
    clusters: &Query<(Entity, &ClusterMembers, &ClusterOf, &Stiffness)>,
    mode: SolverMode,
) {
    let warm: HashMap<Entity, Quat> = cache
        .clusters
        .iter()
        .copied()
        .zip(cache.layout.rotations.iter().copied())
        .collect();
    let mut body_list: Vec<(Entity, &BodyLattice)> = bodies.iter().collect();
    body_list.sort_unstable_by_key(|(e, _)| *e);
    let mut rest = Vec::new();
    let mut particles = Vec::new();
    let mut owners = Vec::new();
    let mut local_to_dense: HashMap<Entity, Vec<u32>> = HashMap::new();
    for (body, lattice) in &body_list {
        let l = &lattice.lattice;
        let mut map = vec![u32::MAX; l.len()];
        // Morton order keeps the members of a cluster, and the clusters of a particle,
        // close in memory.
        let mut order: Vec<u32> = l.live_particles().collect();
        order.sort_by_cached_key(|i| morton_code(l.coord(*i)));
        for i in order {
            map[i as usize] = rest.len() as u32;
            rest.push(l.rest_position(i));
            particles.push(lattice.particles[i as usize]);
            owners.push((*body, i));
        }
        local_to_dense.insert(*body, map);
    }
    // Every cluster's dense members in one flat array (no allocation per cluster).
    let total: usize = clusters.iter().map(|(_, m, _, _)| m.0.len()).sum();
    let mut flat: Vec<u32> = Vec::with_capacity(total);
    let mut cluster_list: Vec<ClusterEntry> = Vec::new();
    for (e, members, of, stiffness) in clusters {
        let Some(map) = local_to_dense.get(&of.0) else {
            continue;
        };
        let start = flat.len();
        flat.extend(
            members
                .0
                .iter()
                .filter_map(|m| map.get(*m as usize).copied().filter(|d| *d != u32::MAX)),
        );
        if let Some(&first) = flat[start..].iter().min() {
            cluster_list.push(ClusterEntry {
                order: (of.0, first, e),
                range: start..flat.len(),
                stiffness: stiffness.0.clamp(0.0, 1.0),
            });
        }
    }
    // Clusters in the order of their first member (then entity, for determinism).
    cluster_list.sort_unstable_by_key(|c| c.order);
    let specs = cluster_list.iter().map(|c| ClusterSpec {
        members: &flat[c.range.clone()],
        stiffness: c.stiffness,
        rotation: warm.get(&c.order.2).copied().unwrap_or(Quat::IDENTITY),
    });
    cache.layout = SolverLayout::new(&rest, specs, mode);
    let max_index = particles
        .iter()
        .map(|e| e.index_u32() as usize + 1)
        .max()
        .unwrap_or(0);
    cache.dense_of = vec![u32::MAX; max_index];
    for (d, e) in particles.iter().enumerate() {
        cache.dense_of[e.index_u32() as usize] = d as u32;
    }
    cache.particles = particles;
    cache.owners = owners;
    cache.clusters = cluster_list.into_iter().map(|c| c.order.2).collect();
    cache.valid = true;
}

/// Interleaves the bits of a lattice coordinate (offset to non-negative) into a
/// Z-order key.
fn morton_code(c: glam::IVec3) -> u64 {
    fn spread(v: i32) -> u64 {
        let mut x = (v as i64 + (1 << 20)) as u64 & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    }
    spread(c.x) | (spread(c.y) << 1) | (spread(c.z) << 2)
}
