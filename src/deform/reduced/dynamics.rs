//! Projective dynamics reduced to a handle subspace: a body's shape-matching clusters
//! (each `½ k mⱼ ‖xⱼ − c − R(x̄ⱼ − c̄)‖²` over its members) and its inertia, with the
//! positions `V̄ + W ΔH`. The global matrix `WᵀMW/dt² + G` is constant and factored
//! once; an iteration fits each cluster's rotation from `ΔH` and solves for the free
//! columns, so a step costs in clusters × columns, and the particles are posed only
//! when the caller asks ([`Weights::pose`]).

use super::{DenseFactor, Groups, weighted_gram};
use crate::deform::weights::Weights;
use crate::error::{CleaveError, Result};
use glam::{DMat3, DVec3, Vec3};

/// A cubature of `clusters`: in each block of `cells`³ lattice cells (by the cell of a
/// cluster's first member, `coords` by particle), the first cluster, standing for all
/// the block's (its weight their count), so that a reduced step fits one rotation per
/// block instead of one per cluster.
pub fn cubature(clusters: &[Vec<u32>], coords: &[glam::IVec3], cells: u32) -> Vec<(f64, Vec<u32>)> {
    let mut kept: Vec<(f64, Vec<u32>)> = Vec::new();
    let mut index: std::collections::HashMap<glam::IVec3, usize> = Default::default();
    for members in clusters {
        let Some(&first) = members.first() else {
            continue;
        };
        let key = coords[first as usize].div_euclid(glam::IVec3::splat(cells.max(1) as i32));
        match index.get(&key) {
            Some(&k) => kept[k].0 += 1.0,
            None => {
                index.insert(key, kept.len());
                kept.push((1.0, members.clone()));
            }
        }
    }
    kept
}

/// A body's projective dynamics in a subspace whose first `fixed` columns are held by
/// the user's handles.
#[derive(Clone, Debug)]
pub struct ReducedDynamics {
    groups: Groups,
    /// `WᵀMW`, row-major.
    mass: Vec<f64>,
    /// `WᵀM1`: what gravity loads on each column.
    load: Vec<f64>,
    fixed: usize,
    dt: f64,
    factor: DenseFactor,
}

/// The state of a reduced body: its parameters' displacements and their velocities.
#[derive(Clone, Debug, PartialEq)]
pub struct ReducedState {
    /// `ΔH`, one displacement per column.
    pub dh: Vec<DVec3>,
    /// `dΔH/dt`.
    pub velocity: Vec<DVec3>,
    rotations: Vec<DMat3>,
}

impl ReducedState {
    /// The displacements in single precision, for [`Weights::pose`].
    pub fn displacements(&self) -> Vec<Vec3> {
        self.dh.iter().map(|d| d.as_vec3()).collect()
    }
}

impl ReducedDynamics {
    /// Precomputes the reduced dynamics of particles resting at `rest` in the subspace
    /// `weights` (first `fixed` columns held) for the clusters `clusters` (each with
    /// the weight it stands for: 1, or more for a [`cubature`]'s), each particle of mass
    /// `mass` (kg), the clusters' stiffness `stiffness` (1/s²: force per unit mass and
    /// displacement) and the time step `dt` (s).
    pub fn new(
        weights: &Weights,
        rest: &[Vec3],
        clusters: &[(f64, Vec<u32>)],
        mass: f64,
        stiffness: f64,
        dt: f64,
        fixed: usize,
    ) -> Result<Self> {
        let h = weights.columns();
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(CleaveError::InvalidEntity(format!(
                    "reduced dynamics: `{name}` must be finite and > 0, not {v}"
                )))
            }
        };
        positive("mass", mass)?;
        positive("stiffness", stiffness)?;
        positive("dt", dt)?;
        if fixed >= h {
            return Err(CleaveError::InvalidEntity(
                "reduced dynamics: the subspace has no column to solve for".into(),
            ));
        }
        let mut groups = Groups::new(clusters.len(), h);
        let mut membership = vec![0.0f64; rest.len()];
        let mut means = Vec::with_capacity(clusters.len());
        let (mut row, mut d) = (vec![0.0; h], vec![0.0; h]);
        for (k, (weight, members)) in clusters.iter().enumerate() {
            let w = stiffness * mass * weight;
            let mut mean = vec![0.0; h];
            let mut centre = DVec3::ZERO;
            for &j in members {
                weights.row_into(j, &mut row);
                for (m, r) in mean.iter_mut().zip(&row) {
                    *m += r;
                }
                centre += rest[j as usize].as_dvec3();
                membership[j as usize] += w;
            }
            let n = members.len().max(1) as f64;
            mean.iter_mut().for_each(|m| *m /= n);
            centre /= n;
            for &j in members {
                weights.row_into(j, &mut row);
                for c in 0..h {
                    d[c] = row[c] - mean[c];
                }
                groups.add(k, w, &d, rest[j as usize].as_dvec3() - centre);
            }
            means.push((w * n, mean));
        }
        // G = Σ_k w_k Σ_j (W_j − W̄_k)ᵀ(W_j − W̄_k)
        //   = Σ_j (Σ_{k∋j} w_k) W_jᵀW_j − Σ_k w_k |k| W̄_kᵀW̄_k
        let particles: Vec<u32> = (0..rest.len() as u32)
            .filter(|&j| membership[j as usize] > 0.0)
            .collect();
        let mut g = weighted_gram(&particles, h, |j, a, b| {
            weights.row_into(j, a);
            b.copy_from_slice(a);
            membership[j as usize]
        });
        for (wn, mean) in &means {
            for r in 0..h {
                for c in 0..h {
                    g[r * h + c] -= wn * mean[r] * mean[c];
                }
            }
        }
        groups.set_g(g);
        let all: Vec<u32> = (0..rest.len() as u32).collect();
        let mass_matrix = weighted_gram(&all, h, |j, a, b| {
            weights.row_into(j, a);
            b.copy_from_slice(a);
            mass
        });
        let mut load = vec![0.0; h];
        for j in 0..rest.len() as u32 {
            weights.row_into(j, &mut row);
            for (l, r) in load.iter_mut().zip(&row) {
                *l += mass * r;
            }
        }
        let inv_dt2 = 1.0 / (dt * dt);
        let factor = DenseFactor::new(h - fixed, |r, c| {
            mass_matrix[(fixed + r) * h + fixed + c] * inv_dt2 + groups.g(fixed + r, fixed + c)
        })
        .ok_or_else(|| {
            CleaveError::InvalidEntity(
                "reduced dynamics: the subspace's free columns are not independent".into(),
            )
        })?;
        Ok(Self {
            groups,
            mass: mass_matrix,
            load,
            fixed,
            dt,
            factor,
        })
    }

    /// The body at rest, still.
    pub fn rest_state(&self) -> ReducedState {
        let h = self.load.len();
        ReducedState {
            dh: vec![DVec3::ZERO; h],
            velocity: vec![DVec3::ZERO; h],
            rotations: vec![DMat3::IDENTITY; self.groups.len()],
        }
    }

    /// One time step of `iterations` local–global iterations, the held columns moved
    /// to `held` (one displacement per held column) and gravity `gravity` (m/s²).
    pub fn step(&self, state: &mut ReducedState, held: &[Vec3], gravity: Vec3, iterations: u32) {
        let (h, fixed) = (self.load.len(), self.fixed);
        let before = state.dh.clone();
        // the inertial target: the held columns where the user put them
        let mut target: Vec<DVec3> = (0..h)
            .map(|c| state.dh[c] + self.dt * state.velocity[c])
            .collect();
        for (t, d) in target.iter_mut().zip(held) {
            *t = d.as_dvec3();
        }
        state.dh[..fixed].copy_from_slice(&target[..fixed]);
        let inv_dt2 = 1.0 / (self.dt * self.dt);
        let g = gravity.as_dvec3();
        let inertia: Vec<DVec3> = (fixed..h)
            .map(|r| {
                let m = &self.mass[r * h..][..h];
                let free: DVec3 = (fixed..h).map(|c| m[c] * target[c]).sum();
                let held: DVec3 = (0..fixed)
                    .map(|c| (m[c] * inv_dt2 + self.groups.g(r, c)) * target[c])
                    .sum();
                free * inv_dt2 + g * self.load[r] - held
            })
            .collect();
        for _ in 0..iterations {
            self.groups.fit(&state.dh, &mut state.rotations);
            let loads = self.groups.rotated_loads(&state.rotations);
            let mut rhs: Vec<DVec3> = (fixed..h).map(|r| inertia[r - fixed] + loads[r]).collect();
            self.factor.solve(&mut rhs);
            state.dh[fixed..].copy_from_slice(&rhs);
        }
        for ((v, d), b) in state.velocity.iter_mut().zip(&state.dh).zip(&before) {
            *v = (*d - *b) / self.dt;
        }
    }
}
