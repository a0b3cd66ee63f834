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
use rayon::prelude::*;
use smallvec::SmallVec;

/// Match tolerance, relative to the size of the cluster's rest coordinates.
pub(in crate::solver) const TOLERANCE: f32 = 64.0 * f32::EPSILON;

/// Clusters sampled to choose the template.
const SAMPLES: usize = 64;

/// A cluster's particles in the template's member order.
pub(in crate::solver) type Order = SmallVec<[u32; 32]>;

impl ClusterTerm {
    /// The members of cluster slot `k` in canonical order, as their sort keys: ordered
    /// by rest offset (z, then y, then x, on a grid of 1/64 of the largest offset, so
    /// rounding cannot reorder a lattice cluster's members), ties by particle, the
    /// particle in the low bits ([`member_of_key`]); with the cluster's match scale, the
    /// largest coordinate of its rest centroid and offsets (the match tolerance is
    /// relative to it).
    fn canonical_keys(&self, k: usize) -> (SmallVec<[u64; 32]>, f32) {
        let members = self.cluster_members(k);
        let offset = |m: u32| self.rest[m as usize] - self.rest_centroid[k];
        let extent = members
            .iter()
            .map(|&m| offset(m).abs().max_element())
            .fold(0.0, f32::max);
        let grid = if extent > 0.0 { 64.0 / extent } else { 0.0 };
        // one integer key per member: cells in [-64, 64] biased to 8 bits each, then
        // the particle (below 2^28, see `MAX_SOLVER_PARTICLES`); the keys are distinct,
        // as the members are, so any sort gives the one order. (Each key is worked out
        // once: sorting the members by a key closure works it out at every comparison.)
        let key = |m: u32| {
            let cell = ((offset(m) * grid).round() + Vec3A::splat(64.0)).as_uvec3();
            (u64::from(cell.z) << 52)
                | (u64::from(cell.y) << 44)
                | (u64::from(cell.x) << 36)
                | u64::from(m)
        };
        // (written into a plain array: collecting into the small vector pushes one
        // key at a time, which costs more than the keys)
        let mut keys = match members.len() {
            n @ 0..=32 => {
                let mut buffer = [0u64; 32];
                for (slot, &m) in buffer.iter_mut().zip(members) {
                    *slot = key(m);
                }
                SmallVec::from_buf_and_len(buffer, n)
            }
            _ => SmallVec::from_vec(members.iter().map(|&m| key(m)).collect()),
        };
        keys.sort_unstable();
        let scale = extent.max(self.rest_centroid[k].abs().max_element());
        (keys, scale)
    }

    /// The rest offset (from the rest centroid of cluster slot `k`) and weight of member
    /// `m`.
    fn offset_and_weight(&self, k: usize, m: u32) -> (Vec3A, f32) {
        (
            self.rest[m as usize] - self.rest_centroid[k],
            self.weight(m),
        )
    }

    /// The members of cluster slot `k` with their rest offsets and weights, in
    /// canonical order, and its match scale ([`Self::canonical_keys`]).
    fn canonical(&self, k: usize) -> (Canonical, f32) {
        let (keys, scale) = self.canonical_keys(k);
        let members = (keys.iter())
            .map(|&key| {
                let m = member_of_key(key);
                let (q, w) = self.offset_and_weight(k, m);
                (m, q, w)
            })
            .collect();
        (members, scale)
    }

    /// Whether a cluster of match scale `scale` with these rest offsets and weights, in
    /// canonical order, matches `template`: same size, same weights, offsets equal
    /// within the tolerance.
    fn matches(
        members: impl ExactSizeIterator<Item = (Vec3A, f32)>,
        scale: f32,
        template: &Template,
    ) -> bool {
        if members.len() != template.len() {
            return false;
        }
        let tolerance = TOLERANCE * scale;
        members.enumerate().all(|(j, (q, w))| {
            let (tq, tw) = template.member(j);
            w == tw && (q - tq).abs().max_element() <= tolerance
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
        let sample: Vec<(Canonical, f32, Vec3A)> = spread
            .map(|k| {
                let (members, scale) = self.canonical(k);
                (members, scale, self.rest_centroid[k])
            })
            .collect();
        // each sampled shape's matches, as their indices in the sample (the candidates
        // tested in parallel), and of those the shape most of the sample shares
        let matchings: Vec<Vec<usize>> = (sample.par_iter())
            .map(|(members, _, _)| {
                let candidate = Template::of(members);
                (0..sample.len())
                    .filter(|&i| {
                        let (members, scale, _) = &sample[i];
                        let members = members.iter().map(|(_, q, w)| (*q, *w));
                        Self::matches(members, *scale, &candidate)
                    })
                    .collect()
            })
            .collect();
        let mut best: Vec<usize> = Vec::new();
        for matching in matchings {
            if matching.len() > best.len().max(1) {
                best = matching;
            }
        }
        // its values from the cluster nearest the origin, whose offsets rounded least
        let nearest = best.into_iter().min_by(|&a, &b| {
            let size = |i: usize| sample[i].2.abs().max_element();
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
        // (read off the keys: a cluster that matches needs no list of its offsets)
        let (keys, scale) = self.canonical_keys(k);
        let members = keys
            .iter()
            .map(|&key| self.offset_and_weight(k, member_of_key(key)));
        Self::matches(members, scale, template)
            .then(|| keys.iter().map(|&key| member_of_key(key)).collect())
    }
}

/// The particle of a key of [`ClusterTerm::canonical_keys`].
fn member_of_key(key: u64) -> u32 {
    (key & ((1 << 36) - 1)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::testing::unit_specs;
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    /// The canonical order as its definition reads: the members sorted by their cell on
    /// the grid of 1/64 of the largest offset (z, then y, then x), then by particle.
    fn sorted_by_definition(l: &ClusterTerm, k: usize) -> Vec<u32> {
        let centroid = l.rest_centroid[k];
        let offset = |m: u32| l.rest[m as usize] - centroid;
        let members = l.cluster_members(k);
        let extent = (members.iter())
            .map(|&m| offset(m).abs().max_element())
            .fold(0.0, f32::max);
        let grid = if extent > 0.0 { 64.0 / extent } else { 0.0 };
        let mut sorted = members.to_vec();
        sorted.sort_by_key(|&m| {
            let cell = (offset(m) * grid).round().as_ivec3();
            (cell.z, cell.y, cell.x, m)
        });
        sorted
    }

    #[test]
    fn canonical_order_is_the_members_sorted_by_cell_then_particle() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(31);
        // a jittered lattice far from the origin, each place held by two particles (as
        // a split's halves rest near each other: their cells tie), and clusters of 1 to
        // 40 members (past 32 the keys do not fit inline)
        let places: Vec<Vec3> = (0..2048)
            .map(|i| {
                let c = Vec3::new((i % 16) as f32, (i / 16 % 16) as f32, (i / 256) as f32);
                c * 0.05 + Vec3::splat(300.0) + Vec3::splat(rng.random_range(-1e-3..1e-3))
            })
            .collect();
        let rest: Vec<Vec3> = (0..4096).map(|i| places[i % 2048]).collect();
        let clusters: Vec<Vec<u32>> = (1..=40)
            .flat_map(|size| std::iter::repeat_n(size, 3))
            .map(|size| {
                let mut members: Vec<u32> = (0..size).map(|_| rng.random_range(0..4096)).collect();
                members.sort_unstable();
                members.dedup();
                members
            })
            .collect();
        let l = ClusterTerm::new(&rest, unit_specs(&clusters), SolverMode::Jacobi);
        let mut long = 0;
        for (k, members) in l.clusters() {
            let expected = sorted_by_definition(&l, k);
            let (canonical, _) = l.canonical(k);
            let sorted: Vec<u32> = canonical.iter().map(|(m, _, _)| *m).collect();
            assert_eq!(sorted, expected, "cluster {k}");
            // a cluster matches the template of its own shape, in that order
            let order = l.template_order(k, &Template::of(&canonical));
            assert_eq!(order.map(|o| o.to_vec()), Some(expected), "cluster {k}");
            long += usize::from(members.len() > 32);
        }
        assert!(long > 0, "some clusters past 32 members");
    }
}
