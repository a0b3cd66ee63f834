//! Shared rest shapes. On a lattice most clusters are translated copies of one shape:
//! the same rest offsets (up to the rounding of their rest positions) and the same
//! weights. The layout picks the most common shape as its *template*; a batch whose
//! clusters all match it keeps only its particles, member by member in the template's
//! order, and the kernel reads the offsets and weights from the template. Such a batch
//! holds 4 bytes per membership instead of 20, and a sweep streams that much less.
//!
//! A match is decided within 64 ulps of the cluster's rest coordinates (76 µm at 10 m
//! from the origin): lattice clusters differ by a few ulps, the rounding their rest
//! positions already carry, and a cluster of another shape by a good part of a spacing.

use super::rows::{Canonical, Template};
use super::term::ClusterTerm;
use glam::Vec3A;
use smallvec::SmallVec;

/// Match tolerance, relative to the size of the cluster's rest coordinates.
pub(in crate::solver) const TOLERANCE: f32 = 64.0 * f32::EPSILON;

/// Clusters sampled to choose the template.
const SAMPLES: usize = 64;

/// A cluster's particles in the template's member order.
pub(in crate::solver) type Order = SmallVec<[u32; 32]>;

impl ClusterTerm {
    /// The members of cluster slot `k` with their rest offsets and weights, ordered by
    /// offset (z, then y, then x, on a grid of 1/64 of the largest offset, so rounding
    /// cannot reorder a lattice cluster's members), ties by particle.
    fn canonical(&self, k: usize) -> Canonical {
        let centroid = self.rest_centroid[k];
        let mut members: Canonical = self
            .cluster_members(k)
            .iter()
            .map(|&m| (m, self.rest[m as usize] - centroid, self.weight(m)))
            .collect();
        let extent = members
            .iter()
            .map(|(_, q, _)| q.abs().max_element())
            .fold(0.0, f32::max);
        let grid = if extent > 0.0 { 64.0 / extent } else { 0.0 };
        // one integer key per member: cells in [-64, 64] biased to 8 bits each, then
        // the particle (below 2^28, see `MAX_SOLVER_PARTICLES`)
        let key = |(m, q, _): &(u32, Vec3A, f32)| {
            let cell = ((*q * grid).round() + Vec3A::splat(64.0)).as_uvec3();
            (u64::from(cell.z) << 52)
                | (u64::from(cell.y) << 44)
                | (u64::from(cell.x) << 36)
                | u64::from(*m)
        };
        members.sort_unstable_by_key(key);
        members
    }

    /// Whether canonical members `members` of a cluster with rest centroid `centroid`
    /// match `template`: same size, same weights, offsets equal within the tolerance.
    fn matches(members: &Canonical, centroid: Vec3A, template: &Template) -> bool {
        if members.len() != template.len() {
            return false;
        }
        let scale = members
            .iter()
            .map(|(_, q, _)| q.abs().max_element())
            .fold(centroid.abs().max_element(), f32::max);
        let tolerance = TOLERANCE * scale;
        members.iter().enumerate().all(|(j, (_, q, w))| {
            let (tq, tw) = template.member(j);
            *w == tw && (*q - tq).abs().max_element() <= tolerance
        })
    }

    /// Chooses the template: of up to [`SAMPLES`] clusters spread over the slots, the
    /// shape that most of them match (the first on a tie), with the offsets of the
    /// matching one nearest the origin. `None` when no sampled cluster matches another.
    pub(in crate::solver) fn choose_template(&self) -> Option<Template> {
        let live: Vec<usize> = self.clusters().map(|(k, _)| k).collect();
        // a golden-ratio (Weyl) sequence of slots: a fixed stride could alias with the
        // lattice's period and see boundary clusters only
        let spread = (0..SAMPLES.min(live.len())).map(|i| {
            let fraction = (i as f64 * 0.618_033_988_749_895).fract();
            live[(fraction * live.len() as f64) as usize]
        });
        let sample: Vec<(Canonical, Vec3A)> = spread
            .map(|k| (self.canonical(k), self.rest_centroid[k]))
            .collect();
        // the shape most of the sample shares, as its members' indices in the sample
        let mut best: Vec<usize> = Vec::new();
        for (members, _) in &sample {
            let candidate = Template::of(members);
            let matching: Vec<usize> = (0..sample.len())
                .filter(|&i| Self::matches(&sample[i].0, sample[i].1, &candidate))
                .collect();
            if matching.len() > best.len().max(1) {
                best = matching;
            }
        }
        // its values from the cluster nearest the origin, whose offsets rounded least
        let nearest = best.into_iter().min_by(|&a, &b| {
            let size = |i: usize| sample[i].1.abs().max_element();
            size(a).total_cmp(&size(b))
        })?;
        Some(Template::of(&sample[nearest].0))
    }

    /// The particles of cluster slot `k` in the template's member order, when it
    /// matches `template` (a plastic cluster never does: its shape changes).
    pub(in crate::solver) fn template_order(&self, k: usize, template: &Template) -> Option<Order> {
        if template.len() == 0
            || self.cluster_size(k) != template.len()
            || self.plastic_shift(k).is_some()
        {
            return None;
        }
        let members = self.canonical(k);
        Self::matches(&members, self.rest_centroid[k], template)
            .then(|| members.iter().map(|(m, _, _)| *m).collect())
    }
}
