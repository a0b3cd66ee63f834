//! Batched cluster fits (SPEC §2.2, issue 4 "batched cluster work"): eight clusters of
//! one colour are fitted at once, one per SIMD lane. Their members are gathered into
//! rows (row `j` holds member `j` of every lane's cluster), the moment matrices are
//! accumulated and the rotations extracted (Müller 2016, warm-started) eight wide, and
//! every row's pull `s (R q + c − p)` is computed eight wide and handed to the caller,
//! which applies it member by member.
//!
//! Batches persist across patches (see `patch.rs`): a removed cluster leaves an empty
//! lane, new clusters are appended in new batches of their colour, and a cluster whose
//! weights changed has its lane rewritten; the batches are laid out afresh only when a
//! quarter of all lanes are empty.
//!
//! A fit is done relative to the cluster's first member so that goals keep full
//! precision far from the origin; a lane's padding rows (past its cluster's size) have
//! weight 0 and sit at that origin, so they add nothing.

use super::colouring::order_by_colour;
use super::sweep::Disjoint;
use super::{CLUSTERS_PER_TASK, FREE_SLOT, PATCH_HEADROOM, ROTATION_ITERATIONS, SolverLayout};
use crate::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::rotation::extract_rotation_x8;
use glam::{Quat, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Lane marker: no cluster.
const EMPTY_LANE: u32 = u32::MAX;

/// Member `j` of each of a batch's clusters, as fixed by the layout.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct BatchRow {
    /// Rest offsets `q` from the cluster's rest centroid (padding: 0).
    offset: Vec3x8,
    /// Matching weights (padding: 0).
    weight: f32x8,
    /// Particle indices; padding repeats the lane's first member (0 for an empty lane),
    /// so that it sits at the lane's origin.
    pub(super) particle: [u32; LANES],
}

/// The members' positions of one row during a fit: scratch of one task.
pub(super) type FitRow = Vec3x8;

/// One row's result of a fit, handed to the caller member by member.
pub(super) struct RowPulls<'a> {
    /// The row's particles (see [`BatchRow::particle`]).
    pub(super) particle: &'a [u32; LANES],
    /// The members' positions the fit saw.
    pub(super) position: &'a Vec3x8,
    /// The pull `s (R q + c − p)` of each lane's member; exactly zero on a padding row
    /// (whose particle is the lane's first member, so adding it changes nothing).
    pub(super) pull: [Vec3A; LANES],
    /// The row's index in the batch.
    pub(super) row: usize,
    /// Each lane's cluster size (0 for an unused lane): lane `l`'s entry is a member
    /// when `row < size[l]`.
    pub(super) size: &'a [u32; LANES],
}

/// The clusters in batches of [`LANES`] clusters of one colour.
#[derive(Clone, Debug, Default)]
pub(super) struct Batches {
    /// All batches' rows.
    rows: Vec<BatchRow>,
    /// Per batch: its first row; one entry more than batches.
    start: Vec<u32>,
    /// Per batch: the cluster slot of each lane ([`EMPTY_LANE`] for none).
    lanes: Vec<[u32; LANES]>,
    /// Per colour: its batches.
    of_colour: Vec<Vec<u32>>,
    /// Per cluster slot: `batch × LANES + lane`.
    place: Vec<u32>,
    /// Lanes without a cluster.
    empty_lanes: usize,
}

impl Batches {
    /// Heap bytes held.
    pub(super) fn heap_bytes(&self) -> usize {
        self.rows.capacity() * size_of::<BatchRow>()
            + self.lanes.capacity() * size_of::<[u32; LANES]>()
            + (self.start.capacity() + self.place.capacity()) * 4
            + self
                .of_colour
                .iter()
                .map(|b| b.capacity() * 4)
                .sum::<usize>()
    }

    /// Number of batches.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.lanes.len()
    }

    /// Whether cluster slot `k` has a lane.
    pub(super) fn has_lane(&self, k: usize) -> bool {
        self.place.get(k).is_some_and(|p| *p != u32::MAX)
    }

    /// Whether so many lanes are empty that the batches should be laid out afresh.
    pub(super) fn fragmented(&self) -> bool {
        4 * self.empty_lanes > self.lanes.len() * LANES
    }
}

impl SolverLayout {
    /// Groups each colour's clusters into batches of [`LANES`] (in colour order) and
    /// lays out all rows (in parallel): after a build, or a patch that left the batches
    /// fragmented.
    pub(super) fn build_batches(&mut self) {
        let old = std::mem::take(&mut self.batches);
        let mut batches = Batches {
            place: vec![u32::MAX; self.cluster_range.len()],
            ..Batches::default()
        };
        batches.start.push(0);
        let (colour_order, colour_start) = order_by_colour(&self.colour_of, FREE_SLOT);
        for colour in colour_start.windows(2) {
            let clusters = &colour_order[colour[0] as usize..colour[1] as usize];
            let ids = clusters
                .chunks(LANES)
                .map(|chunk| self.add_batch(&mut batches, chunk))
                .collect();
            batches.of_colour.push(ids);
        }
        // the old rows' allocation is reused: a fresh one would page-fault every time
        let mut rows = old.rows;
        rows.clear();
        let len = batches.start[batches.lanes.len()] as usize;
        rows.reserve(len + len / PATCH_HEADROOM);
        rows.resize(len, BatchRow::default());
        let mut rest = rows.as_mut_slice();
        let mut per_batch = Vec::with_capacity(batches.lanes.len());
        for range in batches.start.windows(2) {
            let (head, tail) = rest.split_at_mut((range[1] - range[0]) as usize);
            per_batch.push(head);
            rest = tail;
        }
        per_batch
            .into_par_iter()
            .zip(&batches.lanes)
            .with_min_len(64)
            .for_each(|(rows, lanes)| {
                for (l, &k) in lanes.iter().enumerate() {
                    if k != EMPTY_LANE {
                        self.write_lane(rows, l, k as usize);
                    }
                }
            });
        batches.rows = rows;
        self.batches = batches;
    }

    /// Appends a batch of the clusters `slots` (at most [`LANES`]) to `batches` without
    /// writing its rows (they stay as the caller leaves them); returns its index.
    fn add_batch(&self, batches: &mut Batches, slots: &[u32]) -> u32 {
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
        b
    }

    /// Number of members of cluster slot `k`.
    #[inline]
    fn cluster_size(&self, k: usize) -> usize {
        let [start, end] = self.cluster_range[k];
        (end - start) as usize
    }

    /// Writes lane `l` of a batch's `rows` for cluster slot `k`: its members' rest
    /// offsets, weights and particles, then padding at its first member.
    fn write_lane(&self, rows: &mut [BatchRow], l: usize, k: usize) {
        let [start, end] = self.cluster_range[k];
        let members = &self.member_particle[start as usize..end as usize];
        let centroid = self.rest_centroid[k];
        for (row, &m) in rows.iter_mut().zip(members) {
            let offset = self.rest[m as usize] - centroid;
            row.offset.x.as_mut_array()[l] = offset.x;
            row.offset.y.as_mut_array()[l] = offset.y;
            row.offset.z.as_mut_array()[l] = offset.z;
            row.weight.as_mut_array()[l] = self.weight(m);
            row.particle[l] = m;
        }
        let first = members.first().copied().unwrap_or(0);
        for row in &mut rows[members.len()..] {
            row.offset.x.as_mut_array()[l] = 0.0;
            row.offset.y.as_mut_array()[l] = 0.0;
            row.offset.z.as_mut_array()[l] = 0.0;
            row.weight.as_mut_array()[l] = 0.0;
            row.particle[l] = first;
        }
    }

    /// The batch and lane of cluster slot `k`.
    fn place(&self, k: usize) -> (usize, usize) {
        let place = self.batches.place[k] as usize;
        (place / LANES, place % LANES)
    }

    /// Rest offsets from the weighted rest centroid and matching weights, `(q, w)`, of
    /// the members of cluster slot `k` (in the order of [`SolverLayout::clusters`]), as
    /// the kernel reads them from the cluster's lane.
    pub fn member_moments(&self, k: usize) -> Vec<glam::Vec4> {
        let (b, l) = self.place(k);
        self.batch_rows(b)[..self.cluster_size(k)]
            .iter()
            .map(|row| {
                glam::Vec4::new(
                    row.offset.x.as_array()[l],
                    row.offset.y.as_array()[l],
                    row.offset.z.as_array()[l],
                    row.weight.as_array()[l],
                )
            })
            .collect()
    }

    /// Patch step: empties the lane of cluster slot `k` (call before the slot is freed).
    pub(super) fn clear_lane(&mut self, k: usize) {
        let (b, l) = self.place(k);
        let range = self.batches.start[b] as usize..self.batches.start[b + 1] as usize;
        for row in &mut self.batches.rows[range] {
            row.weight.as_mut_array()[l] = 0.0;
            row.particle[l] = 0;
        }
        self.batches.lanes[b][l] = EMPTY_LANE;
        self.batches.place[k] = u32::MAX;
        self.batches.empty_lanes += 1;
    }

    /// Patch step: rewrites the lane of cluster slot `k` (its weights changed).
    pub(super) fn rewrite_lane(&mut self, k: usize) {
        let (b, l) = self.place(k);
        let range = self.batches.start[b] as usize..self.batches.start[b + 1] as usize;
        let mut rows = std::mem::take(&mut self.batches.rows);
        self.write_lane(&mut rows[range], l, k);
        self.batches.rows = rows;
    }

    /// Patch step: puts the new clusters `added` (slots) into new batches, grouped by
    /// colour, or lays all batches out afresh when they are fragmented.
    pub(super) fn batch_added(&mut self, added: &[u32]) {
        if self.batches.fragmented() {
            self.build_batches();
            return;
        }
        let mut added: Vec<u32> = added.to_vec();
        added.sort_unstable_by_key(|&k| (self.colour_of[k as usize], k));
        let mut batches = std::mem::take(&mut self.batches);
        batches.place.resize(self.cluster_range.len(), u32::MAX);
        for group in
            added.chunk_by(|a, b| self.colour_of[*a as usize] == self.colour_of[*b as usize])
        {
            let colour = self.colour_of[group[0] as usize] as usize;
            if batches.of_colour.len() <= colour {
                batches.of_colour.resize(colour + 1, Vec::new());
            }
            for chunk in group.chunks(LANES) {
                let b = self.add_batch(&mut batches, chunk);
                batches.of_colour[colour].push(b);
                let rows = batches.start[b as usize + 1] - batches.start[b as usize];
                batches
                    .rows
                    .resize(batches.rows.len() + rows as usize, BatchRow::default());
                let range =
                    batches.start[b as usize] as usize..batches.start[b as usize + 1] as usize;
                for (l, &k) in chunk.iter().enumerate() {
                    self.write_lane(&mut batches.rows[range.clone()], l, k as usize);
                }
            }
        }
        self.batches = batches;
    }

    /// Runs `f(batch, fit_rows)` for every batch, colour after colour; the batches of
    /// one colour run in parallel (their clusters share no particle). `fit_rows` is
    /// scratch for [`Self::fit_batch`].
    pub(super) fn for_each_batch_by_colour(&self, f: impl Fn(usize, &mut Vec<FitRow>) + Sync) {
        for batches in &self.batches.of_colour {
            batches
                .par_iter()
                .with_min_len(CLUSTERS_PER_TASK / LANES)
                .for_each_init(Vec::new, |fit_rows, &b| f(b as usize, fit_rows));
        }
    }

    /// Which lanes of batch `b` hold a cluster.
    #[inline(always)]
    pub(super) fn lanes_in_use(&self, b: usize) -> [bool; LANES] {
        self.batches.lanes[b].map(|k| k != EMPTY_LANE)
    }

    /// The rows of batch `b`.
    #[inline(always)]
    pub(super) fn batch_rows(&self, b: usize) -> &[BatchRow] {
        let start = &self.batches.start;
        &self.batches.rows[start[b] as usize..start[b + 1] as usize]
    }

    /// Fits the clusters of batch `b` to the particle positions at `positions`, updates
    /// their warm-start rotations, and calls `apply` with every row's pulls, row by row
    /// (a particle appears in at most one lane of a batch, so `apply` may move it).
    ///
    /// # Safety
    /// The caller is the task that owns the clusters of the batch in the current colour
    /// (see [`Disjoint`]), `positions` points to this layout's particle positions, and no
    /// task writes them during the call but `apply`, and only the entries of this
    /// batch's members once their rows' positions were gathered (all rows are gathered
    /// before the first `apply`).
    #[inline(always)]
    pub(super) unsafe fn fit_batch(
        &self,
        b: usize,
        fit_rows: &mut Vec<FitRow>,
        positions: *const Vec3A,
        rotations: Disjoint<Quat>,
        mut apply: impl FnMut(RowPulls),
    ) {
        let rows = self.batch_rows(b);
        if fit_rows.len() < rows.len() {
            fit_rows.resize(rows.len(), FitRow::default());
        }
        let fit_rows = &mut fit_rows[..rows.len()];
        let mut size = [0u32; LANES];
        let mut warm = [Quat::IDENTITY; LANES];
        let mut bias = [Vec3A::ZERO; LANES];
        let (mut inv_weight_sum, mut stiffness) = ([0.0f32; LANES], [0.0f32; LANES]);
        let lanes = &self.batches.lanes[b];
        for (l, &k) in lanes.iter().enumerate() {
            if k == EMPTY_LANE {
                continue;
            }
            let k = k as usize;
            size[l] = self.cluster_size(k) as u32;
            // SAFETY: rotation `k` belongs to the calling task (the caller's contract).
            warm[l] = unsafe { rotations.read(k) };
            bias[l] = self.offset_bias[k];
            inv_weight_sum[l] = self.inv_weight_sum[k];
            stiffness[l] = self.stiffness[k];
        }
        // SAFETY: particle indices were bounds-checked when the layout was built; the
        // positions are not written during the call (the caller's contract).
        let gather = |row: &BatchRow| unsafe {
            let p = |l: usize| *positions.add(row.particle[l] as usize);
            Vec3x8::from_lanes([p(0), p(1), p(2), p(3), p(4), p(5), p(6), p(7)])
        };
        let Some(first) = rows.first() else {
            return;
        };
        let origin = gather(first);
        let mut sum = Vec3x8::ZERO;
        let mut a = Mat3x8::ZERO;
        for (row, position) in rows.iter().zip(fit_rows.iter_mut()) {
            *position = gather(row);
            let d = (*position - origin).scale(row.weight);
            sum = sum + d;
            a.x_axis = d.mul_add(row.offset.x, a.x_axis);
            a.y_axis = d.mul_add(row.offset.y, a.y_axis);
            a.z_axis = d.mul_add(row.offset.z, a.z_axis);
        }
        let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), ROTATION_ITERATIONS);
        for (l, &k) in lanes.iter().enumerate() {
            if k != EMPTY_LANE {
                // SAFETY: as above.
                unsafe { rotations.write(k as usize, q.lane(l)) };
            }
        }
        let r = Mat3x8::from_quat(q);
        // Σ w (R q + c − d) = R·bias + c·W − Σ w d = 0 exactly when c = (Σ w d − R·bias)/W.
        let centroid =
            (sum - r.mul_vec(Vec3x8::from_lanes(bias))).scale(f32x8::new(inv_weight_sum)) + origin;
        let s = f32x8::new(stiffness);
        let scaled = Mat3x8 {
            x_axis: r.x_axis.scale(s),
            y_axis: r.y_axis.scale(s),
            z_axis: r.z_axis.scale(s),
        };
        let translation = centroid.scale(s);
        for (j, (row, position)) in rows.iter().zip(fit_rows.iter()).enumerate() {
            let goal = scaled.mul_vec(row.offset) + translation;
            // members have a positive weight, padding rows weight 0
            let member = row.weight.simd_gt(f32x8::ZERO);
            let pull = Vec3x8::select(member, goal - position.scale(s), Vec3x8::ZERO);
            apply(RowPulls {
                particle: &row.particle,
                position,
                pull: pull.to_lanes(),
                row: j,
                size: &size,
            });
        }
    }
}
