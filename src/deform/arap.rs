//! As-rigid-as-possible deformation of a body's lattice with handles as constraints
//! (Sorkine & Alexa 2007, SPEC §6.4).
//!
//! `E = Σᵢ Σⱼ wᵢⱼ ‖(p′ᵢ − p′ⱼ) − Rᵢ(pᵢ − pⱼ)‖²` over each particle's live lattice links
//! (its *spokes*). Local step: each `Rᵢ` is the rotation of `Sᵢ = Σⱼ wᵢⱼ (p′ᵢ − p′ⱼ)(pᵢ −
//! pⱼ)ᵀ` (its polar factor, a proper rotation, so reflections never arise); global
//! step: `L p′ = Σⱼ wᵢⱼ ½ (Rᵢ + Rⱼ)(pᵢ − pⱼ)` with the handles' particles held at their
//! targets, `L` factored once per handle set.
//!
//! # Spoke weights
//!
//! The cotangent weights of the notes are the linear finite element Laplacian of a
//! triangle mesh. A voxel lattice's spokes are its six axis links, all the same length
//! and orthogonal: the finite-difference (and the finite-volume) Laplacian of a cubic
//! lattice weights each of them the same, so `wᵢⱼ = 1`. That keeps `L` the lattice
//! graph's Laplacian, symmetric and positive definite once a handle holds each piece,
//! and the energy the same along every axis.
//!
//! # The energy never rises
//!
//! Each step minimises the energy over its own variables: the global step exactly (a
//! factored solve), the local step up to the rotation fit's precision. A fitted
//! rotation that would not lower its particle's term (a fit stopped short) is not
//! taken, so no step raises the energy.

use super::handles::{HandleSet, HandleTarget};
use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::error::{CleaveError, Result};
use crate::math::sparse_cholesky::SparseCholesky;
use faer::sparse::Triplet;
use glam::{DMat3, DQuat, DVec3, Vec3};
use rayon::prelude::*;

/// Most iterations of a rotation fit (a warm start needs a few).
const MAX_FIT_ITERATIONS: u32 = 64;

/// When to stop iterating.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ArapOptions {
    /// Stop when an iteration lowers the energy by less than this fraction of it.
    pub tolerance: f64,
    /// Stop after this many iterations at most.
    pub max_iterations: u32,
}

impl Default for ArapOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-4,
            max_iterations: 100,
        }
    }
}

/// What a solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ArapReport {
    /// The energy before the first iteration (with every rotation the identity), then
    /// after each iteration (with a tolerance of 0, which runs every iteration, only
    /// after the last).
    pub energies: Vec<f64>,
    /// Iterations run.
    pub iterations: u32,
}

/// A body's ARAP problem for one handle set: the spokes, and the factored Laplacian of
/// the particles the handles leave free.
#[derive(Clone, Debug)]
pub struct Arap {
    rest: Vec<DVec3>,
    /// Per particle, its six links (`NO_PARTICLE` where none).
    links: Vec<[u32; 6]>,
    /// The live particles, by index.
    live: Vec<u32>,
    /// Per particle, its index among the unknowns, or `NO_PARTICLE` (held or removed).
    unknown: Vec<u32>,
    /// The unknowns' particles.
    free: Vec<u32>,
    factor: Option<SparseCholesky>,
}

impl Arap {
    /// Prepares ARAP on `lattice`, resting at `rest`, with `handles` holding their
    /// particles. A piece no handle holds keeps the pose it is given. Refuses a factor
    /// over `limit` bytes.
    pub fn new(lattice: &Lattice, rest: &[Vec3], handles: &HandleSet, limit: u64) -> Result<Self> {
        let n = lattice.len();
        let mut held = vec![false; n];
        for (_, p) in handles.constrained() {
            held[p as usize] = true;
        }
        let labels = lattice.pieces();
        let mut piece_held = vec![false; labels.count];
        for (_, p) in handles.constrained() {
            piece_held[labels.label[p as usize] as usize] = true;
        }
        let mut unknown = vec![NO_PARTICLE; n];
        let mut free = Vec::new();
        for i in lattice.live_particles() {
            if !held[i as usize] && piece_held[labels.label[i as usize] as usize] {
                unknown[i as usize] = free.len() as u32;
                free.push(i);
            }
        }
        let links: Vec<[u32; 6]> = (0..n as u32).map(|i| lattice.links(i)).collect();
        let mut entries = Vec::new();
        for (f, &i) in free.iter().enumerate() {
            let spokes = links[i as usize].iter().filter(|&&j| j != NO_PARTICLE);
            entries.push(Triplet::new(f, f, 2.0 * spokes.clone().count() as f64));
            for &j in spokes {
                let g = unknown[j as usize];
                if g != NO_PARTICLE && (g as usize) < f {
                    entries.push(Triplet::new(f, g as usize, -2.0));
                }
            }
        }
        let factor = if free.is_empty() {
            None
        } else {
            Some(
                SparseCholesky::new(free.len(), &entries, limit).map_err(|e| {
                    CleaveError::InvalidEntity(format!("handles: ARAP's Laplacian: {e}"))
                })?,
            )
        };
        Ok(Self {
            rest: rest.iter().map(|p| p.as_dvec3()).collect(),
            links,
            live: lattice.live_particles().collect(),
            unknown,
            free,
            factor,
        })
    }

    /// The energy of `positions` with the rotations `rotations` (both by particle).
    pub fn energy(&self, positions: &[DVec3], rotations: &[DMat3]) -> f64 {
        // fixed chunks summed in order: the same on any number of threads
        let partials: Vec<f64> = self
            .live
            .par_chunks(1024)
            .map(|chunk| {
                let mut sum = 0.0;
                for &i in chunk {
                    for j in self.spokes(i) {
                        let (i, j) = (i as usize, j as usize);
                        let spoke = positions[i] - positions[j];
                        sum +=
                            (spoke - rotations[i] * (self.rest[i] - self.rest[j])).length_squared();
                    }
                }
                sum
            })
            .collect();
        partials.iter().sum()
    }

    fn spokes(&self, i: u32) -> impl Iterator<Item = u32> + '_ {
        self.links[i as usize]
            .into_iter()
            .filter(|&j| j != NO_PARTICLE)
    }

    /// Deforms `positions` (by particle: the first guess in, the result out) with the
    /// handles of `handles` (the set this problem was made with) moved to `targets`,
    /// iterating until `options` stop it.
    pub fn solve(
        &self,
        handles: &HandleSet,
        targets: &[HandleTarget],
        positions: &mut [Vec3],
        options: &ArapOptions,
    ) -> Result<ArapReport> {
        let rest: Vec<Vec3> = self.rest.iter().map(|p| p.as_vec3()).collect();
        let dh = handles.displacements(&rest, targets)?;
        let mut x: Vec<DVec3> = positions.iter().map(|p| p.as_dvec3()).collect();
        for (k, p) in handles.constrained() {
            let first = handles.first_column(k);
            let j = handles.coefficients(k, p, &rest);
            let width = handles.handles()[k].columns();
            x[p as usize] = self.rest[p as usize]
                + (0..width)
                    .map(|c| j[c] * dh[first + c].as_dvec3())
                    .sum::<DVec3>();
        }
        let mut rotations = vec![DMat3::IDENTITY; x.len()];
        let mut report = ArapReport {
            energies: vec![self.energy(&x, &rotations)],
            iterations: 0,
        };
        let mut rhs = vec![[0.0f64; 3]; self.free.len()];
        while report.iterations < options.max_iterations {
            self.local_step(&x, &mut rotations);
            self.global_step(&mut x, &rotations, &mut rhs);
            report.iterations += 1;
            // the energy is only needed to stop early, and at the end
            if options.tolerance > 0.0 || report.iterations == options.max_iterations {
                let energy = self.energy(&x, &rotations);
                let before = *report.energies.last().expect("the first energy");
                report.energies.push(energy);
                if before - energy <= options.tolerance * before {
                    break;
                }
            }
        }
        for (p, x) in positions.iter_mut().zip(&x) {
            *p = x.as_vec3();
        }
        Ok(report)
    }

    /// Each particle's rotation fitted to its spokes (kept where the fit is no better).
    fn local_step(&self, x: &[DVec3], rotations: &mut [DMat3]) {
        let fitted: Vec<(u32, DMat3)> = self
            .live
            .par_iter()
            .map(|&i| {
                let mut s = DMat3::ZERO;
                for j in self.spokes(i) {
                    let (a, b) = (i as usize, j as usize);
                    let deformed = x[a] - x[b];
                    let rest = self.rest[a] - self.rest[b];
                    s += DMat3::from_cols(deformed * rest.x, deformed * rest.y, deformed * rest.z);
                }
                (i, fit_rotation(s, rotations[i as usize]))
            })
            .collect();
        for (i, r) in fitted {
            rotations[i as usize] = r;
        }
    }

    /// The positions of the free particles that minimise the energy for `rotations`.
    fn global_step(&self, x: &mut [DVec3], rotations: &[DMat3], rhs: &mut [[f64; 3]]) {
        let Some(factor) = &self.factor else { return };
        rhs.par_iter_mut().zip(&self.free).for_each(|(b, &i)| {
            let mut sum = DVec3::ZERO;
            for j in self.spokes(i) {
                let (a, c) = (i as usize, j as usize);
                sum += (rotations[a] + rotations[c]) * (self.rest[a] - self.rest[c]);
                if self.unknown[c] == NO_PARTICLE {
                    sum += 2.0 * x[c];
                }
            }
            *b = sum.to_array();
        });
        factor.solve_in_place(rhs);
        for (&i, b) in self.free.iter().zip(rhs.iter()) {
            x[i as usize] = DVec3::from_array(*b);
        }
    }
}

/// The rotation `R` that maximises `tr(Rᵀ S)` (the polar factor of `S`), by Müller et
/// al.'s iteration (2016) in double precision from `old`, to a step under 10⁻¹⁰ rad;
/// `old` itself when the fit does not do better.
pub fn fit_rotation(s: DMat3, old: DMat3) -> DMat3 {
    let score = |r: DMat3| r.x_axis.dot(s.x_axis) + r.y_axis.dot(s.y_axis) + r.z_axis.dot(s.z_axis);
    let scale = s
        .x_axis
        .abs()
        .max(s.y_axis.abs())
        .max(s.z_axis.abs())
        .max_element();
    if !(scale.is_finite() && scale > 0.0) {
        return old;
    }
    let mut q = DQuat::from_mat3(&old).normalize();
    for _ in 0..MAX_FIT_ITERATIONS {
        let r = DMat3::from_quat(q);
        let omega =
            (r.x_axis.cross(s.x_axis) + r.y_axis.cross(s.y_axis) + r.z_axis.cross(s.z_axis))
                / (score(r).abs() + 1e-12 * scale);
        let angle = omega.length();
        if !(angle > 1e-10 && angle.is_finite()) {
            break;
        }
        // exp(ω) to second order: no trigonometry, and a fit converges all the same
        let half = 0.5 * omega;
        let step = DQuat::from_xyzw(half.x, half.y, half.z, 1.0 - 0.5 * half.length_squared());
        q = (step * q).normalize();
    }
    let r = DMat3::from_quat(q);
    if score(r) > score(old) { r } else { old }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fit_finds_the_rotation_of_a_stretched_rotation_from_far_away() {
        for angle in [0.3, 1.5, 3.0] {
            let axis = DVec3::new(1.0, -2.0, 0.5).normalize();
            let r = DMat3::from_quat(DQuat::from_axis_angle(axis, angle));
            let s = r * DMat3::from_diagonal(DVec3::new(2.0, 0.5, 1.0));
            let fit = fit_rotation(s, DMat3::IDENTITY);
            let error = (fit - r)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(error < 1e-9, "{angle} rad: off by {error:e}");
        }
    }
}
