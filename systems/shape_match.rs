//! Stage shape-match: one substep's solve on the solver's dense arrays — puts back any
//! particle whose position is not finite, runs the iterations with every term (the
//! terms that read the ECS each substep have just taken their data:
//! [`super::term_sync::TermSubstepData`]), and derives the velocities. Writes particle
//! data (the dense arrays) only.

use crate::ecs::components::*;
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{ParticlesRepaired, SimSettings, SubstepClock};
use crate::solver::term::Substep;
use bevy_ecs::prelude::*;
use glam::Vec3A;

/// One solver substep over all bodies.
pub fn shape_match(
    settings: Res<SimSettings>,
    substep: Res<SubstepClock>,
    mut cache: ResMut<SolverCache>,
    bodies: Query<(Entity, &BodyLattice)>,
    mut repaired_messages: MessageWriter<ParticlesRepaired>,
) {
    let config = &settings.0;
    let cache = &mut *cache;
    let repaired = repair_non_finite(cache, &bodies);
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
    let ends_frame = substep.index + 1 >= substep.count;
    let cluster_counts = cache.solver.clusters.member_counts();
    cache
        .particles
        .update_velocities(inv_dt, cluster_counts, ends_frame);
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
