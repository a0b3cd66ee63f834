//! Batched cluster fits: eight clusters of one colour are fitted at once, one per SIMD
//! lane. Their members are gathered into rows (row `j` holds member `j` of every lane's
//! cluster), the moment matrices are accumulated and the rotations extracted (Müller
//! 2016, warm-started) eight wide, and every row's pull `R q + c − p` is computed eight
//! wide and handed to the scheme's kernel (`BatchKernel`), which applies it member by
//! member.
//!
//! A fit is done relative to the cluster's first member so that goals keep full
//! precision far from the origin; a lane's padding rows (past its cluster's size) have
//! weight 0 and sit at that origin, so they add nothing.

use super::rows::{EMPTY_LANE, FitRow, Group, MomentRow, ParticleRow, TEMPLATED};
use super::term::ClusterTerm;
use crate::math::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::math::rotation::{extract_rotation, extract_rotation_x8};
use crate::math::simd::{Lane, WithLanes, dispatch};
use crate::solver::disjoint::Disjoint;
use glam::{Mat3A, Quat, Vec3A};
use rayon::prelude::*;

/// What a solver scheme does with one batch: generic over the lane type, so that each
/// group of batches runs with the backend [`dispatch`] picks.
pub(in crate::solver) trait BatchKernel: Sync {
    /// Runs batch `b` with lanes `L` (inline it: see [`WithLanes::run`]); `fit_rows` is
    /// scratch for [`ClusterTerm::fit_batch`].
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
pub(in crate::solver) struct RowPulls<'a> {
    /// The row's particles as byte offsets (see [`ParticleRow`]).
    pub(in crate::solver) at: &'a [u32; LANES],
    /// The members' positions the fit saw.
    pub(in crate::solver) position: &'a Vec3x8,
    /// The pull `R q + c − p` of each lane's member; exactly zero on a padding row
    /// (whose particle is the lane's first member, so adding it changes nothing).
    pub(in crate::solver) pull: [Vec3A; LANES],
    /// The row's index in the batch.
    pub(in crate::solver) row: usize,
    /// Each lane's cluster size (0 for an unused lane): lane `l`'s entry is a member
    /// when `row < size[l]`.
    pub(in crate::solver) size: &'a [u32; LANES],
}

impl ClusterTerm {
    /// Runs `kernel` on every batch, colour after colour; the groups of one colour run
    /// in parallel (they share no particle), each group's batches in order.
    pub(in crate::solver) fn for_each_batch_by_colour(&self, kernel: &impl BatchKernel) {
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
    pub(in crate::solver) fn first_row(&self, b: usize) -> usize {
        self.batches.start[b] as usize
    }

    /// Particle rows of all batches.
    pub(in crate::solver) fn row_count(&self) -> usize {
        self.batches.particles.len()
    }

    /// The cluster slot in each lane of batch `b` (`None`: an empty lane).
    #[inline(always)]
    pub(in crate::solver) fn lane_clusters(&self, b: usize) -> [Option<usize>; LANES] {
        self.batches.lanes[b].map(|k| (k != EMPTY_LANE).then_some(k as usize))
    }

    /// Which lanes of batch `b` hold a cluster.
    #[inline(always)]
    pub(in crate::solver) fn lanes_in_use(&self, b: usize) -> [bool; LANES] {
        self.batches.lanes[b].map(|k| k != EMPTY_LANE)
    }

    /// The weight of each lane's cluster's pulls in batch `b`
    /// ([`ClusterTerm::pull_weight_of`]; 0 for an unused lane), or `None` when every
    /// cluster's is 1.
    pub(in crate::solver) fn lane_stiffness(&self, b: usize) -> Option<[f32; LANES]> {
        if self.shared_compliance.is_some() {
            return None;
        }
        Some(self.batches.lanes[b].map(|k| {
            if k == EMPTY_LANE {
                0.0
            } else {
                self.pull_weight_of(k as usize)
            }
        }))
    }

    /// Cluster slot `k`'s rotation fitted to `positions` one cluster at a time (not
    /// batched: for the occasional fits to convergence), from `warm`, with at most
    /// `max_iterations` rotation iterations.
    pub(in crate::solver) fn fit_rotation(
        &self,
        k: usize,
        positions: &[Vec3A],
        warm: Quat,
        max_iterations: u32,
    ) -> Quat {
        self.moment(k, positions)
            .map_or(warm, |a| extract_rotation(a, warm, max_iterations))
    }

    /// The moment matrix of cluster slot `k`'s members at `positions` against their rest
    /// offsets, `Σ wᵢ (pᵢ − c) qᵢᵀ`, what its rotation is extracted from (`None` for a
    /// cluster without members).
    pub(in crate::solver) fn moment(&self, k: usize, positions: &[Vec3A]) -> Option<Mat3A> {
        let members = self.cluster_members(k);
        let &first = members.first()?;
        // (relative to the first member: full precision far from the origin)
        let origin = positions[first as usize];
        let (mut sum, mut total) = (Vec3A::ZERO, 0.0f32);
        for &m in members {
            let w = self.weight(m);
            sum += (positions[m as usize] - origin) * w;
            total += w;
        }
        let centre = sum / total;
        Some(
            (members.iter().enumerate()).fold(Mat3A::ZERO, |a, (j, &m)| {
                let d = (positions[m as usize] - origin - centre) * self.weight(m);
                let q = self.rest_offset(k, j, m);
                a + Mat3A::from_cols(d * q.x, d * q.y, d * q.z)
            }),
        )
    }

    /// The particle rows of batch `b`.
    #[inline(always)]
    pub(super) fn batch_particles(&self, b: usize) -> &[ParticleRow] {
        let start = &self.batches.start;
        &self.batches.particles[start[b] as usize..start[b + 1] as usize]
    }

    /// The moment rows of batch `b`: its own, or the template's.
    #[inline(always)]
    pub(super) fn batch_moments(&self, b: usize) -> &[MomentRow] {
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
    pub(in crate::solver) unsafe fn fit_batch<L: Lane>(
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
