//! Stage load (the end of [`crate::systems::SyncSchedule`]): copies every particle's
//! position, velocity, orientation, angular velocity and inverse mass from its components into the solver's dense
//! arrays, where they stay for the frame's substeps, and gives the particles a term
//! holds kinematic (a hard attachment's) inverse mass 0 there. Writes the solver cache
//! only.

use crate::ecs::components::{AngularVelocity, InvMass, Orientation, Position, Velocity};
use crate::ecs::layout::SolverCache;
use crate::ecs::layout::table_rows::ParticleColumns;
use bevy_ecs::prelude::*;
use glam::Vec3A;

/// Particle data the stage reads.
type ParticleData = (
    Entity,
    &'static Position,
    &'static Velocity,
    &'static Orientation,
    &'static AngularVelocity,
    &'static InvMass,
);

/// Loads the particles' state into the dense arrays.
pub fn load_particles(mut cache: ResMut<SolverCache>, particles: Query<ParticleData>) {
    let cache = &mut *cache;
    // Usually every particle sits in one table: its columns are copied in parallel.
    let mut tables = particles
        .contiguous_iter()
        .expect("particle components are stored in tables")
        .filter(|(entities, ..)| !entities.is_empty());
    match (tables.next(), tables.next()) {
        (Some((entities, positions, velocities, orientations, spins, inv_mass)), None) => {
            let table = ParticleColumns {
                entities,
                positions,
                velocities,
                orientations,
                spins,
                inv_mass,
            };
            cache.layout.load(&mut cache.particles, table);
        }
        _ => {
            for (e, x, v, q, w, inv_mass) in &particles {
                if let Some(d) = cache.layout.dense_of(e) {
                    cache.particles.positions[d] = Vec3A::from(x.0);
                    cache.particles.velocities[d] = Vec3A::from(v.0);
                    cache.particles.orientations[d] = q.0;
                    cache.particles.spins[d] = Vec3A::from(w.0);
                    cache.particles.inv_mass[d] = inv_mass.0;
                }
            }
        }
    }
    cache.solver.hold_kinematic(&mut cache.particles.inv_mass);
}
