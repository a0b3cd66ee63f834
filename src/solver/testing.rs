//! Helpers for the solver's unit tests: clusters with unit compliance, a solver over
//! particles at rest, and a substep of a fixed time step.

use super::clusters::term::{ClusterSpec, ClusterTerm};
use super::particles::Particles;
use super::registry::Terms;
use super::solve::Solver;
use super::term::Substep;
use crate::config::SolverMode;
use glam::{Quat, Vec3};

/// A substep time step (120 Hz).
pub(crate) const TEST_DT: f32 = 1.0 / 120.0;

/// Specs of rigid clusters without rotation for the given member lists.
pub(crate) fn unit_specs(clusters: &[Vec<u32>]) -> Vec<ClusterSpec<'_>> {
    clusters
        .iter()
        .map(|m| ClusterSpec {
            members: m,
            compliance: 0.0,
            rotation: Quat::IDENTITY,
            plastic: None,
        })
        .collect()
}

/// A solver of rigid `clusters` over particles at rest at `rest`, with `terms`.
pub(crate) fn solver(
    rest: &[Vec3],
    clusters: &[Vec<u32>],
    mode: SolverMode,
    terms: Terms,
) -> (Solver, Particles) {
    let term = ClusterTerm::new(rest, unit_specs(clusters), mode);
    (Solver::new(term, terms), Particles::at_rest(rest))
}

/// A substep of [`TEST_DT`] with `iterations` iterations.
pub(crate) fn step(iterations: u32) -> Substep {
    Substep {
        dt: TEST_DT,
        iterations,
        frame_span: [0.0, 1.0],
    }
}
