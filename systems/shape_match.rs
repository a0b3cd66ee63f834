//! Stage shape-match (SPEC §2.2): gathers particles into the dense solver layout
//! (brought up to date only when topology changes, see [`super::layout_sync`]), places
//! the colliders for this substep, runs the iterations with every constraint kind
//! (contacts, colliders), derives velocities, and scatters back. Writes particle data
//! and its own cache only.

use super::contact_sync::sync_contacts;
use super::layout_sync::{LayoutChanges, sync_layout};
use crate::components::*;
use crate::resources::{CutReport, SimSettings, SolverCache, SubstepClock};
use crate::solver::{Colliders, PosedCollider};
use crate::table_rows::ParticleColumns;
use bevy_ecs::entity::Entities;
use bevy_ecs::prelude::*;
use glam::{Vec3, Vec3A};

/// The largest speed (m/s) a particle gains from being pushed out of a collider it
/// started the substep inside: a body spawned in a collider comes out at a walk, not
/// shot out.
pub const MAX_DEPENETRATION_SPEED: f32 = 2.0;

/// Clusters that changed (or appeared) since the last run (any body).
type ChangedClusters<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static ClusterMembers,
        &'static ClusterOf,
        &'static Stiffness,
    ),
    Or<(Changed<ClusterMembers>, Changed<Stiffness>)>,
>;

/// Particle data the stage reads and writes.
type ParticleData = (
    Entity,
    &'static mut Position,
    &'static mut Velocity,
    &'static PrevPosition,
    &'static InvMass,
);

/// One solver substep over all bodies.
#[allow(clippy::too_many_arguments)]
pub fn shape_match(
    settings: Res<SimSettings>,
    substep: Res<SubstepClock>,
    mut cache: ResMut<SolverCache>,
    cut: Res<CutReport>,
    bodies: Query<(Entity, &BodyLattice)>,
    materials: Query<&Body>,
    colliders: Query<(&Collider, &ColliderPose)>,
    indices: Query<(Entity, &ParticleClusters)>,
    entities: &Entities,
    changed_bodies: Query<Entity, Changed<BodyLattice>>,
    clusters: Query<(Entity, &ClusterMembers, &ClusterOf, &Stiffness)>,
    changed_clusters: ChangedClusters,
    mut removed_clusters: RemovedComponents<ClusterMembers>,
    mut removed_bodies: RemovedComponents<BodyLattice>,
    mut particles: Query<ParticleData>,
) {
    let config = &settings.0;
    let removed: Vec<Entity> = removed_clusters.read().collect();
    if removed_bodies.read().count() > 0 {
        cache.valid = false;
    }
    let changed_bodies: Vec<Entity> = changed_bodies.iter().collect();
    if !cache.valid
        || cache.layout.mode() != config.solver
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
                let mut list: Vec<_> = indices.iter().map(|(b, i)| (b, &i.0)).collect();
                list.sort_unstable_by_key(|(b, _)| *b);
                list
            },
            entities,
        };
        sync_layout(&mut cache, &bodies, changes, clusters.iter(), config.solver);
        cache.contacts_built = None;
    }
    if cache.contacts_built != Some(config.contacts) {
        sync_contacts(&mut cache, &bodies, &materials, config.contacts);
    }
    let cache = &mut *cache;
    // Usually every particle sits in one table: its columns are copied in parallel.
    let one_table = {
        let mut tables = particles
            .contiguous_iter()
            .expect("particle components are stored in tables")
            .filter(|(entities, ..)| !entities.is_empty());
        match (tables.next(), tables.next()) {
            (Some((entities, positions, _, previous, inv_mass)), None) => {
                let table = ParticleColumns {
                    entities,
                    positions,
                    previous,
                    inv_mass,
                };
                let slots = &cache.particles;
                cache
                    .rows
                    .load(&mut cache.layout, slots, &cache.dense_of, table);
                true
            }
            _ => false,
        }
    };
    if !one_table {
        gather_entities(cache, &particles);
    }
    cache.kinds.colliders = substep_colliders(config, &substep, &colliders);
    cache.layout.solve(config.iterations, &mut cache.kinds);
    let inv_dt = config.substeps as f32 / config.dt;
    if one_table {
        let tables = particles
            .contiguous_iter_mut()
            .expect("particle components are stored in tables");
        for (_, mut positions, mut velocities, ..) in tables {
            if !positions.is_empty() {
                cache
                    .rows
                    .store(&cache.layout, inv_dt, &mut positions, &mut velocities);
            }
        }
    } else {
        scatter_entities(cache, inv_dt, &mut particles);
    }
}

/// The ground, the config's static boxes and every collider entity, placed for this
/// substep (a kinematic collider moves from its frame-start pose to its frame-end pose
/// over the substeps).
fn substep_colliders(
    config: &crate::config::SimConfig,
    substep: &SubstepClock,
    entities: &Query<(&Collider, &ColliderPose)>,
) -> Colliders {
    let count = substep.count.max(1) as f32;
    let (t0, t1) = (
        substep.index as f32 / count,
        (substep.index + 1) as f32 / count,
    );
    let moving = entities.iter().map(|(c, pose)| {
        let (start, end) = (
            pose.last.lerp(&pose.current, t0),
            pose.last.lerp(&pose.current, t1),
        );
        PosedCollider::new(c.shape.clone(), c.friction, start, end)
    });
    let mut colliders = Colliders::from_config(config, moving);
    colliders.depenetration_step = MAX_DEPENETRATION_SPEED * config.dt / count;
    colliders
}

/// Copies particle state into the layout entity by entity (particles in several tables).
fn gather_entities(cache: &mut SolverCache, particles: &Query<ParticleData>) {
    for (e, x, _, prev, inv_mass) in particles {
        if let Some(&d) = cache.dense_of.get(e.index_u32() as usize)
            && d != u32::MAX
        {
            cache.layout.positions[d as usize] = Vec3A::from(x.0);
            cache.layout.previous[d as usize] = Vec3A::from(prev.0);
            cache.layout.inv_mass[d as usize] = inv_mass.0;
        }
    }
}

/// Writes the solved positions back and adds the corrections / dt to the velocities,
/// entity by entity (particles in several tables).
fn scatter_entities(cache: &SolverCache, inv_dt: f32, particles: &mut Query<ParticleData>) {
    for (e, mut x, mut v, _, _) in particles {
        if let Some(&d) = cache.dense_of.get(e.index_u32() as usize)
            && d != u32::MAX
        {
            x.0 = Vec3::from(cache.layout.positions[d as usize]);
            v.0 += Vec3::from(cache.layout.corrections[d as usize] * inv_dt);
        }
    }
}
