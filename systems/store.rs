//! Stage store (after the substeps): writes the solved positions and velocities from the
//! solver's dense arrays back into the particles' components. Writes particle data
//! only.

use crate::ecs::components::{Position, Velocity};
use crate::ecs::resources::SolverCache;
use bevy_ecs::prelude::*;
use glam::Vec3;

/// Writes the frame's particle state back to the components.
pub fn store_particles(
    cache: Res<SolverCache>,
    mut particles: Query<(Entity, &mut Position, &mut Velocity)>,
) {
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
        for (entities, mut positions, mut velocities) in tables {
            if !entities.is_empty() {
                cache
                    .rows
                    .store(&cache.particles, &mut positions, &mut velocities);
            }
        }
    } else {
        for (e, mut x, mut v) in &mut particles {
            if let Some(&d) = cache.dense_of.get(e.index_u32() as usize)
                && d != u32::MAX
                && cache.entities[d as usize] == e
            {
                x.0 = Vec3::from(cache.particles.positions[d as usize]);
                v.0 = Vec3::from(cache.particles.velocities[d as usize]);
            }
        }
    }
}
