//! Stage predict: gravity, damping, predicted position. Particle data only.
//!
//! The particle components are read as whole table columns (bevy's contiguous query
//! iteration) and advanced in parallel chunks.

use crate::ecs::components::{InvMass, Position, PrevPosition, Velocity};
use crate::ecs::resources::SimSettings;
use bevy_ecs::prelude::*;
use rayon::prelude::*;

/// Particles per parallel task.
const CHUNK: usize = 4096;

/// `v ← (v + g·dt)·e^(−damping·dt)`, `x_prev ← x`, `x ← x + v·dt`; pinned particles keep
/// their velocity (a pin region's, zero for pins that hold still).
pub fn predict(
    settings: Res<SimSettings>,
    mut particles: Query<(&mut Position, &mut PrevPosition, &mut Velocity, &InvMass)>,
) {
    let config = &settings.0;
    let dt = config.dt / config.substeps as f32;
    let keep = (-config.damping * dt).exp();
    let dv = config.gravity * dt;
    let columns = particles
        .contiguous_iter_mut()
        .expect("particle components are stored in tables");
    for (mut x, mut prev, mut v, inv_mass) in columns {
        (&mut *x, &mut *prev, &mut *v, inv_mass)
            .into_par_iter()
            .with_min_len(CHUNK)
            .for_each(|(x, prev, v, inv_mass)| {
                prev.0 = x.0;
                if inv_mass.0 != 0.0 {
                    v.0 = (v.0 + dv) * keep;
                }
                x.0 += v.0 * dt;
            });
    }
}
