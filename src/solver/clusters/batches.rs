//! The clusters in batches of eight, and the batches in groups. One task runs a
//! group's batches in order, and the groups of one colour share no particle, so they
//! run in parallel. Gauss–Seidel groups batches of one cluster colour (a batch's lanes
//! share no particle, as its in-place moves need). Jacobi only reads positions and adds
//! pulls, so its batches take clusters in the particles' spatial order whatever their
//! colour, and its groups are coloured instead: a task then revisits the same few
//! thousand particles while they are in cache, where colour-major order sweeps every
//! particle once per cluster colour.
//!
//! Batches persist across patches (see [`super::patch`]): a removed cluster leaves an
//! empty lane, new clusters are appended in new batches and groups, and a cluster whose
//! weights changed has its lane rewritten; the batches are laid out afresh only when a
//! quarter of all lanes are empty.

use super::colouring::order_by_colour;
use super::rows::{
    Batches, EMPTY_LANE, MomentRow, PARTICLE_BYTES, ParticleRow, TEMPLATED, Template,
};
use super::template::Order;
use super::term::{CLUSTERS_PER_TASK, ClusterTerm, FREE_SLOT, PATCH_HEADROOM, weighted_by_count};
use crate::math::lanes::LANES;
use rayon::prelude::*;

/// Batches per group (at most).
const GROUP_BATCHES: usize = CLUSTERS_PER_TASK / LANES;

impl ClusterTerm {
    /// Puts all clusters in batches of [`LANES`] and groups (spatially for Jacobi, by
    /// cluster colour for Gauss–Seidel or when the spatial groups would need more than
    /// 64 colours) and lays out all rows (in parallel): after a build, or a patch that
    /// left the batches fragmented.
    pub(in crate::solver) fn build_batches(&mut self) {
        let template = self.choose_template().unwrap_or_default();
        self.build_batches_with(template);
    }

    /// [`Self::build_batches`] with the given template (empty: none).
    fn build_batches_with(&mut self, template: Template) {
        let old = std::mem::take(&mut self.batches);
        let empty = || {
            let mut batches = Batches {
                place: vec![u32::MAX; self.cluster_range.len()],
                ..Batches::default()
            };
            batches.start.push(0);
            batches
        };
        // which clusters match the template (a batch whose clusters all do reads it),
        // with their members in its order, kept for writing their lanes (working the
        // order out is most of a templated lane's cost)
        let orders: Vec<Option<Order>> = (0..self.cluster_range.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|k| {
                (self.colour_of[k] != FREE_SLOT)
                    .then(|| self.template_order(k, &template))
                    .flatten()
            })
            .collect();
        let mut batches = empty();
        let spatial = weighted_by_count(self.mode) && {
            let mut order: Vec<u32> = (0..self.cluster_range.len() as u32)
                .filter(|&k| self.colour_of[k as usize] != FREE_SLOT)
                .collect();
            order.sort_unstable_by_key(|&k| (self.first_member(k as usize), k));
            batches.group_colours = vec![0; self.rest.len()];
            self.add_spatial_groups(&mut batches, &order, &orders)
        };
        if !spatial {
            batches = empty();
            let (colour_order, colour_start) = order_by_colour(&self.colour_of, FREE_SLOT);
            for (colour, range) in colour_start.windows(2).enumerate() {
                let clusters = &colour_order[range[0] as usize..range[1] as usize];
                self.add_colour_groups(&mut batches, colour, clusters, &orders);
            }
        }
        let templated: Vec<bool> = batches
            .lanes
            .iter()
            .map(|lanes| {
                lanes
                    .iter()
                    .all(|&k| k == EMPTY_LANE || orders[k as usize].is_some())
            })
            .collect();
        // the old rows' allocations are reused: fresh ones would page-fault every time
        let (mut particles, mut moments) = (old.particles, old.moments);
        let len = batches.start[batches.lanes.len()] as usize;
        let mut moment_len = 0;
        let batch_rows = batches.start.windows(2).zip(&templated);
        for ((range, &templated), first) in batch_rows.zip(&mut batches.moment_start) {
            if !templated {
                *first = moment_len;
                moment_len += range[1] - range[0];
            }
        }
        let moment_len = moment_len as usize;
        particles.clear();
        particles.reserve(len + len / PATCH_HEADROOM);
        particles.resize(len, [0; LANES]);
        moments.clear();
        moments.reserve(moment_len + moment_len / PATCH_HEADROOM);
        moments.resize(moment_len, MomentRow::default());
        let (mut particles_left, mut moments_left) =
            (particles.as_mut_slice(), moments.as_mut_slice());
        let mut per_batch = Vec::with_capacity(batches.lanes.len());
        for (range, &templated) in batches.start.windows(2).zip(&templated) {
            let rows = (range[1] - range[0]) as usize;
            let (p, tail) = std::mem::take(&mut particles_left).split_at_mut(rows);
            particles_left = tail;
            let m = (!templated).then(|| {
                let (m, tail) = std::mem::take(&mut moments_left).split_at_mut(rows);
                moments_left = tail;
                m
            });
            per_batch.push((p, m));
        }
        per_batch
            .into_par_iter()
            .zip(&batches.lanes)
            .with_min_len(64)
            .for_each(|((particles, mut moments), lanes)| {
                for (l, &k) in lanes.iter().enumerate() {
                    if k == EMPTY_LANE {
                        continue;
                    }
                    match moments {
                        Some(ref mut moments) => self.write_lane(particles, moments, l, k as usize),
                        None => write_template_lane(particles, l, &orders[k as usize]),
                    }
                }
            });
        batches.particles = particles;
        batches.moments = moments;
        batches.template = template;
        self.batches = batches;
    }

    /// The first (lowest) member particle of cluster slot `k`: the clusters' spatial
    /// order (particles are in spatial order).
    fn first_member(&self, k: usize) -> u32 {
        let [start, end] = self.cluster_range[k];
        if start < end {
            self.member_particle[start as usize]
        } else {
            u32::MAX
        }
    }

    /// Appends the clusters `slots` (all of colour `colour`, so no two share a
    /// particle) in batches, and the batches in groups of that colour. `orders` holds
    /// the members of each slot that matches the template in its order (empty: none
    /// does).
    fn add_colour_groups(
        &self,
        batches: &mut Batches,
        colour: usize,
        slots: &[u32],
        orders: &[Option<Order>],
    ) {
        for group in slots.chunks(LANES * GROUP_BATCHES) {
            let first = self.add_group_batches(batches, group, orders);
            batches.push_group(colour, first);
        }
    }

    /// Appends the clusters `slots` (in spatial order) in batches and groups, giving
    /// each group the lowest colour that no group holding one of its particles has.
    /// Returns false when a group would need a 65th colour (the batches are then
    /// unusable and must be laid out again by cluster colour). `orders` as for
    /// [`Self::add_colour_groups`].
    fn add_spatial_groups(
        &self,
        batches: &mut Batches,
        slots: &[u32],
        orders: &[Option<Order>],
    ) -> bool {
        for group in slots.chunks(LANES * GROUP_BATCHES) {
            let first = self.add_group_batches(batches, group, orders);
            let members = || {
                group.iter().flat_map(|&k| {
                    let [start, end] = self.cluster_range[k as usize];
                    &self.member_particle[start as usize..end as usize]
                })
            };
            let used = members().fold(0u64, |used, &m| used | batches.group_colours[m as usize]);
            let colour = used.trailing_ones() as usize;
            if colour >= 64 {
                return false;
            }
            for &m in members() {
                batches.group_colours[m as usize] |= 1 << colour;
            }
            batches.push_group(colour, first);
        }
        true
    }

    /// Appends the clusters `slots` of one group in batches of [`LANES`], those that
    /// match the template (those with an order in `orders`, empty for none) first, so
    /// that they fill batches of their own; returns the group's first batch.
    fn add_group_batches(
        &self,
        batches: &mut Batches,
        slots: &[u32],
        orders: &[Option<Order>],
    ) -> u32 {
        let first = batches.lanes.len() as u32;
        let matching = |k: &u32| orders.get(*k as usize).is_some_and(Option::is_some);
        let (templated, other): (Vec<u32>, Vec<u32>) = slots.iter().partition(|k| matching(k));
        for chunk in templated.chunks(LANES).chain(other.chunks(LANES)) {
            self.add_batch(batches, chunk);
        }
        first
    }

    /// Appends a batch of the clusters `slots` (at most [`LANES`]) to `batches` without
    /// writing its rows (they stay as the caller leaves them).
    fn add_batch(&self, batches: &mut Batches, slots: &[u32]) {
        let b = batches.lanes.len() as u32;
        let mut lanes = [EMPTY_LANE; LANES];
        lanes[..slots.len()].copy_from_slice(slots);
        let rows = slots
            .iter()
            .map(|&k| self.cluster_size(k as usize))
            .max()
            .unwrap_or(0);
        for (l, &k) in slots.iter().enumerate() {
            batches.place[k as usize] = b * LANES as u32 + l as u32;
        }
        batches.lanes.push(lanes);
        batches.empty_lanes += LANES - slots.len();
        let last = batches.start[batches.start.len() - 1];
        batches.start.push(last + rows as u32);
        // (no moment rows yet: the caller gives them, or the template)
        batches.moment_start.push(TEMPLATED);
    }

    /// Number of members of cluster slot `k`.
    #[inline]
    pub(in crate::solver) fn cluster_size(&self, k: usize) -> usize {
        let [start, end] = self.cluster_range[k];
        (end - start) as usize
    }

    /// Writes lane `l` of a batch's rows for cluster slot `k`: its members' particles,
    /// rest offsets and weights, then padding at its first member.
    fn write_lane(
        &self,
        particles: &mut [ParticleRow],
        moments: &mut [MomentRow],
        l: usize,
        k: usize,
    ) {
        let [start, end] = self.cluster_range[k];
        let members = &self.member_particle[start as usize..end as usize];
        let rows = particles.iter_mut().zip(moments.iter_mut());
        for (j, ((at, row), &m)) in rows.zip(members).enumerate() {
            let offset = self.rest_offset(k, j, m);
            row.offset.x.as_mut_array()[l] = offset.x;
            row.offset.y.as_mut_array()[l] = offset.y;
            row.offset.z.as_mut_array()[l] = offset.z;
            row.weight.as_mut_array()[l] = self.weight(m);
            at[l] = m * PARTICLE_BYTES;
        }
        let first = members.first().copied().unwrap_or(0);
        let padding = particles
            .iter_mut()
            .zip(moments.iter_mut())
            .skip(members.len());
        for (at, row) in padding {
            row.offset.x.as_mut_array()[l] = 0.0;
            row.offset.y.as_mut_array()[l] = 0.0;
            row.offset.z.as_mut_array()[l] = 0.0;
            row.weight.as_mut_array()[l] = 0.0;
            at[l] = first * PARTICLE_BYTES;
        }
    }

    /// The batch and lane of cluster slot `k`.
    fn place(&self, k: usize) -> (usize, usize) {
        let place = self.batches.place[k] as usize;
        (place / LANES, place % LANES)
    }

    /// Rest offsets from the weighted rest centroid and matching weights, `(q, w)`, of
    /// the members of cluster slot `k` (in the order of [`ClusterTerm::clusters`]), as
    /// the kernel reads them from the cluster's lane (or the template).
    pub fn member_moments(&self, k: usize) -> Vec<glam::Vec4> {
        let (b, l) = self.place(k);
        let rows = self.batch_particles(b).iter().zip(self.batch_moments(b));
        let mut lane: Vec<(u32, glam::Vec4)> = rows
            .take(self.cluster_size(k))
            .map(|(at, row)| {
                let q = glam::Vec4::new(
                    row.offset.x.as_array()[l],
                    row.offset.y.as_array()[l],
                    row.offset.z.as_array()[l],
                    row.weight.as_array()[l],
                );
                (at[l], q)
            })
            .collect();
        // (a templated lane holds its members in the template's order)
        lane.sort_unstable_by_key(|(at, _)| *at);
        self.cluster_members(k)
            .iter()
            .map(|m| {
                let row = lane.partition_point(|(at, _)| *at < m * PARTICLE_BYTES);
                lane[row].1
            })
            .collect()
    }

    /// Patch step: empties the lane of cluster slot `k` (call before the slot is freed).
    pub(in crate::solver) fn clear_lane(&mut self, k: usize) {
        let (b, l) = self.place(k);
        let batches = &mut self.batches;
        let range = batches.start[b] as usize..batches.start[b + 1] as usize;
        for at in &mut batches.particles[range.clone()] {
            at[l] = 0;
        }
        let first = batches.moment_start[b];
        if first != TEMPLATED {
            let first = first as usize;
            for row in &mut batches.moments[first..first + range.len()] {
                row.weight.as_mut_array()[l] = 0.0;
            }
        }
        batches.lanes[b][l] = EMPTY_LANE;
        batches.place[k] = u32::MAX;
        batches.empty_lanes += 1;
    }

    /// Patch step: rewrites the lane of cluster slot `k` (its weights changed); a
    /// templated batch gets rows of its own first.
    pub(in crate::solver) fn rewrite_lane(&mut self, k: usize) {
        let (b, l) = self.place(k);
        let mut batches = std::mem::take(&mut self.batches);
        if batches.moment_start[b] == TEMPLATED {
            self.write_own_rows(&mut batches, b);
        } else {
            let range = batches.start[b] as usize..batches.start[b + 1] as usize;
            let first = batches.moment_start[b] as usize;
            let moments = &mut batches.moments[first..first + range.len()];
            self.write_lane(&mut batches.particles[range], moments, l, k);
        }
        self.batches = batches;
    }

    /// Gives batch `b` moment rows of its own (appended) and writes every lane in use:
    /// a batch a patch added, or a templated one whose weights change.
    fn write_own_rows(&self, batches: &mut Batches, b: usize) {
        let range = batches.start[b] as usize..batches.start[b + 1] as usize;
        let first = batches.moments.len();
        batches.moment_start[b] = first as u32;
        batches
            .moments
            .resize(first + range.len(), MomentRow::default());
        let (particles, moments) = (&mut batches.particles[range], &mut batches.moments[first..]);
        for (l, &k) in batches.lanes[b].iter().enumerate() {
            if k != EMPTY_LANE {
                self.write_lane(particles, moments, l, k as usize);
            }
        }
    }

    /// Patch step: puts the new clusters `added` (slots) into new batches and groups
    /// (spatially, or by colour, as the batches are), or lays all batches out afresh
    /// when they are fragmented or the new groups need a 65th colour.
    pub(in crate::solver) fn batch_added(&mut self, added: &[u32]) {
        if self.batches.fragmented() {
            self.build_batches();
            return;
        }
        let mut added: Vec<u32> = added.to_vec();
        let mut batches = std::mem::take(&mut self.batches);
        batches.place.resize(self.cluster_range.len(), u32::MAX);
        let first_new = batches.lanes.len();
        if batches.group_colours.is_empty() {
            added.sort_unstable_by_key(|&k| (self.colour_of[k as usize], k));
            let same_colour =
                |a: &u32, b: &u32| self.colour_of[*a as usize] == self.colour_of[*b as usize];
            for group in added.chunk_by(same_colour) {
                let colour = self.colour_of[group[0] as usize] as usize;
                self.add_colour_groups(&mut batches, colour, group, &[]);
            }
        } else {
            added.sort_unstable_by_key(|&k| (self.first_member(k as usize), k));
            if !self.add_spatial_groups(&mut batches, &added, &[]) {
                self.build_batches();
                return;
            }
        }
        let len = batches.start[batches.lanes.len()] as usize;
        batches.particles.resize(len, [0; LANES]);
        for b in first_new..batches.lanes.len() {
            self.write_own_rows(&mut batches, b);
        }
        self.batches = batches;
    }
}

/// Writes lane `l` of a templated batch's particle rows for a cluster that matches the
/// template, its members in the template's order being `order`.
fn write_template_lane(particles: &mut [ParticleRow], l: usize, order: &Option<Order>) {
    let order = order
        .as_ref()
        .expect("a templated batch's clusters match the template");
    for (at, &m) in particles.iter_mut().zip(order) {
        at[l] = m * PARTICLE_BYTES;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::particles::Particles;
    use crate::solver::registry::Terms;
    use crate::solver::solve::Solver;
    use crate::solver::testing::{step, unit_specs as specs};
    use glam::Vec3;

    /// A 16³ lattice (x-major particle order) with 3×3×3 clusters at stride 2.
    fn grid() -> (Vec<Vec3>, Vec<Vec<u32>>) {
        let n = 16u32;
        let index = |x: u32, y: u32, z: u32| x + n * (y + n * z);
        let rest = (0..n * n * n)
            .map(|i| Vec3::new((i % n) as f32, (i / n % n) as f32, (i / n / n) as f32))
            .collect();
        let mut clusters = Vec::new();
        for (cx, cy, cz) in (0..n / 2)
            .flat_map(|x| (0..n / 2).flat_map(move |y| (0..n / 2).map(move |z| (x, y, z))))
        {
            let mut members = Vec::new();
            for z in (2 * cz).saturating_sub(1)..(2 * cz + 2).min(n) {
                for y in (2 * cy).saturating_sub(1)..(2 * cy + 2).min(n) {
                    for x in (2 * cx).saturating_sub(1)..(2 * cx + 2).min(n) {
                        members.push(index(x, y, z));
                    }
                }
            }
            members.sort_unstable();
            clusters.push(members);
        }
        (rest, clusters)
    }

    /// Every live cluster has exactly one lane, and no particle is in two groups of one
    /// colour (Gauss–Seidel: in two clusters of one colour).
    fn assert_groups_disjoint(l: &ClusterTerm) {
        let mut lanes = vec![0; l.cluster_range.len()];
        for groups in &l.batches.of_colour {
            let mut owner = vec![usize::MAX; l.particle_count()];
            for (g, group) in groups.iter().enumerate() {
                for b in group[0]..group[1] {
                    for &k in l.batches.lanes[b as usize]
                        .iter()
                        .filter(|k| **k != EMPTY_LANE)
                    {
                        lanes[k as usize] += 1;
                        let unit = if weighted_by_count(l.mode) {
                            g
                        } else {
                            k as usize
                        };
                        for &m in l.cluster_members(k as usize) {
                            let o = std::mem::replace(&mut owner[m as usize], unit);
                            assert!(o == usize::MAX || o == unit, "{m} in two units of a colour");
                        }
                    }
                }
            }
        }
        for (k, _) in l.clusters() {
            assert_eq!(lanes[k], 1, "cluster {k}");
        }
    }

    /// Each live cluster's own rest offsets and weights (member order), as a lane
    /// without the template holds them.
    fn own_moments(l: &ClusterTerm, k: usize) -> Vec<glam::Vec4> {
        l.cluster_members(k)
            .iter()
            .map(|&m| (l.rest[m as usize] - l.rest_centroid[k]).extend(l.weight(m)))
            .collect()
    }

    #[test]
    fn lattice_clusters_share_the_template_up_to_rounding() {
        let (mut rest, clusters) = grid();
        // far from the origin, where rest positions round differently cluster by cluster
        rest.iter_mut()
            .for_each(|r| *r = *r * 0.1 + Vec3::splat(1000.0));
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let l = ClusterTerm::new(&rest, specs(&clusters), mode);
            let templated = (0..l.batches.len())
                .filter(|b| l.batches.moment_start[*b] == TEMPLATED)
                .count();
            // 6³ of the 8³ clusters are interior (all 27 members, regular weights)
            assert!(
                templated * LANES >= 6 * 6 * 6 * 9 / 10,
                "{mode:?}: {templated} of {} batches templated",
                l.batches.len()
            );
            let mut own_rows = 0;
            for (k, _) in l.clusters() {
                let (lane, own) = (l.member_moments(k), own_moments(&l, k));
                assert_eq!(lane.len(), own.len());
                for (a, b) in lane.iter().zip(&own) {
                    assert_eq!(a.w, b.w, "{mode:?} cluster {k}: weights");
                    // within the match tolerance at coordinates of 1000
                    let tolerance = super::super::template::TOLERANCE * 1001.0;
                    assert!(
                        (*a - *b).abs().max_element() <= tolerance,
                        "{mode:?} {k}: {a} vs {b}"
                    );
                }
                own_rows += usize::from(lane == own);
            }
            // the template did replace offsets: rounding differs from cluster to cluster
            assert!(own_rows < l.cluster_count(), "{mode:?}");
        }
    }

    #[test]
    fn a_templated_layout_moves_like_one_with_its_own_offsets() {
        let (rest, clusters) = grid();
        let with = ClusterTerm::new(&rest, specs(&clusters), SolverMode::Jacobi);
        let mut without = with.clone();
        without.build_batches_with(Template::default());
        assert!((0..with.batches.len()).any(|b| with.batches.moment_start[b] == TEMPLATED));
        assert!((0..without.batches.len()).all(|b| without.batches.moment_start[b] != TEMPLATED));
        let solved = [with, without].map(|clusters| {
            let mut particles = Particles::at_rest(&rest);
            particles.inv_mass[0] = 0.0;
            for (i, p) in particles.positions.iter_mut().enumerate() {
                p.y += 0.02 * (i % 7) as f32 - 0.05 * (i % 3) as f32;
            }
            Solver::new(clusters, Terms::default()).solve(&mut particles, &step(20));
            particles
        });
        let [with, without] = &solved;
        let moved: f32 = with.corrections.iter().map(|c| c.length()).sum();
        assert!(moved > 1.0, "the solve moved the particles ({moved})");
        for (p, q) in with.positions.iter().zip(&without.positions) {
            assert!((*p - *q).length() < 1e-5, "{p} vs {q}");
        }
    }

    #[test]
    fn groups_of_one_colour_share_no_particle_after_builds_and_patches() {
        let (rest, clusters) = grid();
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let mut l = ClusterTerm::new(&rest, specs(&clusters), mode);
            assert_eq!(
                l.batches.group_colours.is_empty(),
                mode == SolverMode::GaussSeidel
            );
            assert_groups_disjoint(&l);
            let colours = l.batches.of_colour.len();
            for round in 0..12 {
                // replace some clusters by their two halves
                let removed: Vec<u32> = l
                    .clusters()
                    .filter(|(k, _)| k % 11 == round % 11)
                    .take(60)
                    .map(|(k, _)| k as u32)
                    .collect();
                let halves: Vec<Vec<u32>> = removed
                    .iter()
                    .flat_map(|&k| {
                        let m = l.cluster_members(k as usize);
                        let (a, b) = m.split_at(m.len() / 2);
                        [a.to_vec(), b.to_vec()]
                    })
                    .collect();
                l.patch(&removed, &specs(&halves)).expect("patchable");
                assert_groups_disjoint(&l);
            }
            if mode == SolverMode::Jacobi {
                assert!(!l.batches.group_colours.is_empty(), "still spatial");
                assert!(l.batches.of_colour.len() >= colours);
            }
        }
    }
}
