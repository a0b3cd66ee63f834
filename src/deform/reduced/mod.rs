//! Non-linear solves reduced to a handle subspace (the "domain reduction" of SPEC
//! §6.3): ARAP ([`arap`]) and projective dynamics ([`dynamics`]) with the positions
//! `V = V̄ + W ΔH`, so that an iteration costs in the number of handle parameters and
//! rotation groups, not of particles. The user's handles are the first columns and
//! stay where the user puts them; [`auto_handles`] places the point handles whose
//! parameters are solved for.
//!
//! Both energies are sums over rotation groups `g` of `Σ w ‖s − R_g e‖²`, where `e`
//! is a rest difference of particles (a lattice spoke, or a member's offset from its
//! cluster's centre) and `s = e + D ΔH` the same difference posed (`D` the difference
//! of the particles' rows of `W`). With `Q_g = Σ w e eᵀ` and `P_g = Σ w Dᵀ eᵀ` (one
//! 3-vector per column) and `G = Σ w DᵀD` precomputed, a group's fit is
//! `S_g = Q_g + ΔHᵀ P_g`, the global step's right side is `Σ_g (R_g − I) P_g`, and the
//! energy is `Σ_g 2 tr(Q_g) − 2 tr(R_g Q_g) + 2 ΔH · (I − R_g) P_g` plus `ΔHᵀ G ΔH`.

pub mod arap;
pub mod dynamics;

use super::handles::Handle;
use crate::body::lattice::Lattice;
use crate::math::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::math::rotation::{extract_rotation_x8, warm_start};
use glam::{DMat3, DVec3, Quat, Vec3, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// Steps of the rotation extraction per fit (the fits of one solve carry on from each
/// other's).
const FIT_STEPS: u32 = 4;

/// `tr(Rᵀ S)`: how well `r` fits `s`.
fn score(s: &DMat3, r: &DMat3) -> f64 {
    r.x_axis.dot(s.x_axis) + r.y_axis.dot(s.y_axis) + r.z_axis.dot(s.z_axis)
}

/// `count` point handles placed by farthest-point sampling over the live particles,
/// away from the particles of `user`'s handles and from each other (deterministic: ties
/// go to the lowest particle index).
pub fn auto_handles(
    lattice: &Lattice,
    rest: &[Vec3],
    user: &[Handle],
    count: usize,
) -> Vec<Handle> {
    let live: Vec<u32> = lattice.live_particles().collect();
    let mut distance: Vec<f32> = vec![f32::INFINITY; live.len()];
    let update = |from: Vec3, distance: &mut [f32]| {
        for (d, &i) in distance.iter_mut().zip(&live) {
            *d = d.min(rest[i as usize].distance(from));
        }
    };
    for p in user.iter().flat_map(|h| h.particles()) {
        update(rest[*p as usize], &mut distance);
    }
    let mut out = Vec::with_capacity(count);
    for _ in 0..count.min(live.len()) {
        let (best, &d) = distance
            .iter()
            .enumerate()
            .fold(
                (0, &f32::NEG_INFINITY),
                |a, b| if b.1 > a.1 { b } else { a },
            );
        if d <= 0.0 {
            break;
        }
        let p = live[best];
        out.push(Handle::Point(p));
        update(rest[p as usize], &mut distance);
    }
    out
}

/// The precomputed products of a grouped rotation energy in the subspace (see the
/// module doc).
#[derive(Clone, Debug)]
pub(crate) struct Groups {
    /// Columns of the subspace.
    columns: usize,
    /// `Q_g` per group.
    q: Vec<DMat3>,
    /// `P_g` per group, `columns` rows each.
    p: Vec<DVec3>,
    /// `G`, row-major.
    g: Vec<f64>,
}

impl Groups {
    /// No groups yet, `groups` to come, over `columns` columns.
    pub(crate) fn new(groups: usize, columns: usize) -> Self {
        Self {
            columns,
            q: vec![DMat3::ZERO; groups],
            p: vec![DVec3::ZERO; groups * columns],
            g: vec![0.0; columns * columns],
        }
    }

    /// Adds one difference to group `group`'s `Q_g` and `P_g`: weight `w`, its row
    /// difference `d` (one entry per column) and its rest difference `e`. (`G` is the
    /// caller's: [`weighted_gram`] sums it over particles instead of differences.)
    pub(crate) fn add(&mut self, group: usize, w: f64, d: &[f64], e: DVec3) {
        let h = self.columns;
        self.q[group] += DMat3::from_cols(e * e.x, e * e.y, e * e.z) * w;
        for (p, &dc) in self.p[group * h..][..h].iter_mut().zip(d) {
            *p += e * (w * dc);
        }
    }

    /// Sets `G` (row-major, `columns²` entries).
    pub(crate) fn set_g(&mut self, g: Vec<f64>) {
        assert_eq!(
            g.len(),
            self.columns * self.columns,
            "G is columns × columns"
        );
        self.g = g;
    }

    /// Number of groups.
    pub(crate) fn len(&self) -> usize {
        self.q.len()
    }

    /// `G`'s entry `(r, c)`.
    pub(crate) fn g(&self, r: usize, c: usize) -> f64 {
        self.g[r * self.columns + c]
    }

    /// Group `g`'s `P_g`.
    fn p(&self, g: usize) -> &[DVec3] {
        &self.p[g * self.columns..][..self.columns]
    }

    /// Each group's rotation fitted to `dh`, eight groups at a time: `S_g` in double
    /// precision, a few steps of the eight-lane rotation extraction from the current
    /// rotations (an iteration's fits carry on from the last one's), and a rotation
    /// kept where the new one would not raise `tr(RᵀS_g)`, so no fit raises the energy.
    pub(crate) fn fit(&self, dh: &[DVec3], rotations: &mut [DMat3]) {
        rotations
            .par_chunks_mut(LANES)
            .enumerate()
            .for_each(|(chunk, rotations)| {
                let mut s = [DMat3::ZERO; LANES];
                for (k, s) in s.iter_mut().enumerate().take(rotations.len()) {
                    // S_g = Q_g + ΔHᵀ P_g, column by column
                    let g = chunk * LANES + k;
                    let (mut x, mut y, mut z) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
                    for (d, p) in dh.iter().zip(self.p(g)) {
                        x += *d * p.x;
                        y += *d * p.y;
                        z += *d * p.z;
                    }
                    *s = self.q[g] + DMat3::from_cols(x, y, z);
                }
                let column = |f: fn(&DMat3) -> DVec3| {
                    Vec3x8::<f32x8>::from_lanes(s.map(|m| Vec3A::from(f(&m).as_vec3())))
                };
                let a = Mat3x8 {
                    x_axis: column(|m| m.x_axis),
                    y_axis: column(|m| m.y_axis),
                    z_axis: column(|m| m.z_axis),
                };
                let mut warm = [Quat::IDENTITY; LANES];
                for (w, r) in warm.iter_mut().zip(rotations.iter()) {
                    *w = warm_start(Quat::from_mat3(&r.as_mat3()));
                }
                let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), FIT_STEPS);
                for (k, r) in rotations.iter_mut().enumerate() {
                    let fitted = DMat3::from_quat(q.lane(k).as_dquat().normalize());
                    if score(&s[k], &fitted) > score(&s[k], r) {
                        *r = fitted;
                    }
                }
            });
    }

    /// `Σ_g (R_g − I) P_g`, one vector per column: summed in fixed chunks of groups,
    /// then chunk by chunk in order, so the sum is the same on any number of threads.
    pub(crate) fn rotated_loads(&self, rotations: &[DMat3]) -> Vec<DVec3> {
        const CHUNK: usize = 64;
        let h = self.columns;
        let partials: Vec<Vec<DVec3>> = rotations
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(chunk, rotations)| {
                let mut acc = vec![DVec3::ZERO; h];
                for (k, r) in rotations.iter().enumerate() {
                    let m = *r - DMat3::IDENTITY;
                    for (a, p) in acc.iter_mut().zip(self.p(chunk * CHUNK + k)) {
                        *a += m * *p;
                    }
                }
                acc
            })
            .collect();
        let mut sum = vec![DVec3::ZERO; h];
        for partial in partials {
            for (s, p) in sum.iter_mut().zip(partial) {
                *s += p;
            }
        }
        sum
    }

    /// The energy of `dh` with `rotations`, given `loads` (what
    /// [`Groups::rotated_loads`] gives for these rotations): the cross terms
    /// `Σ_g ΔH · (I − R_g) P_g` are `−ΔH · loads`.
    pub(crate) fn energy(&self, dh: &[DVec3], rotations: &[DMat3], loads: &[DVec3]) -> f64 {
        let h = self.columns;
        let trace = |m: DMat3| m.x_axis.x + m.y_axis.y + m.z_axis.z;
        let mut e: f64 = rotations
            .iter()
            .zip(&self.q)
            .map(|(r, q)| 2.0 * trace(*q) - 2.0 * trace(*r * *q))
            .sum();
        e -= 2.0 * dh.iter().zip(loads).map(|(d, l)| d.dot(*l)).sum::<f64>();
        for r in 0..h {
            for c in 0..h {
                e += self.g[r * h + c] * dh[r].dot(dh[c]);
            }
        }
        e
    }
}

/// `Σᵢ wᵢ aᵢᵀ bᵢ` (row-major, `h × h`, made symmetric) over `particles`, where
/// `rows(i, a, b)` fills particle `i`'s rows `a` and `b` and returns `wᵢ`. Summed in
/// fixed chunks, then chunk by chunk in order: the same on any number of threads.
pub(crate) fn weighted_gram(
    particles: &[u32],
    h: usize,
    rows: impl Fn(u32, &mut [f64], &mut [f64]) -> f64 + Sync,
) -> Vec<f64> {
    let partials: Vec<Vec<f64>> = particles
        .par_chunks(512)
        .map(|chunk| {
            let (mut a, mut b) = (vec![0.0; h], vec![0.0; h]);
            let mut sum = vec![0.0; h * h];
            for &i in chunk {
                let w = rows(i, &mut a, &mut b);
                for (r, &ar) in a.iter().enumerate() {
                    if ar == 0.0 {
                        continue;
                    }
                    for (s, &bc) in sum[r * h..][..h].iter_mut().zip(&b) {
                        *s += w * ar * bc;
                    }
                }
            }
            sum
        })
        .collect();
    let mut g = vec![0.0; h * h];
    for partial in partials {
        for (g, p) in g.iter_mut().zip(partial) {
            *g += p;
        }
    }
    for r in 0..h {
        for c in 0..r {
            let mean = 0.5 * (g[r * h + c] + g[c * h + r]);
            g[r * h + c] = mean;
            g[c * h + r] = mean;
        }
    }
    g
}

/// The Cholesky factor of a dense symmetric positive definite matrix of the free
/// columns, with its solve for three right-hand sides.
#[derive(Clone, Debug)]
pub(crate) struct DenseFactor {
    llt: faer::linalg::solvers::Llt<f64>,
}

impl DenseFactor {
    /// Factors the `n × n` matrix `entry(r, c)`; `None` if it is not positive definite.
    pub(crate) fn new(n: usize, entry: impl Fn(usize, usize) -> f64) -> Option<Self> {
        let m = faer::Mat::<f64>::from_fn(n, n, entry);
        m.llt(faer::Side::Lower).ok().map(|llt| Self { llt })
    }

    /// Solves for `rhs` (one 3-vector per row) in place.
    pub(crate) fn solve(&self, rhs: &mut [DVec3]) {
        use faer::linalg::solvers::SolveCore;
        let mut b = faer::Mat::<f64>::from_fn(rhs.len(), 3, |r, c| rhs[r][c]);
        self.llt
            .solve_in_place_with_conj(faer::Conj::No, b.as_mut());
        for (r, x) in rhs.iter_mut().enumerate() {
            *x = DVec3::new(b[(r, 0)], b[(r, 1)], b[(r, 2)]);
        }
    }
}

/// Rotation groups of a lattice: the live particles of each block of `cells`³ lattice
/// cells and each piece. Returns each particle's group (`u32::MAX`: removed) and the
/// number of groups, numbered in order of their lowest particle.
pub fn block_groups(lattice: &Lattice, cells: u32) -> (Vec<u32>, usize) {
    let labels = lattice.pieces();
    let mut group = vec![u32::MAX; lattice.len()];
    let mut index = std::collections::HashMap::new();
    for i in lattice.live_particles() {
        let key = (
            lattice
                .coord(i)
                .div_euclid(glam::IVec3::splat(cells.max(1) as i32)),
            labels.label[i as usize],
        );
        let next = index.len() as u32;
        group[i as usize] = *index.entry(key).or_insert(next);
    }
    (group, index.len())
}
