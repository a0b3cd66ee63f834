//! The guard against non-finite positions: one NaN in a cluster's fit turns the whole
//! cluster NaN, and the next iterations carry it across the body. So before a solve,
//! every live particle whose position is not finite is put back where it started the
//! substep, or, when that is not finite either, where a caller-chosen fallback says.

use super::SolverLayout;
use glam::Vec3A;
use rayon::prelude::*;

/// Particles per parallel task of the scan.
const PER_TASK: usize = 8192;

impl SolverLayout {
    /// Repairs the live particles (`live[d]`) whose position is not finite: each goes
    /// back to its substep-start position if that is finite, else to `fallback(d,
    /// positions)`. Returns their dense indices, ascending (empty on the usual path, which
    /// costs one multiply-add per particle).
    pub fn repair_non_finite(
        &mut self,
        live: &[bool],
        fallback: impl Fn(usize, &[Vec3A]) -> Vec3A,
    ) -> Vec<u32> {
        let bad: Vec<u32> = self
            .positions
            .par_chunks(PER_TASK)
            .enumerate()
            .flat_map_iter(|(task, chunk)| {
                // Σ 0·p stays zero while every point is finite
                let probe = chunk
                    .iter()
                    .fold(Vec3A::ZERO, |probe, p| probe + *p * Vec3A::ZERO);
                let first = task * PER_TASK;
                let found: Vec<u32> = if probe.is_nan() {
                    (0..chunk.len())
                        .filter(|i| !chunk[*i].is_finite() && live.get(first + i) == Some(&true))
                        .map(|i| (first + i) as u32)
                        .collect()
                } else {
                    Vec::new()
                };
                found
            })
            .collect();
        for &d in &bad {
            let d = d as usize;
            let back = self.previous[d];
            let at = if back.is_finite() {
                back
            } else {
                fallback(d, &self.positions)
            };
            self.positions[d] = at;
            self.previous[d] = at;
        }
        bad
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::{ConstraintKinds, unit_specs};
    use glam::Vec3;

    #[test]
    fn a_nan_particle_is_put_back_and_does_not_spread() {
        let rest: Vec<Vec3> = (0..10).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let clusters: Vec<Vec<u32>> = (0..8).map(|i| vec![i, i + 1, i + 2]).collect();
        let mut l = SolverLayout::new(&rest, unit_specs(&clusters), SolverMode::Jacobi);
        let live = vec![true; 10];
        assert!(l.repair_non_finite(&live, |_, _| Vec3A::ZERO).is_empty());
        // particle 3 NaN with a finite start; particle 7 NaN from the start too
        l.positions[3] = Vec3A::NAN;
        l.positions[7] = Vec3A::new(f32::INFINITY, 0.0, 0.0);
        l.previous[7] = Vec3A::NAN;
        let repaired = l.repair_non_finite(&live, |d, p| (p[d - 1] + p[d + 1]) * 0.5);
        assert_eq!(repaired, vec![3, 7]);
        assert_eq!(l.positions[3], Vec3A::new(3.0, 0.0, 0.0));
        assert_eq!(l.positions[7], Vec3A::new(7.0, 0.0, 0.0));
        l.solve(10, crate::solver::TEST_DT, &mut ConstraintKinds::default());
        assert!(l.positions.iter().all(|p| p.is_finite()));
        // a dead particle's slot is left alone
        l.positions[5] = Vec3A::NAN;
        let mut dead = live.clone();
        dead[5] = false;
        assert!(l.repair_non_finite(&dead, |_, _| Vec3A::ZERO).is_empty());
    }
}
