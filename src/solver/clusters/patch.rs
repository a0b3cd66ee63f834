//! Updating a built layout in place after a cut, instead of building it again: removed
//! clusters free their slots, new clusters take slots and the lowest colour none of their
//! particles' clusters has, and only the clusters whose
//! weights changed get new rest offsets. The cost follows the clusters that changed,
//! not the body, when the caller names the clusters whose weights change
//! ([`ClusterTerm::patch_with_neighbours`]); otherwise one pass over the membership list
//! finds them.

use super::term::{ClusterSpec, ClusterTerm, FREE_SLOT};
use rayon::prelude::*;

impl ClusterTerm {
    /// Whether [`ClusterTerm::patch`] can update this layout (its colouring fits the
    /// 64 colour bits kept per particle).
    pub fn can_patch(&self) -> bool {
        !self.particle_colours.is_empty() || self.rest.is_empty()
    }

    /// Member particles of cluster slot `k` (none for a free or unknown slot).
    pub fn cluster_members(&self, k: usize) -> &[u32] {
        match self.cluster_range.get(k) {
            Some(&[start, end]) if self.colour_of[k] != FREE_SLOT => {
                &self.member_particle[start as usize..end as usize]
            }
            _ => &[],
        }
    }

    /// Cluster slots in use, in slot order, with their member particles.
    pub fn clusters(&self) -> impl Iterator<Item = (usize, &[u32])> {
        (0..self.cluster_range.len())
            .filter(|k| self.colour_of[*k] != FREE_SLOT)
            .map(|k| (k, self.cluster_members(k)))
    }

    /// Removes the clusters in slots `removed` and adds `added` (members are particle
    /// indices of this layout). Returns the slot of each added
    /// cluster (`u32::MAX` for one without members), or `None` when the layout cannot be
    /// patched (see [`ClusterTerm::can_patch`], or a new cluster needs a 65th colour);
    /// the layout must then be built again with [`ClusterTerm::new`].
    pub fn patch(&mut self, removed: &[u32], added: &[ClusterSpec]) -> Option<Vec<u32>> {
        self.patch_inner(removed, added, None::<fn(&[u32]) -> Vec<u32>>)
    }

    /// [`Self::patch`], told which kept clusters hold a given particle: `neighbours`
    /// receives the particles whose number of clusters the patch changes and returns
    /// the kept clusters that hold any of them (slots as before the patch; more is
    /// harmless) — the clusters whose Jacobi weights change. Saves the pass over every
    /// membership of the layout that finds them.
    pub fn patch_with_neighbours(
        &mut self,
        removed: &[u32],
        added: &[ClusterSpec],
        neighbours: impl FnOnce(&[u32]) -> Vec<u32>,
    ) -> Option<Vec<u32>> {
        self.patch_inner(removed, added, Some(neighbours))
    }

    fn patch_inner(
        &mut self,
        removed: &[u32],
        added: &[ClusterSpec],
        neighbours: Option<impl FnOnce(&[u32]) -> Vec<u32>>,
    ) -> Option<Vec<u32>> {
        if !self.can_patch() {
            return None;
        }
        self.coefficients_stale = true;
        // Every particle of a removed or added cluster, once, with its cluster count
        // before the patch: only those whose count ends different get new weights.
        let mut changed = vec![false; self.rest.len()];
        let mut touched: Vec<(u32, u32)> = Vec::new();
        for &k in removed {
            let k = k as usize;
            if self.colour_of.get(k).is_none_or(|c| *c == FREE_SLOT) {
                continue;
            }
            self.clear_lane(k);
            self.set_plastic(k, 0, None);
            let bit = !(1u64 << self.colour_of[k]);
            let [start, end] = self.cluster_range[k];
            for &m in &self.member_particle[start as usize..end as usize] {
                if !std::mem::replace(&mut changed[m as usize], true) {
                    touched.push((m, self.member_count[m as usize]));
                }
                self.member_count[m as usize] -= 1;
                self.particle_colours[m as usize] &= bit;
            }
            self.garbage += (end - start) as usize;
            self.cluster_range[k] = [0, 0];
            self.colour_of[k] = FREE_SLOT;
            self.free_slots.push(k as u32);
        }
        let mut slots = Vec::with_capacity(added.len());
        for spec in added {
            if spec.members.is_empty() {
                slots.push(u32::MAX);
                continue;
            }
            let used = spec
                .members
                .iter()
                .fold(0u64, |used, m| used | self.particle_colours[*m as usize]);
            let colour = used.trailing_ones();
            if colour >= 64 {
                return None;
            }
            for &m in spec.members {
                self.particle_colours[m as usize] |= 1 << colour;
                if !std::mem::replace(&mut changed[m as usize], true) {
                    touched.push((m, self.member_count[m as usize]));
                }
            }
            let slot = self.free_slots.pop().map(|k| k as usize);
            slots.push(self.push_cluster(spec, slot, colour) as u32);
        }
        // `changed` now marks the particles whose count changed
        let mut recounted = Vec::with_capacity(touched.len());
        for (p, old_count) in touched {
            let count = self.member_count[p as usize];
            if count == old_count {
                changed[p as usize] = false;
            } else {
                self.inv_count[p as usize] = if count > 0 { 1.0 / count as f32 } else { 0.0 };
                recounted.push(p);
            }
        }
        // Jacobi (and projective) weights are 1/nᵢ: every cluster holding a particle whose count changed
        // needs a new rest centroid; Gauss–Seidel weights are 1, so only the new clusters.
        let refresh: Vec<usize> = if self.count_weights {
            // the new clusters (their constants were computed before the last counts
            // were) and the kept clusters holding a recounted particle, in slot order
            {
                let holding = match neighbours {
                    Some(neighbours) => neighbours(&recounted),
                    None => self.slots_holding(&changed),
                };
                // (sorted rather than marked: a cut's list is short, the layout long)
                let mut refresh: Vec<usize> = holding
                    .iter()
                    .chain(&slots)
                    .map(|k| *k as usize)
                    .filter(|&k| self.colour_of.get(k).is_some_and(|c| *c != FREE_SLOT))
                    .collect();
                refresh.sort_unstable();
                refresh.dedup();
                refresh
            }
        } else {
            slots
                .iter()
                .filter(|k| **k != u32::MAX)
                .map(|k| *k as usize)
                .collect()
        };
        for k in refresh {
            self.fill_constants(k);
            // a cluster already in a batch: its lane gets the new weights (new clusters
            // are written when they are batched below)
            if self.batches.has_lane(k) {
                self.rewrite_lane(k);
            }
        }
        if 2 * self.garbage > self.member_particle.len() {
            self.compact_members();
        }
        let new: Vec<u32> = slots.iter().copied().filter(|k| *k != u32::MAX).collect();
        self.batch_added(&new);
        Some(slots)
    }

    /// The slots of the clusters that hold a `flagged` particle: a pass over every
    /// membership of the layout (in parallel).
    fn slots_holding(&self, flagged: &[bool]) -> Vec<u32> {
        self.cluster_range
            .par_iter()
            .enumerate()
            .filter(|(k, r)| {
                self.colour_of[*k] != FREE_SLOT
                    && self.member_particle[r[0] as usize..r[1] as usize]
                        .iter()
                        .any(|m| flagged[*m as usize])
            })
            .map(|(k, _)| k as u32)
            .collect()
    }

    /// Copies the live clusters' memberships to fresh arrays, dropping the garbage.
    fn compact_members(&mut self) {
        let live = self.member_particle.len() - self.garbage;
        let mut particles = Vec::with_capacity(live);
        for range in &mut self.cluster_range {
            let (start, end) = (range[0] as usize, range[1] as usize);
            let new_start = particles.len() as u32;
            particles.extend_from_slice(&self.member_particle[start..end]);
            *range = [new_start, particles.len() as u32];
        }
        self.member_particle = particles;
        self.garbage = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::math::lanes::LANES;
    use crate::solver::clusters::colouring::order_by_colour;
    use crate::solver::particles::Particles;
    use crate::solver::registry::Terms;
    use crate::solver::solve::Solver;
    use crate::solver::testing::{step, unit_specs as specs};
    use glam::Vec3;

    /// A 200-particle bar with clusters of three consecutive particles (enough batches
    /// for a small patch to update them in place).
    fn bar_clusters() -> (Vec<Vec3>, Vec<Vec<u32>>) {
        let rest = (0..200).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let clusters = (0..198).map(|i| vec![i, i + 1, i + 2]).collect();
        (rest, clusters)
    }

    /// Each cluster's members with its rest offsets and weights, sorted by members.
    fn moments(l: &ClusterTerm) -> Vec<(Vec<u32>, Vec<glam::Vec4>)> {
        let mut out: Vec<_> = l
            .clusters()
            .map(|(k, m)| (m.to_vec(), l.member_moments(k)))
            .collect();
        out.sort_by(|a, b| a.0.cmp(&b.0));
        out
    }

    #[test]
    fn told_neighbours_the_patch_matches_the_one_that_finds_them() {
        let (rest, clusters) = bar_clusters();
        let pieces = vec![vec![3, 4], vec![6, 7]];
        let removed = [3u32, 4, 5];
        let mut scanned = ClusterTerm::new(&rest, specs(&clusters), SolverMode::Jacobi);
        let mut told = scanned.clone();
        // counts before → after: 3: 3 → 3, 4: 3 → 2, 5: 3 → 0 (retired), 6: 3 → 2,
        // 7: 3 → 3; so only the kept clusters holding 4, 5 or 6 get new weights
        let kept_holding = |layout: &ClusterTerm, particles: &[u32]| -> Vec<u32> {
            layout
                .clusters()
                .filter(|(k, m)| {
                    !removed.contains(&(*k as u32)) && m.iter().any(|p| particles.contains(p))
                })
                .map(|(k, _)| k as u32)
                .collect()
        };
        let neighbours = kept_holding(&told, &[4, 5, 6]);
        assert_eq!(neighbours, [2, 6]);
        scanned.patch(&removed, &specs(&pieces)).expect("patchable");
        let mut asked = Vec::new();
        told.patch_with_neighbours(&removed, &specs(&pieces), |recounted| {
            asked = recounted.to_vec();
            neighbours.clone()
        })
        .expect("patchable");
        assert_eq!(asked, [4, 5, 6], "the particles whose count changed");
        assert_eq!(moments(&told), moments(&scanned));
        // leaving out cluster 2 ({2, 3, 4}: particle 4 lost a cluster) leaves its old
        // weights: the hint matters
        let mut short = ClusterTerm::new(&rest, specs(&clusters), SolverMode::Jacobi);
        short
            .patch_with_neighbours(&removed, &specs(&pieces), |_| vec![6])
            .expect("patchable");
        assert!(
            moments(&short) != moments(&scanned),
            "a stale cluster went unnoticed"
        );
    }

    #[test]
    fn a_patched_layout_matches_a_rebuilt_one() {
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let (rest, clusters) = bar_clusters();
            let mut patched = ClusterTerm::new(&rest, specs(&clusters), mode);
            let before = (patched.batches.len(), patched.batches.empty_lanes());
            // cut particle 5: clusters 3, 4, 5 hold it; replace them by their pieces
            let pieces = vec![vec![3, 4], vec![6, 7]];
            let slots = patched
                .patch(&[3, 4, 5], &specs(&pieces))
                .expect("patchable");
            assert_eq!(slots.len(), 2);
            assert_eq!(patched.cluster_count(), 197);
            assert_eq!(patched.membership_count(), 195 * 3 + 4);
            let mut kept: Vec<Vec<u32>> = clusters
                .iter()
                .enumerate()
                .filter(|(k, _)| ![3, 4, 5].contains(k))
                .map(|(_, m)| m.clone())
                .collect();
            kept.extend(pieces);
            let rebuilt = ClusterTerm::new(&rest, specs(&kept), mode);
            // the patch emptied three lanes and appended batches for the two pieces (one,
            // or one per colour) instead of laying out all batches again
            let appended = patched.batches.len() - before.0;
            assert!((1..=2).contains(&appended), "{mode:?}: {appended} batches");
            assert_eq!(
                patched.batches.empty_lanes(),
                before.1 + 3 + appended * LANES - 2
            );
            // the same clusters with the same rest offsets and weights (Jacobi weights
            // 1/nᵢ changed at particles 3, 4, 6, 7 and at their other clusters); a lane
            // that reads the template differs from the cluster's own offsets by the
            // rounding of its coordinates (≤ 200 here, 1.5·10⁻⁵ per ulp)
            let (a, b) = (moments(&patched), moments(&rebuilt));
            assert_eq!(a.len(), b.len());
            for ((ma, qa), (mb, qb)) in a.iter().zip(&b) {
                assert_eq!(ma, mb);
                for (x, y) in qa.iter().zip(qb) {
                    assert!((*x - *y).length() < 1e-4, "{mode:?} {ma:?}: {x} vs {y}");
                }
            }
            assert_eq!(patched.inv_count, rebuilt.inv_count);
            if mode == SolverMode::Jacobi {
                // Jacobi does not depend on cluster order: the two move alike
                let [patched, rebuilt] = [patched, rebuilt].map(|clusters| {
                    let mut particles = Particles::at_rest(&rest);
                    particles.inv_mass[0] = 0.0;
                    particles.inv_mass[5] = 0.0;
                    for (i, p) in particles.positions.iter_mut().enumerate() {
                        p.y -= 0.01 * i as f32;
                    }
                    Solver::new(clusters, Terms::default()).solve(&mut particles, &step(20));
                    particles
                });
                for (p, q) in patched.positions.iter().zip(&rebuilt.positions) {
                    assert!((*p - *q).length() < 1e-5, "{p} vs {q}");
                }
            }
        }
    }

    #[test]
    fn colours_stay_proper_and_garbage_is_compacted() {
        let (rest, clusters) = bar_clusters();
        let mut l = ClusterTerm::new(&rest, specs(&clusters), SolverMode::GaussSeidel);
        // replace every cluster by itself many times: slots are reused, garbage compacted
        for round in 0..20 {
            let k = round % 8;
            let slots = l.patch(&[k as u32], &specs(&clusters[k..k + 1])).unwrap();
            assert_eq!(slots, vec![k as u32], "the freed slot is reused");
            assert!(l.member_particle.len() <= 2 * l.membership_count());
        }
        assert_eq!(l.cluster_count(), 198);
        let (order, start) = order_by_colour(&l.colour_of, FREE_SLOT);
        for group in start.windows(2) {
            let mut seen = vec![false; rest.len()];
            for &k in &order[group[0] as usize..group[1] as usize] {
                let [s, e] = l.cluster_range[k as usize];
                for &m in &l.member_particle[s as usize..e as usize] {
                    assert!(!seen[m as usize], "two clusters of one colour share {m}");
                    seen[m as usize] = true;
                }
            }
        }
    }
}
