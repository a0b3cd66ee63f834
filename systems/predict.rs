//! Stage predict: gravity, damping, predicted positions, on the solver's dense particle
//! arrays ([`crate::solver::particles::Particles::predict`]). Particle data only.

use crate::ecs::layout::SolverCache;
use crate::ecs::resources::SimSettings;
use bevy_ecs::prelude::*;

/// `v ← (v + g·dt)·e^(−damping·dt)`, `x_prev ← x`, `x ← x + v·dt`; kinematic particles
/// (inverse mass 0: pinned, held by a hard attachment) keep their velocity.
pub fn predict(settings: Res<SimSettings>, mut cache: ResMut<SolverCache>) {
    let config = &settings.0;
    let dt = config.dt / config.substeps as f32;
    let cache = &mut *cache;
    let cluster_counts = cache.solver.clusters.member_counts();
    cache
        .particles
        .predict(dt, config.gravity, config.damping, cluster_counts);
}
