//! The shape of a body's clustering in four numbers — how many clusters, their mean
//! size, the memberships per particle and the clusters' mean extent — and the ratios of
//! one clustering's numbers to another's. `cleave fidelity` compares a cut body's
//! rebuilt clusters with a fresh clustering of the same geometry this way: the
//! reconstruction aims to keep all four.

use crate::body::lattice::Lattice;
use glam::IVec3;
use serde::Serialize;

/// Counts and sizes of one clustering of a lattice's live particles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ClusterShape {
    /// Clusters.
    pub clusters: usize,
    /// Mean members per cluster.
    pub mean_size: f64,
    /// Memberships (sum of cluster sizes) per live particle.
    pub memberships_per_particle: f64,
    /// Mean over clusters of the diagonal of the members' lattice bounding box, in
    /// lattice cells (a full 3×3×3 cluster: 2√3 ≈ 3.46).
    pub mean_extent: f64,
}

impl ClusterShape {
    /// The shape of `clusters` (member lists of live particles of `lattice`).
    pub fn of<'a>(lattice: &Lattice, clusters: impl IntoIterator<Item = &'a [u32]>) -> Self {
        let (mut count, mut memberships, mut extent) = (0usize, 0usize, 0.0f64);
        for members in clusters {
            let Some(&first) = members.first() else {
                continue;
            };
            let (mut lo, mut hi) = (lattice.coord(first), lattice.coord(first));
            for &m in members {
                lo = lo.min(lattice.coord(m));
                hi = hi.max(lattice.coord(m));
            }
            count += 1;
            memberships += members.len();
            extent += diagonal(hi - lo);
        }
        let per = |total: f64, n: usize| if n == 0 { 0.0 } else { total / n as f64 };
        Self {
            clusters: count,
            mean_size: per(memberships as f64, count),
            memberships_per_particle: per(memberships as f64, lattice.live_count()),
            mean_extent: per(extent, count),
        }
    }

    /// Each number of this shape over the same number of `reference`'s.
    pub fn ratios_to(&self, reference: &ClusterShape) -> ShapeRatios {
        ShapeRatios {
            clusters: self.clusters as f64 / reference.clusters as f64,
            mean_size: self.mean_size / reference.mean_size,
            memberships_per_particle: self.memberships_per_particle
                / reference.memberships_per_particle,
            mean_extent: self.mean_extent / reference.mean_extent,
        }
    }
}

/// The length of a lattice box's diagonal.
fn diagonal(span: IVec3) -> f64 {
    span.as_dvec3().length()
}

/// One clustering's [`ClusterShape`] over another's, number by number.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ShapeRatios {
    /// Cluster counts.
    pub clusters: f64,
    /// Mean sizes.
    pub mean_size: f64,
    /// Memberships per particle.
    pub memberships_per_particle: f64,
    /// Mean extents.
    pub mean_extent: f64,
}

impl ShapeRatios {
    /// The largest relative difference of the three size measures (mean size,
    /// memberships per particle, mean extent) from 1.
    pub fn worst(&self) -> f64 {
        [
            self.mean_size,
            self.memberships_per_particle,
            self.mean_extent,
        ]
        .iter()
        .map(|r| (r - 1.0).abs())
        .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn a_cube_and_a_bar_measure_as_counted_by_hand() {
        let l = Shape::cuboid(UVec3::new(3, 3, 4)).voxelise(1.0).unwrap();
        let all: Vec<u32> = l.live_particles().collect();
        let cube: Vec<u32> = all
            .iter()
            .copied()
            .filter(|p| l.coord(*p).z < l.coord(all[0]).z + 3)
            .collect();
        let bar = [all[0], all[1], all[2]];
        let shape = ClusterShape::of(&l, [&cube[..], &bar[..]]);
        assert_eq!(shape.clusters, 2);
        assert_eq!(shape.mean_size, 15.0);
        assert_eq!(shape.memberships_per_particle, 30.0 / 36.0);
        // the cube's diagonal 2√3, the bar's 2
        assert!((shape.mean_extent - (12f64.sqrt() + 2.0) / 2.0).abs() < 1e-12);
        let half = ClusterShape::of(&l, [&bar[..]]);
        let r = shape.ratios_to(&half);
        assert_eq!(r.clusters, 2.0);
        assert_eq!(r.mean_size, 5.0);
        assert!((r.worst() - 9.0).abs() < 1e-12, "{r:?}");
        assert_eq!(ClusterShape::of(&l, []), ClusterShape::default());
    }
}
