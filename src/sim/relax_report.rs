//! What relaxation reports ([`crate::sim::relax`]), apart from the relaxation itself so
//! that the simulation can keep the reports of a scene's relaxations.

use bevy_ecs::prelude::*;
use serde::Serialize;

/// What a relaxation did ([`crate::sim::simulation::Simulation::relax`]). Distances are
/// in lattice spacings.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RelaxReport {
    /// Frames run.
    pub frames: u32,
    /// Whether the rms speed fell under the tolerance within the frames allowed.
    pub converged: bool,
    /// The final residual: the particles' rms speed, spacings per second.
    pub rms_speed: f64,
    /// The final kinetic energy, J.
    pub kinetic_energy: f64,
    /// How far the shape was from its rest before: rms distance of the particles from
    /// the best rigid placement of the rest shape.
    pub shape_error_before: f64,
    /// The same after.
    pub shape_error: f64,
    /// Boundary sets (held or not: their drift is measured either way).
    pub boundary_sets: usize,
    /// Largest distance of a boundary set's centroid from where it started.
    pub boundary_drift: f64,
}

/// The reports of the relaxations [`crate::sim::simulation::Simulation::from_scene`]
/// ran (a scene's `settings.relax`), by body; not saved.
#[derive(Resource, Clone, Debug, Default)]
pub struct RelaxReports(pub Vec<(Entity, RelaxReport)>);
