//! Batched cluster fits: eight clusters of one colour are fitted at once, one per SIMD
//! lane. Their members are gathered into rows (row `j` holds member `j` of every lane's
//! cluster), the moment matrices are accumulated and the rotations extracted (Müller
//! 2016, warm-started) eight wide, and every row's pull `R q + c − p` is computed eight
//! wide and handed to the caller, which applies it member by member.
//!
//! Batches run in *groups*: one task runs a group's batches in order, and the groups of
//! one colour share no particle, so they run in parallel. Gauss–Seidel groups batches of
//! one cluster colour (a batch's lanes share no particle, as its in-place moves need).
//! Jacobi only reads positions and adds pulls, so its batches take clusters in the
//! particles' spatial order whatever their colour, and its groups are coloured instead:
//! a task then revisits the same few thousand particles while they are in cache, where
//! colour-major order sweeps every particle once per cluster colour.
//!
//! Batches persist across patches (see `patch.rs`): a removed cluster leaves an empty
//! lane, new clusters are appended in new batches and groups, and a cluster whose
//! weights changed has its lane rewritten; the batches are laid out afresh only when a
//! quarter of all lanes are empty.
//!
//! A fit is done relative to the cluster's first member so that goals keep full
//! precision far from the origin; a lane's padding rows (past its cluster's size) have
//! weight 0 and sit at that origin, so they add nothing.

use super::colouring::order_by_colour;
use super::sweep::Disjoint;
use super::template::Template;
use super::{CLUSTERS_PER_TASK, FREE_SLOT, PATCH_HEADROOM, SolverLayout};
use crate::math::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::math::rotation::extract_rotation_x8;
use crate::math::simd::{Lane, WithLanes, dispatch};
use glam::{Quat, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Lane marker: no cluster.
const EMPTY_LANE: u32 = u32::MAX;

/// Batches per group (at most).
const GROUP_BATCHES: usize = CLUSTERS_PER_TASK / LANES;

/// A group: the batches `[first, end)`, run in order by one task.
type Group = [u32; 2];

/// Member `j`'s rest offset and weight in each of a batch's clusters, as fixed by the
/// layout (or by its template, see `template.rs`).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(super) struct MomentRow {
    /// Rest offsets `q` from the cluster's rest centroid (padding: 0).
    pub(super) offset: Vec3x8,
    /// Matching weights (padding: 0).
    #[serde(with = "crate::math::lanes::f32x8_serde")]
    pub(super) weight: f32x8,
}

/// Member `j`'s particle in each of a batch's clusters, as a byte offset into a
/// per-particle `Vec3A` array ([`PARTICLE_BYTES`] × index: x86 addressing scales an
/// index by at most 8, so a stored index would cost a shift per lane and pass); padding
/// repeats the lane's first member (0 for an empty lane), so that it sits at the lane's
/// origin.
pub(super) type ParticleRow = [u32; LANES];

/// A batch's first row in [`Batches::moments`] when it reads the template instead.
const TEMPLATED: u32 = u32::MAX;

/// Bytes per particle in the per-particle `Vec3A` arrays the rows address.
pub(super) const PARTICLE_BYTES: u32 = size_of::<Vec3A>() as u32;

/// The members' positions of one row during a fit: scratch of one task.
pub(super) type FitRow = Vec3x8;

/// What a solver scheme does with one batch: generic over the lane type, so that each
/// group of batches runs with the backend [`dispatch`] picks.
pub(super) trait BatchKernel: Sync {
    /// Runs batch `b` with lanes `L` (inline it: see [`WithLanes::run`]); `fit_rows` is
    /// scratch for [`SolverLayout::fit_batch`].
    fn batch<L: Lane>(&self, b: usize, fit_rows: &mut Vec<FitRow>);
}

/// One group's batches in order: the unit of work [`dispatch`] hands to a backend.
struct GroupRun<'a, K> {
    kernel: &'a K,
    group: Group,
    fit_rows: &'a mut Vec<FitRow>,
}

impl<K: BatchKernel> WithLanes for GroupRun<'_, K> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lane>(self) {
        for b in self.group[0]..self.group[1] {
            self.kernel.batch::<L>(b as usize, self.fit_rows);
        }
    }
}

/// One row's result of a fit, handed to the caller member by member.
pub(super) struct RowPulls<'a> {
    /// The row's particles as byte offsets (see [`ParticleRow`]).
    pub(super) at: &'a [u32; LANES],
    /// The members' positions the fit saw.
    pub(super) position: &'a Vec3x8,
    /// The pull `R q + c − p` of each lane's member; exactly zero on a padding row
    /// (whose particle is the lane's first member, so adding it changes nothing).
    pub(super) pull: [Vec3A; LANES],
    /// The row's index in the batch.
    pub(super) row: usize,
    /// Each lane's cluster size (0 for an unused lane): lane `l`'s entry is a member
    /// when `row < size[l]`.
    pub(super) size: &'a [u32; LANES],
}

/// The clusters in batches of [`LANES`] clusters, the batches in coloured groups.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(super) struct Batches {
    /// All batches' particle rows.
    particles: Vec<ParticleRow>,
    /// Per batch: its first particle row; one entry more than batches.
    start: Vec<u32>,
    /// The moment rows of the batches that do not read the template.
    moments: Vec<MomentRow>,
    /// Per batch: its first moment row, or [`TEMPLATED`].
    moment_start: Vec<u32>,
    /// The shared rest shape (empty when the layout has none).
    template: Template,
    /// Per batch: the cluster slot of each lane ([`EMPTY_LANE`] for none).
    lanes: Vec<[u32; LANES]>,
    /// Per colour: its groups (which share no particle).
    of_colour: Vec<Vec<Group>>,
    /// Per cluster slot: `batch × LANES + lane`.
    place: Vec<u32>,
    /// Lanes without a cluster.
    empty_lanes: usize,
    /// Spatial batches (Jacobi): per particle, bit `c` set when a group of colour `c`
    /// holds it. Empty when the batches are by cluster colour.
    group_colours: Vec<u64>,
}

impl Batches {
    /// The particle of every membership slot, row by row, lane by lane (a padding
    /// slot names its lane's first member).
    pub(super) fn membership_particles(&self) -> impl Iterator<Item = u32> + '_ {
        self.particles
            .iter()
            .flat_map(|row| row.map(|at| at / PARTICLE_BYTES))
    }

    /// Heap bytes held.
    pub(super) fn heap_bytes(&self) -> usize {
        self.particles.capacity() * size_of::<ParticleRow>()
            + (self.moments.capacity() + self.template.rows.capacity()) * size_of::<MomentRow>()
            + self.lanes.capacity() * size_of::<[u32; LANES]>()
            + (self.start.capacity() + self.moment_start.capacity() + self.place.capacity()) * 4
            + self.group_colours.capacity() * 8
            + self
                .of_colour
                .iter()
                .map(|b| b.capacity() * size_of::<Group>())
                .sum::<usize>()
    }

    /// Number of batches.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.lanes.len()
    }

    /// Number of lanes without a cluster.
    #[cfg(test)]
    pub(super) fn empty_lanes(&self) -> usize {
        self.empty_lanes
    }

    /// Whether cluster slot `k` has a lane.
    pub(super) fn has_lane(&self, k: usize) -> bool {
        self.place.get(k).is_some_and(|p| *p != u32::MAX)
    }

    /// Records the batches from `first` to the last one as a group of `colour`.
    fn push_group(&mut self, colour: usize, first: u32) {
        if self.of_colour.len() <= colour {
            self.of_colour.resize(colour + 1, Vec::new());
        }
        self.of_colour[colour].push([first, self.lanes.len() as u32]);
    }

    /// Whether so many lanes are empty that the batches should be laid out afresh.
    pub(super) fn fragmented(&self) -> bool {
        4 * self.empty_lanes > self.lanes.len() * LANES
    }
}

impl SolverLayout {
    /// Puts all clusters in batches of [`LANES`] and groups (spatially for Jacobi, by
    /// cluster colour for Gauss–Seidel or when the spatial groups would need more than
    /// 64 colours) and lays out all rows (in parallel): after a build, or a patch that
    /// left the batches fragmented.
    pub(super) fn build_batches(&mut self) {
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
        // which clusters match the template (a batch whose clusters all do reads it)
        let matches: Vec<bool> = (0..self.cluster_range.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|k| self.colour_of[k] != FREE_SLOT && self.template_order(k, &template).is_some())
            .collect();
        let mut batches = empty();
        let spatial = super::weighted_by_count(self.mode) && {
            let mut order: Vec<u32> = (0..self.cluster_range.len() as u32)
                .filter(|&k| self.colour_of[k as usize] != FREE_SLOT)
                .collect();
            order.sort_unstable_by_key(|&k| (self.first_member(k as usize), k));
            batches.group_colours = vec![0; self.rest.len()];
            self.add_spatial_groups(&mut batches, &order, &matches)
        };
        if !spatial {
            batches = empty();
            let (colour_order, colour_start) = order_by_colour(&self.colour_of, FREE_SLOT);
            for (colour, range) in colour_start.windows(2).enumerate() {
                let clusters = &colour_order[range[0] as usize..range[1] as usize];
                self.add_colour_groups(&mut batches, colour, clusters, &matches);
            }
        }
        let templated: Vec<bool> = batches
            .lanes
            .iter()
            .map(|lanes| {
                lanes
                    .iter()
                    .all(|&k| k == EMPTY_LANE || matches[k as usize])
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
                        None => self.write_template_lane(particles, l, k as usize, &template),
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
    /// particle) in batches, and the batches in groups of that colour. `matches` flags
    /// the slots that match the template (empty: none does).
    fn add_colour_groups(
        &self,
        batches: &mut Batches,
        colour: usize,
        slots: &[u32],
        matches: &[bool],
    ) {
        for group in slots.chunks(LANES * GROUP_BATCHES) {
            let first = self.add_group_batches(batches, group, matches);
            batches.push_group(colour, first);
        }
    }

    /// Appends the clusters `slots` (in spatial order) in batches and groups, giving
    /// each group the lowest colour that no group holding one of its particles has.
    /// Returns false when a group would need a 65th colour (the batches are then
    /// unusable and must be laid out again by cluster colour). `matches` as for
    /// [`Self::add_colour_groups`].
    fn add_spatial_groups(&self, batches: &mut Batches, slots: &[u32], matches: &[bool]) -> bool {
        for group in slots.chunks(LANES * GROUP_BATCHES) {
            let first = self.add_group_batches(batches, group, matches);
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
    /// match the template (flagged in `matches`, empty for none) first, so that they
    /// fill batches of their own; returns the group's first batch.
    fn add_group_batches(&self, batches: &mut Batches, slots: &[u32], matches: &[bool]) -> u32 {
        let first = batches.lanes.len() as u32;
        let matching = |k: &u32| matches.get(*k as usize).copied().unwrap_or(false);
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
    pub(super) fn cluster_size(&self, k: usize) -> usize {
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
        let centroid = self.rest_centroid[k];
        let rows = particles.iter_mut().zip(moments.iter_mut());
        for ((at, row), &m) in rows.zip(members) {
            let offset = self.rest[m as usize] - centroid;
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

    /// Writes lane `l` of a templated batch's particle rows for cluster slot `k`, which
    /// matches `template`: its members in the template's order.
    fn write_template_lane(
        &self,
        particles: &mut [ParticleRow],
        l: usize,
        k: usize,
        template: &Template,
    ) {
        let order = self
            .template_order(k, template)
            .expect("a templated batch's clusters match the template");
        for (at, m) in particles.iter_mut().zip(order) {
            at[l] = m * PARTICLE_BYTES;
        }
    }

    /// The batch and lane of cluster slot `k`.
    fn place(&self, k: usize) -> (usize, usize) {
        let place = self.batches.place[k] as usize;
        (place / LANES, place % LANES)
    }

    /// Rest offsets from the weighted rest centroid and matching weights, `(q, w)`, of
    /// the members of cluster slot `k` (in the order of [`SolverLayout::clusters`]), as
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
    pub(super) fn clear_lane(&mut self, k: usize) {
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
    pub(super) fn rewrite_lane(&mut self, k: usize) {
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
    pub(super) fn batch_added(&mut self, added: &[u32]) {
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

    /// Runs `kernel` on every batch, colour after colour; the groups of one colour run
    /// in parallel (they share no particle), each group's batches in order.
    pub(super) fn for_each_batch_by_colour(&self, kernel: &impl BatchKernel) {
        for groups in &self.batches.of_colour {
            groups
                .par_iter()
                .for_each_init(Vec::new, |fit_rows, &group| {
                    dispatch(GroupRun {
                        kernel,
                        group,
                        fit_rows,
                    })
                });
        }
    }

    /// The index of batch `b`'s first particle row among all batches' rows.
    #[inline(always)]
    pub(super) fn first_row(&self, b: usize) -> usize {
        self.batches.start[b] as usize
    }

    /// Particle rows of all batches.
    pub(super) fn row_count(&self) -> usize {
        self.batches.particles.len()
    }

    /// The cluster slot in each lane of batch `b` (`None`: an empty lane).
    #[inline(always)]
    pub(super) fn lane_clusters(&self, b: usize) -> [Option<usize>; LANES] {
        self.batches.lanes[b].map(|k| (k != EMPTY_LANE).then_some(k as usize))
    }

    /// Which lanes of batch `b` hold a cluster.
    #[inline(always)]
    pub(super) fn lanes_in_use(&self, b: usize) -> [bool; LANES] {
        self.batches.lanes[b].map(|k| k != EMPTY_LANE)
    }

    /// The particle rows of batch `b`.
    #[inline(always)]
    fn batch_particles(&self, b: usize) -> &[ParticleRow] {
        let start = &self.batches.start;
        &self.batches.particles[start[b] as usize..start[b + 1] as usize]
    }

    /// The moment rows of batch `b`: its own, or the template's.
    #[inline(always)]
    fn batch_moments(&self, b: usize) -> &[MomentRow] {
        let batches = &self.batches;
        match batches.moment_start[b] {
            TEMPLATED => &batches.template.rows,
            first => {
                let len = batches.start[b + 1] - batches.start[b];
                &batches.moments[first as usize..(first + len) as usize]
            }
        }
    }

    /// Fits the clusters of batch `b` to the particle positions at `positions`, updates
    /// their warm-start rotations, and calls `apply` with every row's pulls, row by row.
    /// In batches by cluster colour a particle appears in at most one lane, so `apply`
    /// may move it; spatial batches (Jacobi) may hold a particle in several lanes, and
    /// their `apply` only accumulates.
    ///
    /// # Safety
    /// The caller is the task that owns the clusters of the batch in the current colour
    /// (see [`Disjoint`]), `positions` points to this layout's particle positions, and no
    /// task writes them during the call but `apply`, and only the entries of this
    /// batch's members once their rows' positions were gathered (all rows are gathered
    /// before the first `apply`).
    #[inline(always)]
    pub(super) unsafe fn fit_batch<L: Lane>(
        &self,
        b: usize,
        fit_rows: &mut Vec<FitRow>,
        positions: *const Vec3A,
        rotations: Disjoint<Quat>,
        mut apply: impl FnMut(RowPulls),
    ) {
        let (particles, moments) = (self.batch_particles(b), self.batch_moments(b));
        if fit_rows.len() < particles.len() {
            fit_rows.resize(particles.len(), FitRow::default());
        }
        let fit_rows = &mut fit_rows[..particles.len()];
        let templated = self.batches.moment_start[b] == TEMPLATED;
        let template = &self.batches.template;
        let mut size = [0u32; LANES];
        let mut warm = [Quat::IDENTITY; LANES];
        let lanes = &self.batches.lanes[b];
        for (l, &k) in lanes.iter().enumerate() {
            if k == EMPTY_LANE {
                continue;
            }
            let k = k as usize;
            size[l] = self.cluster_size(k) as u32;
            // SAFETY: rotation `k` belongs to the calling task (the caller's contract).
            warm[l] = unsafe { rotations.read(k) };
        }
        // (a templated batch broadcasts the template's: no per-lane reads, no transpose)
        let (bias, inv_weight_sum) = if templated {
            (
                Vec3x8::<L>::splat(template.bias),
                L::splat(template.inv_weight_sum),
            )
        } else {
            let (mut bias, mut inv_weight_sum) = ([Vec3A::ZERO; LANES], [0.0f32; LANES]);
            for (l, &k) in lanes.iter().enumerate() {
                if k != EMPTY_LANE {
                    bias[l] = self.offset_bias[k as usize];
                    inv_weight_sum[l] = self.inv_weight_sum[k as usize];
                }
            }
            (Vec3x8::from_lanes(bias), L::from_array(inv_weight_sum))
        };
        /// The positions of a row's particles (a function, not a closure, so that it is
        /// inlined into the backend's code).
        ///
        /// # Safety
        /// `positions` holds every particle of `at`, and no task writes them.
        #[inline(always)]
        unsafe fn gather<L: Lane>(positions: *const Vec3A, at: &ParticleRow) -> Vec3x8<L> {
            let p = |l: usize| unsafe { *positions.byte_add(at[l] as usize) };
            Vec3x8::from_lanes([p(0), p(1), p(2), p(3), p(4), p(5), p(6), p(7)])
        }
        let Some(first) = particles.first() else {
            return;
        };
        // SAFETY (both gathers): particle indices were bounds-checked when the layout
        // was built; the positions are not written during the call (the caller's
        // contract).
        let origin = unsafe { gather::<L>(positions, first) };
        let mut sum = Vec3x8::ZERO;
        let mut a = Mat3x8::ZERO;
        let rows = particles.iter().zip(moments);
        for ((at, row), position) in rows.clone().zip(fit_rows.iter_mut()) {
            let p = unsafe { gather::<L>(positions, at) };
            *position = p.store();
            let offset = Vec3x8::<L>::load(&row.offset);
            let d = (p - origin).scale(L::from_stored(row.weight));
            sum = sum + d;
            a.x_axis = d.mul_add(offset.x, a.x_axis);
            a.y_axis = d.mul_add(offset.y, a.y_axis);
            a.z_axis = d.mul_add(offset.z, a.z_axis);
        }
        let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), self.rotation_iterations());
        for (l, &k) in lanes.iter().enumerate() {
            if k != EMPTY_LANE {
                // SAFETY: as above.
                unsafe { rotations.write(k as usize, q.lane(l)) };
            }
        }
        let r = Mat3x8::from_quat(q);
        // Σ w (R q + c − d) = R·bias + c·W − Σ w d = 0 exactly when c = (Σ w d − R·bias)/W.
        let centroid = (sum - r.mul_vec(bias)).scale(inv_weight_sum) + origin;
        for (j, ((at, row), position)) in rows.zip(fit_rows.iter()).enumerate() {
            // members have a positive weight, padding rows weight 0: their pull is
            // masked to exactly zero
            let member = L::from_stored(row.weight).simd_gt(L::ZERO) & L::ONE;
            let goal = r.mul_vec_add(Vec3x8::load(&row.offset), centroid);
            let pull = (goal - Vec3x8::load(position)).scale(member);
            apply(RowPulls {
                at,
                position,
                pull: pull.to_lanes(),
                row: j,
                size: &size,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::SolverMode;
    use crate::solver::ConstraintKinds;
    use crate::solver::unit_specs as specs;
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
    fn assert_groups_disjoint(l: &SolverLayout) {
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
                        let unit = if super::super::weighted_by_count(l.mode) {
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
    fn own_moments(l: &SolverLayout, k: usize) -> Vec<glam::Vec4> {
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
            let l = SolverLayout::new(&rest, specs(&clusters), mode);
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
        let with = SolverLayout::new(&rest, specs(&clusters), SolverMode::Jacobi);
        let mut without = with.clone();
        without.build_batches_with(Template::default());
        assert!((0..with.batches.len()).any(|b| with.batches.moment_start[b] == TEMPLATED));
        assert!((0..without.batches.len()).all(|b| without.batches.moment_start[b] != TEMPLATED));
        let mut layouts = [with, without];
        for l in &mut layouts {
            l.inv_mass[0] = 0.0;
            for (i, p) in l.positions.iter_mut().enumerate() {
                p.y += 0.02 * (i % 7) as f32 - 0.05 * (i % 3) as f32;
            }
            l.solve(20, crate::solver::TEST_DT, &mut ConstraintKinds::default());
        }
        let [with, without] = &layouts;
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
            let mut l = SolverLayout::new(&rest, specs(&clusters), mode);
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
                l.patch(&removed, &specs(&halves), &[]).expect("patchable");
                assert_groups_disjoint(&l);
            }
            if mode == SolverMode::Jacobi {
                assert!(!l.batches.group_colours.is_empty(), "still spatial");
                assert!(l.batches.of_colour.len() >= colours);
            }
        }
    }
}
