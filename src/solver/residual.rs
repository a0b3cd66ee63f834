//! How far a solve is from its solution: the residual of the substep's implicit step,
//! the net force on every free particle at the current positions.
//!
//! Every scheme minimises the same objective, `½|x − s|²_M/dt² + Σ E(x)`
//! ([`Solver::solve`]), so its gradient is a measure they share: a solver is converged
//! where the net force vanishes, whatever its iterations did on the way. Each cluster's
//! rotation is fitted here to convergence (the schemes take a few warm-started
//! iterations per solve), so the residual does not flatter a scheme whose fits lag.
//! The terms count through their projective form (attachments, edges: `w SᵀAᵀ(p − A S
//! x)`); contacts and colliders, whose constraints change every substep, have none and
//! are left out, as is a term's hard constraint beyond the stiffness projective
//! dynamics gives it ([`STIFFEST`](super::term::STIFFEST)).

use super::particles::Particles;
use super::solve::Solver;
use super::term::{NO_DENSE, Substep, Unknowns};
use crate::math::rotation::extract_rotation;
use glam::{DMat3, DVec3, Mat3A};

/// Rotation iterations of a fit here: enough to converge from the last fit.
const FIT_ITERATIONS: u32 = 64;

impl Solver {
    /// The net force on each particle (by dense index) at its current position, for the
    /// substep `step` whose inertial targets are `particles.predicted`: zero for a
    /// particle of inverse mass 0 and at the objective's minimum.
    pub fn net_forces(&self, particles: &Particles, step: &Substep) -> Vec<DVec3> {
        let n = particles.len();
        let inv_dt2 = 1.0 / (step.dt as f64 * step.dt as f64);
        let mass = |i: usize| 1.0 / particles.inv_mass[i] as f64;
        let position = |i: usize| particles.positions[i].as_dvec3();
        let mut forces: Vec<DVec3> = (0..n)
            .map(|i| {
                if particles.inv_mass[i] > 0.0 {
                    (particles.predicted[i].as_dvec3() - position(i)) * mass(i) * inv_dt2
                } else {
                    DVec3::ZERO
                }
            })
            .collect();
        let row_of: Vec<u32> = (0..n as u32)
            .map(|i| {
                if particles.inv_mass[i as usize] > 0.0 {
                    i
                } else {
                    NO_DENSE
                }
            })
            .collect();
        let unknowns = Unknowns {
            row_of: &row_of,
            inv_mass: &particles.inv_mass,
        };
        let clusters = &self.clusters;
        for (k, members) in clusters.clusters() {
            let weight = |m: u32| clusters.weight(m) as f64;
            let total: f64 = members.iter().map(|&m| weight(m)).sum();
            if total <= 0.0 {
                continue;
            }
            let mean = |at: &dyn Fn(usize) -> DVec3| {
                members
                    .iter()
                    .map(|&m| at(m as usize) * weight(m))
                    .sum::<DVec3>()
                    / total
            };
            let rest = |i: usize| clusters.rest[i].as_dvec3();
            let (centre, rest_centre) = (mean(&position), mean(&rest));
            // member j's rest offset (a plastic cluster's own shape: the shift's mean is
            // taken off with the centroid)
            let shift = |j: usize| {
                clusters
                    .plastic_shift(k)
                    .map_or(DVec3::ZERO, |s| s[j].as_dvec3())
            };
            let shift_centre = (members.iter().enumerate())
                .map(|(j, &m)| shift(j) * weight(m))
                .sum::<DVec3>()
                / total;
            let offset =
                |j: usize, m: u32| rest(m as usize) - rest_centre + shift(j) - shift_centre;
            let mut moment = DMat3::ZERO;
            for (j, &m) in members.iter().enumerate() {
                let p = position(m as usize) - centre;
                let q = offset(j, m) * weight(m);
                moment += DMat3::from_cols(p * q.x, p * q.y, p * q.z);
            }
            let rotation = extract_rotation(
                Mat3A::from(moment.as_mat3()),
                clusters.rotations()[k],
                FIT_ITERATIONS,
            )
            .as_dquat();
            let kappa = unknowns.weight(clusters.compliance[k], members, step.dt);
            for (j, &m) in members.iter().enumerate() {
                let i = m as usize;
                if particles.inv_mass[i] > 0.0 {
                    let goal = centre + rotation * offset(j, m);
                    forces[i] += (goal - position(i)) * kappa * weight(m);
                }
            }
        }
        // (the residual leaves the particles' orientations as they are)
        let mut orientations = particles.orientations.clone();
        for term in self.terms.iter() {
            if let Some(form) = term.projective() {
                form.add_forces(
                    step,
                    &unknowns,
                    &particles.positions,
                    &mut orientations,
                    &mut forces,
                );
            }
        }
        for (force, &w) in forces.iter_mut().zip(&particles.inv_mass) {
            if w == 0.0 {
                *force = DVec3::ZERO;
            }
        }
        forces
    }

    /// The root-sum-square of [`Solver::net_forces`], newtons.
    pub fn residual(&self, particles: &Particles, step: &Substep) -> f64 {
        self.net_forces(particles, step)
            .iter()
            .map(|f| f.length_squared())
            .sum::<f64>()
            .sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::clusters::term::{ClusterSpec, ClusterTerm};
    use crate::solver::registry::Terms;
    use crate::solver::testing::step;
    use glam::{Quat, Vec3, Vec3A};

    /// One cluster of a unit cube's eight corners (h = 0.1), compliance 1e-3.
    fn cube(mode: SolverMode) -> (Solver, Particles, Vec<Vec3>) {
        let rest: Vec<Vec3> = (0..8)
            .map(|b| Vec3::new((b & 1) as f32, ((b >> 1) & 1) as f32, (b >> 2) as f32) * 0.1)
            .collect();
        let members: Vec<u32> = (0..8).collect();
        let spec = ClusterSpec {
            members: &members,
            compliance: 1e-3,
            rotation: Quat::IDENTITY,
            plastic: None,
        };
        let solver = Solver::new(ClusterTerm::new(&rest, [spec], mode), Terms::default());
        (solver, Particles::at_rest(&rest), rest)
    }

    #[test]
    fn a_body_at_rest_or_moved_rigidly_feels_no_force() {
        for mode in SolverMode::ALL {
            let (solver, mut particles, rest) = cube(mode);
            assert!(solver.residual(&particles, &step(1)) < 1e-3, "{mode:?}");
            let turn = Quat::from_rotation_y(1.1) * Quat::from_rotation_x(0.3);
            for (p, r) in particles.positions.iter_mut().zip(&rest) {
                *p = Vec3A::from(turn * *r + Vec3::new(2.0, -1.0, 0.5));
            }
            particles.predicted.clone_from(&particles.positions);
            // a cluster force of 1e-3 N is a stretch of 1e-6 m at this stiffness
            assert!(solver.residual(&particles, &step(1)) < 1e-3, "{mode:?}");
        }
    }

    #[test]
    fn a_stretched_cluster_pulls_each_member_back_by_its_stiffness_and_inertia_adds_its_own() {
        let (solver, mut particles, rest) = cube(SolverMode::Projective);
        let stretch = 0.01;
        let centre = Vec3::splat(0.05);
        for (p, r) in particles.positions.iter_mut().zip(&rest) {
            *p = Vec3A::from(centre + (*r - centre) * (1.0 + stretch));
        }
        particles.predicted.clone_from(&particles.positions);
        // each member in one cluster: weight 1, κ = 1/compliance; the best rotation is
        // the identity, so the goal is the rest place about the stretched centre
        let forces = solver.net_forces(&particles, &step(1));
        for (force, r) in forces.iter().zip(&rest) {
            let expected = ((*r - centre) * -stretch / 1e-3).as_dvec3();
            assert!(
                (*force - expected).length() < 1e-3 * expected.length(),
                "{force}"
            );
        }
        // a particle away from its inertial target is pulled back by m/dt² per metre;
        // held particles feel nothing
        particles.predicted[3] += Vec3A::new(0.0, 1e-3, 0.0);
        particles.inv_mass[5] = 0.0;
        let moved = solver.net_forces(&particles, &step(1));
        let dt = step(1).dt as f64;
        let inertia = moved[3] - forces[3];
        assert!(
            (inertia.y - 1e-3 / (dt * dt)).abs() < 1e-3 * inertia.y,
            "{inertia}"
        );
        assert_eq!(moved[5], DVec3::ZERO);
    }
}
