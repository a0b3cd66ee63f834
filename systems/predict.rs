//! Stage predict (SPEC §2.1): gravity, damping, predicted position. Particle data only.

use crate::components::{InvMass, Position, PrevPosition, Velocity};
use crate::resources::SimSettings;
use bevy_ecs::prelude::*;

/// `v ← (v + g·dt)·e^(−damping·dt)`, `x_prev ← x`, `x ← x + v·dt`; pinned particles stay.
pub fn predict(
    settings: Res<SimSettings>,
    mut particles: Query<(&mut Position, &mut PrevPosition, &mut Velocity, &InvMass)>,
) {
    let config = &settings.0;
    let dt = config.dt / config.substeps as f32;
    let keep = (-config.damping * dt).exp();
    let dv = config.gravity * dt;
    for (mut x, mut prev, mut v, inv_mass) in &mut particles {
        prev.0 = x.0;
        if inv_mass.0 == 0.0 {
            v.0 = glam::Vec3::ZERO;
            continue;
        }
        v.0 = (v.0 + dv) * keep;
        x.0 += v.0 * dt;
    }
}
