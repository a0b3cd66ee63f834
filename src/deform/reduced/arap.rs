//! ARAP in a handle subspace: the lattice spokes of [`crate::deform::arap`], one
//! rotation per block of particles instead of one per particle, and the positions
//! `V̄ + W ΔH` with the user's handles' parameters held and the rest solved for.

use super::{DenseFactor, Groups, block_groups, weighted_gram};
use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::deform::arap::{ArapOptions, ArapReport};
use crate::deform::weights::Weights;
use crate::error::{CleaveError, Result};
use glam::{DMat3, DVec3, Vec3};

/// ARAP reduced to a subspace whose first `fixed` columns the user's handles hold.
#[derive(Clone, Debug)]
pub struct ReducedArap {
    groups: Groups,
    fixed: usize,
    factor: DenseFactor,
}

impl ReducedArap {
    /// Precomputes the reduced problem of `lattice` (resting at `rest`) in the subspace
    /// `weights`, whose first `fixed` columns are held, with one rotation per block of
    /// `group_cells`³ cells.
    pub fn new(
        lattice: &Lattice,
        rest: &[Vec3],
        weights: &Weights,
        fixed: usize,
        group_cells: u32,
    ) -> Result<Self> {
        let h = weights.columns();
        if fixed >= h {
            return Err(CleaveError::InvalidEntity(
                "reduced ARAP: the subspace has no column to solve for".into(),
            ));
        }
        let (group, count) = block_groups(lattice, group_cells);
        let mut groups = Groups::new(count, h);
        let (mut wi, mut wj, mut d) = (vec![0.0; h], vec![0.0; h], vec![0.0; h]);
        for i in lattice.live_particles() {
            weights.row_into(i, &mut wi);
            for j in lattice.links(i) {
                if j == NO_PARTICLE {
                    continue;
                }
                weights.row_into(j, &mut wj);
                for c in 0..h {
                    d[c] = wi[c] - wj[c];
                }
                let e = (rest[i as usize] - rest[j as usize]).as_dvec3();
                groups.add(group[i as usize] as usize, 1.0, &d, e);
            }
        }
        // G = Σ over spokes (from both ends) of DᵀD = 2 Wᵀ L W, L the lattice graph's
        // Laplacian: one outer product per particle instead of one per spoke
        let live: Vec<u32> = lattice.live_particles().collect();
        groups.set_g(weighted_gram(&live, h, |i, a, b| {
            weights.row_into(i, a);
            let mut wj = vec![0.0; h];
            let mut degree = 0.0;
            b.fill(0.0);
            for j in lattice.links(i) {
                if j != NO_PARTICLE {
                    weights.row_into(j, &mut wj);
                    for (b, w) in b.iter_mut().zip(&wj) {
                        *b -= w;
                    }
                    degree += 1.0;
                }
            }
            for (b, a) in b.iter_mut().zip(a.iter()) {
                *b += degree * a;
            }
            2.0
        }));
        let factor = DenseFactor::new(h - fixed, |r, c| groups.g(fixed + r, fixed + c))
            .ok_or_else(|| {
                CleaveError::InvalidEntity(
                    "reduced ARAP: the subspace's free columns are not independent".into(),
                )
            })?;
        Ok(Self {
            groups,
            fixed,
            factor,
        })
    }

    /// One rotation per group, each the identity: the rotations to start from at rest.
    pub fn rest_rotations(&self) -> Vec<DMat3> {
        vec![DMat3::IDENTITY; self.groups.len()]
    }

    /// Solves for the free columns of `dh` (one displacement per column: the held ones
    /// given, the free ones the first guess in and the result out), the groups'
    /// `rotations` fitted from where they are (the previous frame's, or
    /// [`ReducedArap::rest_rotations`]).
    ///
    /// # Panics
    /// If `rotations` does not hold one rotation per group.
    pub fn solve(
        &self,
        dh: &mut [Vec3],
        rotations: &mut [DMat3],
        options: &ArapOptions,
    ) -> ArapReport {
        assert_eq!(rotations.len(), self.groups.len(), "one rotation per group");
        let mut x: Vec<DVec3> = dh.iter().map(|d| d.as_dvec3()).collect();
        let (fixed, h) = (self.fixed, x.len());
        let mut loads = self.groups.rotated_loads(rotations);
        let mut report = ArapReport {
            energies: vec![self.groups.energy(&x, rotations, &loads)],
            iterations: 0,
        };
        while report.iterations < options.max_iterations {
            self.groups.fit(&x, rotations);
            loads = self.groups.rotated_loads(rotations);
            let mut rhs: Vec<DVec3> = (fixed..h)
                .map(|r| {
                    loads[r]
                        - (0..fixed)
                            .map(|c| self.groups.g(r, c) * x[c])
                            .sum::<DVec3>()
                })
                .collect();
            self.factor.solve(&mut rhs);
            x[fixed..].copy_from_slice(&rhs);
            report.iterations += 1;
            // the energy is only needed to stop early, and at the end
            if options.tolerance > 0.0 || report.iterations == options.max_iterations {
                let energy = self.groups.energy(&x, rotations, &loads);
                let before = *report.energies.last().expect("the first energy");
                report.energies.push(energy);
                if before - energy <= options.tolerance * before {
                    break;
                }
            }
        }
        for (d, x) in dh.iter_mut().zip(&x) {
            *d = x.as_vec3();
        }
        report
    }
}
