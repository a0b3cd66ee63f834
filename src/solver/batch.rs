//! Batched cluster fits (SPEC §2.2, issue 4 "batched cluster work"): eight clusters of
//! one colour are fitted at once, one per SIMD lane. Their members are gathered into
//! rows (row `j` holds member `j` of every lane's cluster), the moment matrices are
//! accumulated and the rotations extracted (Müller 2016, warm-started) eight wide, and
//! every row's pull `s (R q + c − p)` is computed eight wide; the caller applies the
//! pulls member by member.
//!
//! A fit is done relative to the cluster's first member so that goals keep full
//! precision far from the origin; a lane's padding rows (past its cluster's size) have
//! weight 0 and sit at that origin, so they add nothing.

use super::sweep::Disjoint;
use super::{CLUSTERS_PER_TASK, ROTATION_ITERATIONS, SolverLayout};
use crate::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::rotation::extract_rotation_x8;
use glam::{Quat, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Member `j` of each of a batch's clusters, as fixed by the layout: rebuilt by
/// [`SolverLayout::build_batches`] whenever the clusters change.
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

/// Member `j` of each of a batch's clusters during one fit: scratch of one task.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct FitRow {
    /// Current positions.
    pub(super) position: Vec3x8,
    /// The pull `s (R q + c − p)` of each lane's member.
    pub(super) pull: [Vec3A; LANES],
}

impl SolverLayout {
    /// Groups each colour's clusters into batches of [`LANES`] (in colour order) and
    /// lays out their rows; called after every build or patch.
    pub(super) fn build_batches(&mut self) {
        let size = |k: u32| {
            let [start, end] = self.cluster_range[k as usize];
            (end - start) as usize
        };
        let mut batch_start = vec![0u32];
        let mut colour_batches = vec![0u32];
        for colour in self.colour_start.windows(2) {
            for batch in self.colour_order[colour[0] as usize..colour[1] as usize].chunks(LANES) {
                let rows = batch.iter().map(|k| size(*k)).max().unwrap_or(0);
                batch_start.push(batch_start[batch_start.len() - 1] + rows as u32);
            }
            colour_batches.push(batch_start.len() as u32 - 1);
        }
        let mut rows = vec![BatchRow::default(); batch_start[batch_start.len() - 1] as usize];
        let batches = self.colour_start.windows(2).flat_map(|colour| {
            self.colour_order[colour[0] as usize..colour[1] as usize].chunks(LANES)
        });
        for (batch, range) in batches.zip(batch_start.windows(2)) {
            let rows = &mut rows[range[0] as usize..range[1] as usize];
            for (l, &k) in batch.iter().enumerate() {
                let [start, end] = self.cluster_range[k as usize];
                let range = start as usize..end as usize;
                let members = &self.member_particle[range.clone()];
                for (row, (&m, moment)) in rows
                    .iter_mut()
                    .zip(members.iter().zip(&self.member_moment[range]))
                {
                    row.offset.x.as_mut_array()[l] = moment.x;
                    row.offset.y.as_mut_array()[l] = moment.y;
                    row.offset.z.as_mut_array()[l] = moment.z;
                    row.weight.as_mut_array()[l] = moment.w;
                    row.particle[l] = m;
                }
                let first = members.first().copied().unwrap_or(0);
                for row in &mut rows[members.len()..] {
                    row.particle[l] = first;
                }
            }
        }
        self.batch_rows = rows;
        self.batch_start = batch_start;
        self.colour_batches = colour_batches;
    }

    /// Runs `f(batch, slots, fit_rows)` for every batch of up to [`LANES`] cluster
    /// slots, colour after colour; the batches of one colour run in parallel (their
    /// clusters share no particle). `fit_rows` is scratch for [`Self::fit_batch`].
    pub(super) fn for_each_batch_by_colour(
        &self,
        f: impl Fn(usize, &[u32], &mut Vec<FitRow>) + Sync,
    ) {
        for (colour, batches) in self.colour_batches.windows(2).enumerate() {
            let clusters =
                self.colour_start[colour] as usize..self.colour_start[colour + 1] as usize;
            let order = &self.colour_order[clusters];
            (batches[0] as usize..batches[1] as usize)
                .into_par_iter()
                .with_min_len(CLUSTERS_PER_TASK / LANES)
                .for_each_init(Vec::new, |fit_rows, b| {
                    let first = (b - batches[0] as usize) * LANES;
                    let slots = &order[first..(first + LANES).min(order.len())];
                    f(b, slots, fit_rows)
                });
        }
    }

    /// Fits the clusters of batch `b` (`slots`: its cluster slots) to the particle
    /// positions at `positions`, updates their warm-start rotations, and leaves in `fit_rows`
    /// every member's position and pull. Returns the size of each lane's cluster (0 for
    /// unused lanes): row `j` of lane `l` is a member for `j < size[l]`, its particle
    /// `self.batch_rows(b)[j].particle[l]`.
    ///
    /// # Safety
    /// The caller is the task that owns the clusters of the batch in the current colour
    /// (see [`Disjoint`]), `positions` points to this layout's particle positions, and no
    /// task writes them during the call.
    #[inline(always)]
    pub(super) unsafe fn fit_batch(
        &self,
        b: usize,
        slots: &[u32],
        fit_rows: &mut Vec<FitRow>,
        positions: *const Vec3A,
        rotations: Disjoint<Quat>,
    ) -> [usize; LANES] {
        let rows = self.batch_rows(b);
        if fit_rows.len() < rows.len() {
            fit_rows.resize(rows.len(), FitRow::default());
        }
        let fit_rows = &mut fit_rows[..rows.len()];
        let mut size = [0usize; LANES];
        let mut warm = [Quat::IDENTITY; LANES];
        let mut bias = [Vec3A::ZERO; LANES];
        let (mut inv_weight_sum, mut stiffness) = ([0.0f32; LANES], [0.0f32; LANES]);
        for (l, &k) in slots.iter().enumerate() {
            let k = k as usize;
            let [start, end] = self.cluster_range[k];
            size[l] = (end - start) as usize;
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
            return size;
        };
        let origin = gather(first);
        let mut sum = Vec3x8::ZERO;
        let mut a = Mat3x8::ZERO;
        for (row, fit) in rows.iter().zip(fit_rows.iter_mut()) {
            fit.position = gather(row);
            let d = (fit.position - origin).scale(row.weight);
            sum = sum + d;
            a.x_axis = d.mul_add(row.offset.x, a.x_axis);
            a.y_axis = d.mul_add(row.offset.y, a.y_axis);
            a.z_axis = d.mul_add(row.offset.z, a.z_axis);
        }
        let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), ROTATION_ITERATIONS);
        for (l, &k) in slots.iter().enumerate() {
            // SAFETY: as above.
            unsafe { rotations.write(k as usize, q.lane(l)) };
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
        for (row, fit) in rows.iter().zip(fit_rows.iter_mut()) {
            let goal = scaled.mul_vec(row.offset) + translation;
            fit.pull = (goal - fit.position.scale(s)).to_lanes();
        }
        size
    }

    /// The rows of batch `b`.
    #[inline(always)]
    pub(super) fn batch_rows(&self, b: usize) -> &[BatchRow] {
        &self.batch_rows[self.batch_start[b] as usize..self.batch_start[b + 1] as usize]
    }
}
