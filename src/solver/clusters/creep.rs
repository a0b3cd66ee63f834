//! The clusters' plastic flow ([`super::plastic`]): after every substep each plastic
//! cluster is fitted to the solved positions and its rest shape flows as
//! [`crate::solver::yielding`] describes, its members weighted as in the kernel's fit. A
//! cluster whose shape flowed gets its lane and its offset bias written again. Plastic
//! clusters never read the shared template: their shapes are their own.
//!
//! A cluster a cut rebuilds starts again from its lattice shape; a cluster a layout
//! rebuild carries over unchanged keeps its shift ([`PlasticSpec::shift`]).

use super::plastic::{Offsets, PlasticCluster, PlasticSpec};
use super::term::{CLUSTERS_PER_TASK, ClusterTerm};
use glam::Vec3A;
use rayon::prelude::*;

/// Rotation iterations of a creep fit, warm-started from the cluster's last fit of the
/// substep (so a few settle it).
const FIT_ITERATIONS: u32 = 8;

impl ClusterTerm {
    /// Makes cluster slot `k` (of `members` members) plastic as `spec` says, or elastic.
    pub(in crate::solver) fn set_plastic(
        &mut self,
        k: usize,
        members: usize,
        spec: Option<PlasticSpec>,
    ) {
        match spec {
            Some(spec) => {
                if self.plastic.len() <= k {
                    self.plastic.resize(k + 1, None);
                }
                self.plastic[k] = Some(PlasticCluster::new(spec, members));
            }
            None => {
                if let Some(p) = self.plastic.get_mut(k) {
                    *p = None;
                }
            }
        }
    }

    /// The plastic shift of each member's rest offset of cluster slot `k` (member
    /// order), or `None` for an elastic cluster.
    pub fn plastic_shift(&self, k: usize) -> Option<&[Vec3A]> {
        self.plastic
            .get(k)
            .and_then(|p| p.as_ref())
            .map(|p| p.shift.as_slice())
    }

    /// Whether the plastic data fits the clusters (a loaded layout's check): one shift
    /// per member of each plastic cluster, all finite.
    pub fn plasticity_fits(&self) -> bool {
        self.plastic.len() <= self.cluster_range.len()
            && self.plastic.iter().enumerate().all(|(k, p)| {
                p.as_ref().is_none_or(|p| {
                    p.shift.len() == self.cluster_size(k) && p.shift.iter().all(|s| s.is_finite())
                })
            })
    }

    /// Member `j` (particle `m`) of cluster slot `k`: its rest offset from the cluster's
    /// weighted rest centroid, plastic shift included.
    #[inline]
    pub(in crate::solver) fn rest_offset(&self, k: usize, j: usize, m: u32) -> Vec3A {
        let offset = self.rest[m as usize] - self.rest_centroid[k];
        match self.plastic_shift(k) {
            Some(shift) => offset + shift[j],
            None => offset,
        }
    }

    /// Lets every plastic cluster's rest shape flow toward its shape at the solved
    /// `positions` over a substep of `dt` (see the module docs).
    pub(in crate::solver) fn creep(&mut self, positions: &[Vec3A], dt: f32) {
        if self.plastic.is_empty() {
            return;
        }
        let mut plastic = std::mem::take(&mut self.plastic);
        let flowed: Vec<usize> = plastic
            .par_iter_mut()
            .enumerate()
            .with_min_len(CLUSTERS_PER_TASK)
            .filter_map(|(k, p)| {
                let p = p.as_mut()?;
                self.flow_cluster(k, p, positions, dt).then_some(k)
            })
            .collect();
        self.plastic = plastic;
        for k in flowed {
            self.fill_constants(k);
            if self.batches.has_lane(k) {
                self.rewrite_lane(k);
            }
        }
    }

    /// Fits cluster slot `k` to `positions` and lets its rest shape flow; returns
    /// whether it did (then `plastic`'s shift is the new one).
    fn flow_cluster(
        &self,
        k: usize,
        plastic: &mut PlasticCluster,
        positions: &[Vec3A],
        dt: f32,
    ) -> bool {
        let members = self.cluster_members(k);
        let Some(&first) = members.first() else {
            return false;
        };
        let centroid = self.rest_centroid[k];
        let lattice: Offsets = (members.iter())
            .map(|&m| self.rest[m as usize] - centroid)
            .collect();
        // (relative to the first member: full precision far from the origin)
        let origin = positions[first as usize];
        let at: Offsets = (members.iter())
            .map(|&m| positions[m as usize] - origin)
            .collect();
        let weight = |j: usize| self.weight(members[j]);
        let rotation = self.fit_rotation(k, positions, self.rotations[k], FIT_ITERATIONS);
        plastic.flow(lattice, at, weight, rotation, dt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{SolverMode, Yield};
    use crate::solver::clusters::term::ClusterSpec;
    use crate::solver::testing::unit_specs;
    use glam::{Quat, Vec3};

    const YIELD: Yield = Yield {
        strain: 0.01,
        creep: 1.0,
        max_strain: 0.5,
    };

    /// A 3×3×3 block (particle `x + 3y + 9z` at `(x, y, z)`) in two clusters, its lower
    /// and its upper two layers (sharing the middle one), plastic.
    fn block() -> (Vec<Vec3>, ClusterTerm) {
        let rest: Vec<Vec3> = (0..27u32)
            .map(|i| Vec3::new((i % 3) as f32, (i / 3 % 3) as f32, (i / 9) as f32))
            .collect();
        let clusters = vec![(0..18).collect(), (9..27).collect()];
        let specs = unit_specs(&clusters).into_iter().map(|s| ClusterSpec {
            plastic: Some(PlasticSpec {
                yielding: YIELD,
                shift: &[],
            }),
            ..s
        });
        let term = ClusterTerm::new(&rest, specs, SolverMode::Jacobi);
        (rest, term)
    }

    /// `rest` stretched along x by `stretch` about the block's middle, then turned and
    /// moved far from the origin.
    fn deformed(rest: &[Vec3], stretch: f32) -> Vec<Vec3A> {
        let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 1.1);
        rest.iter()
            .map(|r| {
                let d = *r - Vec3::ONE;
                Vec3A::from(turn * Vec3::new(d.x * stretch, d.y, d.z) + Vec3::splat(100.0))
            })
            .collect()
    }

    /// The RMS distance of cluster `k`'s rest shape, as the kernel reads it, from its
    /// members' positions in `rest` stretched along x by `stretch` (both taken about
    /// their means), over the stretched shape's RMS offset: how far the rest shape is
    /// from that stretch, as strain.
    fn strain_from(term: &ClusterTerm, k: usize, rest: &[Vec3], stretch: f32) -> f32 {
        let centred = |v: Vec<Vec3>| {
            let mean = v.iter().copied().sum::<Vec3>() / v.len() as f32;
            v.into_iter().map(move |x| x - mean)
        };
        let target = centred(
            (term.cluster_members(k).iter())
                .map(|&m| (rest[m as usize] - Vec3::ONE) * Vec3::new(stretch, 1.0, 1.0))
                .collect(),
        );
        let shape = centred(
            term.member_moments(k)
                .iter()
                .map(|q| q.truncate())
                .collect(),
        );
        let (mut off, mut spread) = (0.0, 0.0);
        for (q, t) in shape.zip(target) {
            off += (q - t).length_squared();
            spread += t.length_squared();
        }
        (off / spread).sqrt()
    }

    #[test]
    fn a_held_stretch_becomes_the_rest_shape_up_to_the_yield() {
        let (rest, mut term) = block();
        let at = deformed(&rest, 1.2);
        let before = strain_from(&term, 0, &rest, 1.2);
        for _ in 0..4 {
            term.creep(&at, 1.0);
        }
        for k in 0..2 {
            let after = strain_from(&term, k, &rest, 1.2);
            assert!(
                before > 0.05 && after <= 1.05 * YIELD.strain,
                "cluster {k}: {before} → {after}"
            );
        }
    }

    #[test]
    fn a_rigid_motion_or_a_strain_below_the_yield_leaves_the_rest_shape() {
        let (rest, mut term) = block();
        for stretch in [1.0, 1.005] {
            term.creep(&deformed(&rest, stretch), 1.0);
            for k in 0..2 {
                let shift = term.plastic_shift(k).unwrap();
                assert!(
                    shift.iter().all(|s| *s == Vec3A::ZERO),
                    "{stretch}: {shift:?}"
                );
            }
        }
    }

    #[test]
    fn a_patch_keeps_the_shifts_of_the_clusters_it_leaves_and_a_rebuild_takes_them() {
        let (rest, mut term) = block();
        term.creep(&deformed(&rest, 1.2), 1.0);
        let kept = term.plastic_shift(1).unwrap().to_vec();
        assert!(kept.iter().any(|s| s.length() > 0.01));
        let moments = term.member_moments(1);
        // cluster 0 replaced by its lower layer: cluster 1 keeps its shape, the new
        // cluster starts from its lattice shape
        let lower: Vec<u32> = (0..9).collect();
        let slots = term
            .patch(
                &[0],
                &[ClusterSpec {
                    members: &lower,
                    compliance: 0.0,
                    rotation: Quat::IDENTITY,
                    plastic: Some(PlasticSpec {
                        yielding: YIELD,
                        shift: &[],
                    }),
                }],
            )
            .expect("patchable");
        assert_eq!(term.plastic_shift(1).unwrap(), kept.as_slice());
        let new = term.plastic_shift(slots[0] as usize).unwrap();
        assert!(new.iter().all(|s| *s == Vec3A::ZERO));
        assert!(term.plasticity_fits());
        // (the weights of the middle layer changed, so its offsets moved with its centroid,
        // but the shape did not: the moments differ by one translation)
        let shifted = term.member_moments(1);
        let delta = shifted[0] - moments[0];
        for (a, b) in shifted.iter().zip(&moments) {
            assert!((*a - *b - delta).truncate().length() < 1e-5);
        }
        // a layout built again with the shift carried over has the same shape
        let members = term.cluster_members(1).to_vec();
        let again = ClusterTerm::new(
            &rest,
            [ClusterSpec {
                members: &members,
                compliance: 0.0,
                rotation: Quat::IDENTITY,
                plastic: Some(PlasticSpec {
                    yielding: YIELD,
                    shift: &kept,
                }),
            }],
            SolverMode::Jacobi,
        );
        assert_eq!(again.plastic_shift(0).unwrap(), kept.as_slice());
    }
}
