//! The implicit groups in batches of eight, one group per SIMD lane, so that a sweep
//! fits and projects eight groups with one stream of instructions (as the clusters'
//! kernel does, [`crate::solver::clusters::fit`]). An implicit group is a particle and
//! its live linked neighbours, at most [`ROWS`] members: row `j` of a batch holds
//! member `j` of every lane's group, the centre in row 0. Rows carry the members'
//! particles, rest offsets (from the centre's rest position), moment diagonals and
//! compliances, and their `λ`; a member's step is the scalar sweep's
//! (`super::Sweep::project`), lane by lane. The groups of one colour share no
//! particle, so a batch's lanes, and the batches of a colour, write disjoint entries.
//!
//! Derived from the body's groups once per topology change; a plastic body's rows take
//! its rest shapes again after they creep ([`ImplicitBatches::refresh_rest`]).

use super::fit::{KINEMATIC_WEIGHT, ROTATION_ITERATIONS};
use crate::math::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::math::rotation::extract_rotation_x8;
use crate::math::simd::{Lane, WithLanes, dispatch};
use crate::solver::disjoint::Disjoint;
use glam::{Quat, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Rows per batch: the centre and its six links.
pub const ROWS: usize = 7;

/// Batches per parallel task.
const BATCHES_PER_TASK: usize = 32;

/// Member `j` of each lane's group.
#[derive(Clone, Copy, Debug, Default)]
struct Row {
    /// Dense particle per lane (padding: the lane's centre; an empty lane: the first
    /// lane's).
    at: [u32; LANES],
    /// The body's membership per lane (`u32::MAX` for padding).
    membership: [u32; LANES],
    /// Rest offset from the lane's centre (padding: 0).
    rest: Vec3x8,
    /// Moment diagonal per unit mass (padding: 0).
    moment: Vec3x8,
    /// Compliance (m/N) of the member's pull.
    compliance: f32x8,
    /// 1 for a member, 0 for padding.
    member: f32x8,
}

/// The implicit groups of one body in batches; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct ImplicitBatches {
    /// Per colour of the body: `[start, end)` of its batches (empty for a colour of
    /// explicit groups).
    colours: Vec<[u32; 2]>,
    /// [`ROWS`] rows per batch.
    rows: Vec<Row>,
    /// Per row: each lane's accumulated `λ` in this substep.
    lambda: Vec<Vec3x8>,
}

/// The memberships of a body's groups, as the batches are built from them.
pub struct Memberships<'a> {
    /// Dense member of each membership.
    pub members: &'a [u32],
    /// Rest position of each membership's particle.
    pub rest: &'a [Vec3A],
    /// Moment diagonal of each.
    pub moment: &'a [Vec3A],
    /// Compliance of each.
    pub compliance: &'a [f32],
}

/// The arrays a sweep reads and writes.
#[derive(Clone, Copy)]
pub(in crate::solver) struct Targets<'a> {
    pub(in crate::solver) positions: Disjoint<Vec3A>,
    pub(in crate::solver) corrections: Disjoint<Vec3A>,
    pub(in crate::solver) orientations: Disjoint<Quat>,
    pub(in crate::solver) moved: Disjoint<Vec3A>,
    pub(in crate::solver) inv_mass: &'a [f32],
    /// `1/dt²`.
    pub(in crate::solver) inv_dt2: f32,
    /// How far past its goal a member moves.
    pub(in crate::solver) over_relaxation: f32,
}

impl ImplicitBatches {
    /// The batches of the implicit groups: per colour, `Some` list of its groups'
    /// membership ranges (centre first), or `None` for a colour of explicit groups.
    pub fn build(colours: &[Option<Vec<[u32; 2]>>], of: &Memberships) -> Self {
        let mut out = ImplicitBatches::default();
        for groups in colours {
            let first = (out.rows.len() / ROWS) as u32;
            for batch in groups.as_deref().unwrap_or(&[]).chunks(LANES) {
                let mut rows = [Row::default(); ROWS];
                for row in &mut rows {
                    row.membership = [u32::MAX; LANES];
                }
                for (l, range) in batch.iter().enumerate() {
                    let centre = range[0] as usize;
                    for (j, k) in (range[0]..range[1]).enumerate().take(ROWS) {
                        let (k, row) = (k as usize, &mut rows[j]);
                        row.at[l] = of.members[k];
                        row.membership[l] = k as u32;
                        set(&mut row.rest, l, of.rest[k] - of.rest[centre]);
                        set(&mut row.moment, l, of.moment[k]);
                        row.compliance.as_mut_array()[l] = of.compliance[k];
                        row.member.as_mut_array()[l] = 1.0;
                    }
                    for row in &mut rows[(range[1] - range[0]) as usize..] {
                        row.at[l] = of.members[centre];
                    }
                }
                // (an empty lane reads the first lane's centre: a particle of this batch)
                for row in &mut rows {
                    for l in batch.len()..LANES {
                        row.at[l] = of.members[batch[0][0] as usize];
                    }
                }
                out.rows.extend(rows);
            }
            out.colours.push([first, (out.rows.len() / ROWS) as u32]);
        }
        out.lambda = vec![Vec3x8::default(); out.rows.len()];
        out
    }

    /// Takes the rest positions `rest` of the body's memberships again (a plastic
    /// body's, after they crept).
    pub fn refresh_rest(&mut self, rest: &[Vec3A]) {
        for batch in self.rows.chunks_mut(ROWS) {
            let centre = batch[0].membership;
            for row in batch {
                for (l, (k, c)) in row.membership.into_iter().zip(centre).enumerate() {
                    if k != u32::MAX {
                        set(&mut row.rest, l, rest[k as usize] - rest[c as usize]);
                    }
                }
            }
        }
    }

    /// Starts a substep: every `λ` back to zero.
    pub fn begin_substep(&mut self) {
        self.lambda.fill(Vec3x8::default());
    }

    /// Whether colour `c` of the body is batched here.
    pub fn has_colour(&self, c: usize) -> bool {
        self.colours.get(c).is_some_and(|r| r[0] < r[1])
    }

    /// Fits and projects the groups of colour `c` (see the module docs), its batches in
    /// parallel.
    ///
    /// # Safety
    /// `targets` hold every particle of this body's groups, and no other task touches
    /// them during the call.
    pub(in crate::solver) unsafe fn sweep_colour(&mut self, c: usize, targets: &Targets) {
        let [first, end] = self.colours[c].map(|b| b as usize);
        let rows = &self.rows[first * ROWS..end * ROWS];
        let lambda = &mut self.lambda[first * ROWS..end * ROWS];
        rows.par_chunks(ROWS * BATCHES_PER_TASK)
            .zip(lambda.par_chunks_mut(ROWS * BATCHES_PER_TASK))
            .for_each(|(rows, lambda)| {
                for (rows, lambda) in rows.chunks(ROWS).zip(lambda.chunks_mut(ROWS)) {
                    dispatch(Batch {
                        rows,
                        lambda,
                        targets,
                    });
                }
            });
    }
}

/// Sets lane `l` of `v`.
fn set(v: &mut Vec3x8, l: usize, value: Vec3A) {
    v.x.as_mut_array()[l] = value.x;
    v.y.as_mut_array()[l] = value.y;
    v.z.as_mut_array()[l] = value.z;
}

/// One batch's fit and projection, run with the backend [`dispatch`] picks.
struct Batch<'a, 'b> {
    rows: &'a [Row],
    lambda: &'a mut [Vec3x8],
    targets: &'a Targets<'b>,
}

impl WithLanes for Batch<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run<L: Lane>(self) {
        let Batch {
            rows,
            lambda,
            targets: t,
        } = self;
        // SAFETY (every read and write below): the rows' particles belong to this
        // batch's groups, which no other task touches during the colour (the caller's
        // contract); padding reads the lane's centre and writes nothing.
        let read = |at: &[u32; LANES]| unsafe { at.map(|d| t.positions.read(d as usize)) };
        let mut position = [Vec3x8::<L>::ZERO; ROWS];
        let mut inv_mass = [L::ZERO; ROWS];
        let mut weight = [L::ZERO; ROWS];
        let mut heaviest = L::ZERO;
        for (j, row) in rows.iter().enumerate() {
            position[j] = Vec3x8::from_lanes(read(&row.at));
            inv_mass[j] = L::from_array(row.at.map(|d| t.inv_mass[d as usize]));
            let moving = inv_mass[j].simd_gt(L::ZERO) & L::from_stored(row.member).simd_gt(L::ZERO);
            heaviest = heaviest.max(moving.select(L::ONE / inv_mass[j], L::ZERO));
        }
        // the fit's weights (see `fit::KINEMATIC_WEIGHT`): a mass, or for a member held
        // still a thousand times the heaviest moving member's
        let kinematic =
            L::splat(KINEMATIC_WEIGHT) * heaviest.simd_gt(L::ZERO).select(heaviest, L::ONE);
        let (mut sum, mut rest_sum, mut total) = (Vec3x8::<L>::ZERO, Vec3x8::<L>::ZERO, L::ZERO);
        let origin = position[0];
        for (j, row) in rows.iter().enumerate() {
            let w = inv_mass[j];
            weight[j] =
                w.simd_gt(L::ZERO).select(L::ONE / w, kinematic) * L::from_stored(row.member);
            sum = (position[j] - origin).mul_add(weight[j], sum);
            rest_sum = Vec3x8::load(&row.rest).mul_add(weight[j], rest_sum);
            total = total + weight[j];
        }
        let inv_total = L::ONE / total;
        let (centre, rest_centre) = (sum.scale(inv_total), rest_sum.scale(inv_total));
        // A = Σ m (x − c)(x̄ − c̄)ᵀ + Σ m R D; its rotation is warm-started from the
        // centre's (row 0) orientation, the rotation the group gave last
        let mut a = Mat3x8::<L>::ZERO;
        let mut warm = None;
        for (j, row) in rows.iter().enumerate() {
            let x = (position[j] - origin - centre).scale(weight[j]);
            let r = Vec3x8::load(&row.rest) - rest_centre;
            // SAFETY: as above
            let q = Quatx8::from_lanes(unsafe { row.at.map(|d| t.orientations.read(d as usize)) });
            warm.get_or_insert(q);
            let turn = Mat3x8::from_quat(q);
            let d = Vec3x8::<L>::load(&row.moment).scale(weight[j]);
            a.x_axis = turn.x_axis.mul_add(d.x, x.mul_add(r.x, a.x_axis));
            a.y_axis = turn.y_axis.mul_add(d.y, x.mul_add(r.y, a.y_axis));
            a.z_axis = turn.z_axis.mul_add(d.z, x.mul_add(r.z, a.z_axis));
        }
        let Some(warm) = warm else {
            return;
        };
        let rotation = extract_rotation_x8(&a, warm, ROTATION_ITERATIONS);
        let turn = Mat3x8::from_quat(rotation);
        let centroid = origin + centre;
        let (inv_dt2, relax) = (L::splat(t.inv_dt2), L::splat(t.over_relaxation));
        for (j, (row, lambda)) in rows.iter().zip(lambda.iter_mut()).enumerate() {
            let goal = turn.mul_vec_add(Vec3x8::load(&row.rest) - rest_centre, centroid);
            let c = position[j] - goal;
            let alpha = L::from_stored(row.compliance) * inv_dt2;
            let l = Vec3x8::<L>::load(lambda);
            let w = inv_mass[j];
            let scale = relax / (w + alpha);
            let delta = (Vec3x8::ZERO - c - l.scale(alpha)).scale(scale);
            let active = w.simd_gt(L::ZERO) & L::from_stored(row.member).simd_gt(L::ZERO);
            let delta = Vec3x8::select(active, delta, Vec3x8::ZERO);
            *lambda = (l + delta).store();
            let step = delta.scale(w).to_lanes();
            let active = (active & L::ONE).to_array();
            for l in 0..LANES {
                if active[l] > 0.0 {
                    let d = row.at[l] as usize;
                    // SAFETY: as above
                    unsafe {
                        t.positions.write(d, t.positions.read(d) + step[l]);
                        t.corrections.write(d, t.corrections.read(d) + step[l]);
                        t.moved.write(d, t.moved.read(d) + step[l]);
                        // (the centre, moving, takes the group's rotation)
                        if j == 0 {
                            t.orientations.write(d, rotation.lane(l));
                        }
                    }
                }
            }
        }
    }
}
