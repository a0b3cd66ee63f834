//! Stage store (after the substeps): writes the solved positions, velocities,
//! orientations and angular velocities from the solver's dense arrays back into the
//! particles' components. Writes particle data only.

use crate::ecs::components::{AngularVelocity, Orientation, Position, Velocity};
use crate::ecs::layout::SolverCache;
use crate::ecs::layout::table_rows::StoredColumns;
use bevy_ecs::prelude::*;
use glam::Vec3;

/// Particle data the stage writes.
type ParticleData = (
    Entity,
    &'static mut Position,
    &'static mut Velocity,
    &'static mut Orientation,
    &'static mut AngularVelocity,
);

/// Writes the frame's particle state back to the components.
pub fn store_particles(cache: Res<SolverCache>, mut particles: Query<ParticleData>) {
    let one_table = particles
        .contiguous_iter()
        .expect("particle components are stored in tables")
        .filter(|(entities, ..)| !entities.is_empty())
        .count()
        == 1;
    if one_table {
        let tables = particles
            .contiguous_iter_mut()
            .expect("particle components are stored in tables");
        for (entities, mut positions, mut velocities, mut orientations, mut spins) in tables {
            if !entities.is_empty() {
                let columns = StoredColumns {
                    positions: &mut positions,
                    velocities: &mut velocities,
                    orientations: &mut orientations,
                    spins: &mut spins,
                };
                cache.layout.store(&cache.particles, columns);
            }
        }
    } else {
        for (e, mut x, mut v, mut q, mut w) in &mut particles {
            if let Some(d) = cache.layout.dense_of(e) {
                x.0 = Vec3::from(cache.particles.positions[d]);
                v.0 = Vec3::from(cache.particles.velocities[d]);
                q.0 = cache.particles.orientations[d];
                w.0 = Vec3::from(cache.particles.spins[d]);
            }
        }
    }
}
