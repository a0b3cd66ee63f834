//! The particles' state in the solver's dense order: positions, velocities, orientations,
//! angular velocities and inverse masses, and what a substep derives from them. The ECS components hold a particle's
//! state between frames; within a frame these arrays do — loaded once at its start,
//! advanced by every substep (prediction, solve, velocities), written back after the
//! substeps.

use super::term::ParticleState;
use crate::math::lanes::{LANES, Quatx8};
use crate::math::log_map::{turn, turn_x8};
use crate::math::simd::{Lane, WithLanes, dispatch};
use glam::{Quat, Vec3, Vec3A};
use rayon::prelude::*;
use std::iter::repeat_n;

/// Particles per parallel task.
pub const PARTICLES_PER_TASK: usize = 2048;

/// Particles per parallel task of the non-finite scan.
const SCAN_PER_TASK: usize = 8192;

/// Fills `v` with `items` in the allocation it has, giving back what it holds beyond a
/// quarter more than it needs. An empty one is sized exactly; one too small grows with
/// an eighth to spare: its body grew (by splits) and will likely grow again, and each
/// growth copies the old allocation.
fn refill<T>(v: &mut Vec<T>, items: impl ExactSizeIterator<Item = T>) {
    let n = items.len();
    v.clear();
    if v.capacity() < n {
        let spare = if v.capacity() == 0 { 0 } else { n / 8 };
        v.reserve_exact(n + spare);
    }
    v.extend(items);
    if v.capacity() > n + n / 4 {
        v.shrink_to_fit();
    }
}

/// Dense particle state (see the module docs).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Particles {
    /// Positions (predicted, then solved, during a substep).
    pub positions: Vec<Vec3A>,
    /// Positions at the start of the substep.
    pub previous: Vec<Vec3A>,
    /// Velocities.
    pub velocities: Vec<Vec3A>,
    /// Inverse masses as the solver takes them: 0 for a particle held kinematic (by a
    /// hard attachment, or pinned by hand) or cut away.
    pub inv_mass: Vec<f32>,
    /// Total position correction of each particle in the last solve.
    pub corrections: Vec<Vec3A>,
    /// The predictions the last solve started from.
    pub predicted: Vec<Vec3A>,
    /// Orientations (unit quaternions; rest: identity), predicted from the angular
    /// velocities, then set by the solve where a term or the clusters turn them.
    pub orientations: Vec<Quat>,
    /// Orientations at the start of the substep.
    pub previous_orientations: Vec<Quat>,
    /// Angular velocities (rad/s, world frame).
    pub spins: Vec<Vec3A>,
}

impl Particles {
    /// Particles at rest at `positions`, of unit inverse mass.
    pub fn at_rest(positions: &[Vec3]) -> Self {
        let mut particles = Particles::default();
        particles.reset_at_rest(positions);
        particles
    }

    /// Makes these particles [`Particles::at_rest`] at `positions`, in the arrays they
    /// have: a relayout of a big body then writes memory it already holds instead of
    /// freeing it and touching as much afresh.
    pub fn reset_at_rest(&mut self, positions: &[Vec3]) {
        let n = positions.len();
        refill(
            &mut self.positions,
            positions.iter().map(|r| Vec3A::from(*r)),
        );
        refill(&mut self.previous, self.positions.iter().copied());
        refill(&mut self.predicted, self.positions.iter().copied());
        refill(&mut self.velocities, repeat_n(Vec3A::ZERO, n));
        refill(&mut self.inv_mass, repeat_n(1.0, n));
        refill(&mut self.corrections, repeat_n(Vec3A::ZERO, n));
        refill(&mut self.orientations, repeat_n(Quat::IDENTITY, n));
        refill(&mut self.previous_orientations, repeat_n(Quat::IDENTITY, n));
        refill(&mut self.spins, repeat_n(Vec3A::ZERO, n));
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The prediction of a substep of `dt`: `v ← (v + g·dt)·e^(−damping·dt)`,
    /// `x_prev ← x`, `x ← x + v·dt`, and likewise `ω ← ω·e^(−damping·dt)`,
    /// `q_prev ← q`, `q ← exp(ω dt) q` (the exact turn at constant `ω`, so that a free
    /// particle's spin survives the round trip through [`Particles::update_velocities`]);
    /// a particle of inverse mass 0 keeps its velocity and spin.
    ///
    /// `cluster_counts` is the number of clusters each particle is in
    /// ([`crate::solver::clusters::term::ClusterTerm::member_counts`]; a particle past its
    /// end is in none). The orientation of a particle in any is set by their blend after
    /// the solve ([`crate::solver::clusters::term::ClusterTerm::blend_orientations`]), and
    /// no term reads it before, so it is not turned here (`q_prev ← q` only): its spin is
    /// not needed until the frame ends.
    pub fn predict(&mut self, dt: f32, gravity: Vec3, damping: f32, cluster_counts: &[u32]) {
        let keep = (-damping * dt).exp();
        let dv = Vec3A::from(gravity * dt);
        self.positions
            .par_iter_mut()
            .zip(self.previous.par_iter_mut())
            .zip(self.velocities.par_iter_mut())
            .zip(self.inv_mass.par_iter())
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(((x, prev), v), inv_mass)| {
                *prev = *x;
                if *inv_mass != 0.0 {
                    *v = (*v + dv) * keep;
                }
                *x += *v * dt;
            });
        self.orientations
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(
                self.previous_orientations
                    .par_chunks_mut(PARTICLES_PER_TASK),
            )
            .zip(self.spins.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.inv_mass.par_chunks(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, (((q, prev), w), inv_mass))| {
                prev.copy_from_slice(q);
                let first = task * PARTICLES_PER_TASK;
                for i in 0..q.len() {
                    if in_clusters(cluster_counts, first + i) {
                        continue;
                    }
                    if inv_mass[i] != 0.0 {
                        w[i] *= keep;
                    }
                    if w[i] != Vec3A::ZERO {
                        q[i] = (Quat::from_scaled_axis(Vec3::from(w[i] * dt)) * q[i]).normalize();
                    }
                }
            });
    }

    /// Adds the last solve's corrections to the velocities, `v += Σ Δp / dt`, and sets
    /// each angular velocity to the substep's turn, `ω = log(q q_prev⁻¹) / dt` — that of
    /// a particle in clusters (`cluster_counts`, as for [`Particles::predict`]) only when
    /// the substep `ends_frame`: until then nothing reads it.
    ///
    /// Deriving velocity from the corrections rather than from `(p − p_prev) / dt` keeps
    /// the rounding of large absolute positions out of the velocities, so momentum is
    /// conserved to the precision of the (small) corrections. Orientations have no such
    /// offset, so their turn is read off directly.
    pub fn update_velocities(&mut self, inv_dt: f32, cluster_counts: &[u32], ends_frame: bool) {
        self.velocities
            .par_iter_mut()
            .zip(&self.corrections)
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(v, c)| *v += *c * inv_dt);
        self.spins
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.orientations.par_chunks(PARTICLES_PER_TASK))
            .zip(self.previous_orientations.par_chunks(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, ((spins, to), from))| {
                let counts = cluster_counts
                    .get(task * PARTICLES_PER_TASK..)
                    .unwrap_or(&[]);
                dispatch(SpinBlock {
                    spins,
                    from,
                    to,
                    counts,
                    inv_dt,
                    ends_frame,
                })
            });
    }

    /// The arrays as a term sees them.
    pub fn state(&mut self) -> ParticleState<'_> {
        ParticleState {
            positions: &mut self.positions,
            previous: &self.previous,
            inv_mass: &self.inv_mass,
            corrections: &mut self.corrections,
            orientations: &mut self.orientations,
            spins: &self.spins,
        }
    }

    /// The guard against non-finite positions: one NaN in a cluster's fit turns the
    /// whole cluster NaN, and the next iterations carry it across the body. Every live
    /// particle (`live[d]`) whose position is not finite goes back to its substep-start
    /// position if that is finite, else to `fallback(d, positions)`, with zero velocity.
    /// Returns their dense indices, ascending (empty on the usual path, which costs one
    /// multiply-add per particle).
    pub fn repair_non_finite(
        &mut self,
        live: &[bool],
        fallback: impl Fn(usize, &[Vec3A]) -> Vec3A,
    ) -> Vec<u32> {
        let bad: Vec<u32> = self
            .positions
            .par_chunks(SCAN_PER_TASK)
            .enumerate()
            .flat_map_iter(|(task, chunk)| {
                // Σ 0·p stays zero while every point is finite
                let probe = chunk
                    .iter()
                    .fold(Vec3A::ZERO, |probe, p| probe + *p * Vec3A::ZERO);
                let first = task * SCAN_PER_TASK;
                let found: Vec<u32> = if probe.is_nan() {
                    (0..chunk.len())
                        .filter(|i| !chunk[*i].is_finite() && live.get(first + i) == Some(&true))
                        .map(|i| (first + i) as u32)
                        .collect()
                } else {
                    Vec::new()
                };
                found
            })
            .collect();
        for &d in &bad {
            let d = d as usize;
            let back = self.previous[d];
            let at = if back.is_finite() {
                back
            } else {
                fallback(d, &self.positions)
            };
            self.positions[d] = at;
            self.previous[d] = at;
            self.velocities[d] = Vec3A::ZERO;
            self.orientations[d] = self.previous_orientations[d];
            self.spins[d] = Vec3A::ZERO;
        }
        bad
    }
}

/// Whether particle `d` is in any cluster by `cluster_counts` (see [`Particles::predict`]).
fn in_clusters(cluster_counts: &[u32], d: usize) -> bool {
    cluster_counts.get(d).is_some_and(|&count| count > 0)
}

/// One task's angular velocities, eight particles at a time (see
/// [`Particles::update_velocities`]): `counts` are its particles' cluster counts (as
/// many as the body's list has from its first).
struct SpinBlock<'a> {
    spins: &'a mut [Vec3A],
    from: &'a [Quat],
    to: &'a [Quat],
    counts: &'a [u32],
    inv_dt: f32,
    ends_frame: bool,
}

/// The quaternions `q[first..first + 8]` as lanes, the identity past the end.
#[inline(always)]
fn eight_from<L: Lane>(q: &[Quat], first: usize) -> Quatx8<L> {
    Quatx8::from_lanes(std::array::from_fn(|l| {
        q.get(first + l).copied().unwrap_or(Quat::IDENTITY)
    }))
}

impl WithLanes for SpinBlock<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lane>(self) {
        for first in (0..self.spins.len()).step_by(LANES) {
            let n = LANES.min(self.spins.len() - first);
            let clustered = |i: usize| in_clusters(self.counts, i);
            // (no closure around lane code: see `crate::math::simd`)
            let lanes = if self.ends_frame && (first..first + n).any(clustered) {
                let (from, to) = (eight_from(self.from, first), eight_from(self.to, first));
                Some(turn_x8::<L>(from, to).to_lanes())
            } else {
                None
            };
            for i in first..first + n {
                if !clustered(i) {
                    self.spins[i] = Vec3A::from(turn(self.from[i], self.to[i])) * self.inv_dt;
                } else if let Some(lanes) = &lanes {
                    self.spins[i] = lanes[i - first] * self.inv_dt;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn particles_reset_at_rest_are_those_made_at_rest_and_keep_no_more_than_they_need() {
        let rest = |n: usize| -> Vec<Vec3> { (0..n).map(|i| Vec3::splat(i as f32)).collect() };
        // used particles: moved, spun, pinned
        let mut used = Particles::at_rest(&rest(1000));
        used.predict(0.01, Vec3::new(0.0, -9.8, 0.0), 0.5, &[]);
        used.inv_mass[3] = 0.0;
        used.spins[7] = Vec3A::X;
        used.orientations[7] = Quat::from_rotation_x(0.3);
        for n in [1000, 1100, 200] {
            used.reset_at_rest(&rest(n));
            let fresh = Particles::at_rest(&rest(n));
            // (compared as their serialised form: every field, bit for bit)
            assert_eq!(
                serde_json::to_string(&used).unwrap(),
                serde_json::to_string(&fresh).unwrap(),
                "{n}"
            );
            assert!(used.positions.capacity() <= n + n / 4, "{n}");
            assert!(used.spins.capacity() <= n + n / 4, "{n}");
        }
    }

    #[test]
    fn a_nan_particle_is_put_back_with_zero_velocity() {
        let rest: Vec<Vec3> = (0..10).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let mut p = Particles::at_rest(&rest);
        let live = vec![true; 10];
        assert!(p.repair_non_finite(&live, |_, _| Vec3A::ZERO).is_empty());
        // particle 3 NaN with a finite start; particle 7 NaN from the start too
        p.positions[3] = Vec3A::NAN;
        p.velocities[3] = Vec3A::NAN;
        p.positions[7] = Vec3A::new(f32::INFINITY, 0.0, 0.0);
        p.previous[7] = Vec3A::NAN;
        let repaired = p.repair_non_finite(&live, |d, x| (x[d - 1] + x[d + 1]) * 0.5);
        assert_eq!(repaired, vec![3, 7]);
        assert_eq!(p.positions[3], Vec3A::new(3.0, 0.0, 0.0));
        assert_eq!(p.velocities[3], Vec3A::ZERO);
        assert_eq!(p.positions[7], Vec3A::new(7.0, 0.0, 0.0));
        // a dead particle's slot is left alone
        p.positions[5] = Vec3A::NAN;
        let mut dead = live.clone();
        dead[5] = false;
        assert!(p.repair_non_finite(&dead, |_, _| Vec3A::ZERO).is_empty());
    }

    #[test]
    fn prediction_holds_particles_of_inverse_mass_zero_at_their_velocity() {
        let mut p = Particles::at_rest(&[Vec3::ZERO, Vec3::X]);
        p.velocities[1] = Vec3A::new(0.0, 0.0, 2.0);
        p.inv_mass[1] = 0.0;
        p.predict(0.5, Vec3::new(0.0, -10.0, 0.0), 0.0, &[]);
        assert_eq!(p.positions[0], Vec3A::new(0.0, -2.5, 0.0));
        assert_eq!(p.positions[1], Vec3A::new(1.0, 0.0, 1.0));
        assert_eq!(p.previous[1], Vec3A::X);
    }

    #[test]
    fn a_free_spin_is_kept_through_prediction_and_velocity_update() {
        let mut p = Particles::at_rest(&[Vec3::ZERO]);
        let spin = Vec3A::new(0.0, 2.0 * std::f32::consts::TAU, 1.0);
        p.spins[0] = spin;
        let dt = 1.0 / 120.0;
        for _ in 0..240 {
            p.predict(dt, Vec3::ZERO, 0.0, &[]);
            p.corrections[0] = Vec3A::ZERO;
            p.update_velocities(1.0 / dt, &[], false);
        }
        assert!(
            (p.spins[0] - spin).length() < 1e-3 * spin.length(),
            "{}",
            p.spins[0]
        );
        // two seconds at (0, 2 rev/s, 1 rad/s): the exact turn, up to rounding
        let exact = Quat::from_scaled_axis(Vec3::from(spin) * 2.0);
        assert!(p.orientations[0].dot(exact).abs() > 1.0 - 1e-5);
    }

    #[test]
    fn a_clustered_particle_is_spun_at_the_frame_end_and_a_free_one_every_substep() {
        // 19 particles (two full lane groups and a partial one), every third in no cluster
        let n = 19;
        let mut p = Particles::at_rest(&vec![Vec3::ZERO; n]);
        let counts: Vec<u32> = (0..n as u32).map(|d| (d % 3 != 0) as u32 * 2).collect();
        for d in 0..n {
            p.previous_orientations[d] = Quat::from_rotation_x(0.1 * d as f32);
            p.orientations[d] =
                Quat::from_rotation_y(0.01 * d as f32 + 0.02) * p.previous_orientations[d];
        }
        let (inv_dt, unset) = (50.0, Vec3A::splat(7.0));
        let exact = |p: &Particles, d: usize| {
            Vec3A::from(turn(p.previous_orientations[d], p.orientations[d])) * inv_dt
        };
        p.spins.fill(unset);
        p.update_velocities(inv_dt, &counts, false);
        for (d, &count) in counts.iter().enumerate() {
            if count == 0 {
                assert_eq!(p.spins[d], exact(&p, d), "{d}: the libm turn, bit for bit");
            } else {
                assert_eq!(p.spins[d], unset, "{d}: not before the frame's end");
            }
        }
        p.update_velocities(inv_dt, &counts, true);
        for d in 0..n {
            let expected = Vec3A::new(0.0, 0.01 * d as f32 + 0.02, 0.0) * inv_dt;
            assert!(
                (p.spins[d] - expected).length() < 1e-4,
                "{d}: {} vs {expected}",
                p.spins[d]
            );
            assert!((p.spins[d] - exact(&p, d)).length() < 1e-5 * inv_dt, "{d}");
        }
    }
}
