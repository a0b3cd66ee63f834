//! Stage shape-match: one substep's solve on the solver's dense arrays — puts back any
//! particle whose position is not finite, places the colliders for this substep, runs
//! the iterations with every term, and derives the velocities. Writes particle data
//! (the dense arrays) only.

use crate::ecs::components::*;
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{ParticlesRepaired, SimSettings, SubstepClock};
use crate::ecs::spawn::checked_pose;
use crate::error::CleaveError;
use crate::solver::term::Substep;
use crate::solver::terms::colliders::{Colliders, PosedCollider};
use bevy_ecs::prelude::*;
use glam::Vec3A;

/// How fast (m/s) a particle that began a substep inside a collider is pushed out of
/// it (see [`Colliders::depenetration_step`]): a body spawned in a collider comes out at
/// a walk, not shot out.
pub const MAX_DEPENETRATION_SPEED: f32 = 2.0;

/// One solver substep over all bodies.
pub fn shape_match(
    settings: Res<SimSettings>,
    substep: Res<SubstepClock>,
    mut cache: ResMut<SolverCache>,
    bodies: Query<(Entity, &BodyLattice)>,
    colliders: Query<(Entity, &Collider, &ColliderPose, Option<&DynamicCollider>)>,
    mut refused: Local<Vec<Entity>>,
    mut repaired_messages: MessageWriter<ParticlesRepaired>,
) {
    let config = &settings.0;
    let cache = &mut *cache;
    let repaired = repair_non_finite(cache, &bodies);
    if let Some(term) = cache.solver.terms.get_mut::<Colliders>() {
        term.place(
            substep_colliders(config, &substep, &colliders, &mut refused),
            substep.index == 0,
        );
    }
    let count = substep.count.max(1) as f32;
    let step = Substep {
        dt: config.dt / config.substeps as f32,
        iterations: config.iterations,
        frame_span: [
            substep.index as f32 / count,
            (substep.index + 1) as f32 / count,
        ],
    };
    cache.solver.solve(&mut cache.particles, &step);
    // (the same 1/dt as `substeps / dt`, rounded once)
    let inv_dt = config.substeps as f32 / config.dt;
    cache.particles.update_velocities(inv_dt);
    report_repaired(cache, &repaired, &mut repaired_messages);
}

/// Puts every live particle whose position is not finite back where it started
/// the substep (or, if that is not finite either, at the mean of its finite lattice
/// neighbours, else at the origin), before it can spread through its clusters; returns
/// them.
fn repair_non_finite(cache: &mut SolverCache, bodies: &Query<(Entity, &BodyLattice)>) -> Vec<u32> {
    let SolverCache {
        particles, layout, ..
    } = cache;
    particles.repair_non_finite(layout.live(), |d, positions| {
        let Some((body, local)) = layout.owner(d) else {
            return Vec3A::ZERO;
        };
        let (Ok((_, lattice)), Some(b)) = (bodies.get(body), layout.body(body)) else {
            return Vec3A::ZERO;
        };
        let (sum, count) = lattice
            .lattice
            .neighbours(local)
            .filter_map(|n| b.dense.get(n as usize).copied())
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

/// Reports the repaired particles per body (their velocities were zeroed with them).
fn report_repaired(
    cache: &SolverCache,
    repaired: &[u32],
    messages: &mut MessageWriter<ParticlesRepaired>,
) {
    let mut by_body: Vec<(Entity, u32)> = repaired
        .iter()
        .filter_map(|&d| cache.layout.owner(d as usize))
        .collect();
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
/// over the substeps; a dynamic one starts the frame where it is, and the term carries
/// it on from substep to substep). Game code may have written anything into the
/// components: a collider whose pose is out of bounds is left out, a dynamic one whose
/// state is out of bounds is kinematic, each with a warning the first time (`refused`
/// lists them).
fn substep_colliders(
    config: &crate::config::SimConfig,
    substep: &SubstepClock,
    entities: &Query<(Entity, &Collider, &ColliderPose, Option<&DynamicCollider>)>,
    refused: &mut Vec<Entity>,
) -> Colliders {
    let dt = config.dt / config.substeps as f32;
    let count = substep.count.max(1) as f32;
    let (t0, t1) = (
        substep.index as f32 / count,
        (substep.index + 1) as f32 / count,
    );
    let mut refuse = |e: Entity, error: Option<(CleaveError, &str)>| match error {
        Some((error, so)) if !refused.contains(&e) => {
            tracing::warn!("cleave: collider {e} {so}: {error}");
            refused.push(e);
        }
        Some(_) => {}
        None => refused.retain(|r| *r != e),
    };
    let moving = entities.iter().filter_map(|(e, c, pose, dynamic)| {
        let posed = checked_pose("collider.pose.current", pose.current)
            .and_then(|_| checked_pose("collider.pose.last", pose.last));
        if let Err(error) = posed {
            refuse(e, Some((error, "left out")));
            return None;
        }
        // (tagged by its entity, for its wrench: see `systems::wrench`)
        let shape = c.shape.clone();
        match dynamic.map(|d| d.check().map(|()| d.motion())) {
            Some(Ok(motion)) => {
                refuse(e, None);
                let posed = PosedCollider::dynamic(
                    shape,
                    c.friction,
                    pose.current,
                    motion,
                    config.gravity,
                    dt,
                );
                return Some(posed.tagged(e.to_bits()));
            }
            Some(Err(error)) => refuse(e, Some((error, "stays kinematic"))),
            None => refuse(e, None),
        }
        let (start, end) = (
            pose.last.lerp(&pose.current, t0),
            pose.last.lerp(&pose.current, t1),
        );
        Some(PosedCollider::new(shape, c.friction, start, end).tagged(e.to_bits()))
    });
    let mut colliders = Colliders::from_config(config, moving);
    colliders.depenetration_step = MAX_DEPENETRATION_SPEED * config.dt / count;
    colliders
}
