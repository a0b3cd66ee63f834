//! Stage shape-match: gathers particles into the dense solver layout
//! (which [`super::layout_sync::sync_solver`] has brought up to date at the start of the
//! frame), places the colliders for this substep, runs the iterations with every
//! constraint kind (contacts, colliders), derives velocities, and scatters back. Writes
//! particle data and its own cache only.

use crate::ecs::components::*;
use crate::ecs::resources::{ParticlesRepaired, SimSettings, SolverCache, SubstepClock};
use crate::ecs::table_rows::ParticleColumns;
use crate::solver::{Colliders, PosedCollider};
use bevy_ecs::prelude::*;
use glam::{Vec3, Vec3A};

/// The largest speed (m/s) a particle gains from being pushed out of a collider it
/// started the substep inside: a body spawned in a collider comes out at a walk, not
/// shot out.
pub const MAX_DEPENETRATION_SPEED: f32 = 2.0;

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
    bodies: Query<(Entity, &BodyLattice)>,
    colliders: Query<(&Collider, &ColliderPose)>,
    mut particles: Query<ParticleData>,
    mut repaired_messages: MessageWriter<ParticlesRepaired>,
) {
    let config = &settings.0;
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
    let repaired = repair_non_finite(cache, &bodies);
    cache.kinds.colliders = substep_colliders(config, &substep, &colliders);
    let dt = config.dt / config.substeps as f32;
    cache.layout.solve(config.iterations, dt, &mut cache.kinds);
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
    report_repaired(cache, &repaired, &mut particles, &mut repaired_messages);
}

/// Puts every live particle whose loaded position is not finite back where it started
/// the substep (or, if that is not finite either, at the mean of its finite lattice
/// neighbours, else at the origin), before it can spread through its clusters; returns
/// them.
fn repair_non_finite(cache: &mut SolverCache, bodies: &Query<(Entity, &BodyLattice)>) -> Vec<u32> {
    let SolverCache {
        layout,
        live,
        locals,
        body_dense,
        ..
    } = cache;
    layout.repair_non_finite(live, |d, positions| {
        let Some((body, local)) = crate::ecs::resources::dense_owner(locals, body_dense, d) else {
            return Vec3A::ZERO;
        };
        let (Ok((_, lattice)), Ok(b)) = (
            bodies.get(body),
            body_dense.binary_search_by_key(&body, |b| b.body),
        ) else {
            return Vec3A::ZERO;
        };
        let (sum, count) = lattice
            .lattice
            .neighbours(local)
            .filter_map(|n| body_dense[b].dense.get(n as usize).copied())
            .filter(|n| *n != u32::MAX && positions[*n as usize].is_finite())
            .fold((Vec3A::ZERO, 0u32), |(sum, count), n| {
                (sum + positions[n as usize], count + 1)
            });
        if count > 0 {
            sum / count as f32
        } else {
            Vec3A::ZERO
        }
    })
}

/// Zeroes the velocities of the repaired particles (a NaN velocity would carry the
/// particle off again at the next prediction) and reports them per body.
fn report_repaired(
    cache: &SolverCache,
    repaired: &[u32],
    particles: &mut Query<ParticleData>,
    messages: &mut MessageWriter<ParticlesRepaired>,
) {
    let mut by_body: Vec<(Entity, u32)> = Vec::with_capacity(repaired.len());
    for &d in repaired {
        if let Ok((_, _, mut velocity, ..)) = particles.get_mut(cache.particles[d as usize]) {
            velocity.0 = Vec3::ZERO;
        }
        if let Some(owner) = cache.owner(d as usize) {
            by_body.push(owner);
        }
    }
    by_body.sort_unstable();
    for group in by_body.chunk_by(|a, b| a.0 == b.0) {
        messages.write(ParticlesRepaired {
            body: group[0].0,
            particles: group.iter().map(|(_, i)| *i).collect(),
        });
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
