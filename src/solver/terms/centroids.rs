//! Centroid holds (SPEC §6.1, Yuksel et al. 2012): a set of particles whose centroid is
//! held to a target while the set itself deforms freely. One vector constraint per set,
//! `C = (1/n) Σ xᵢ − t`, with `t` the centroid of the particles' places in the target's
//! pose — the pose the attachments' targets move with — so `t` follows a keyframed path
//! or game code, and after a cut it is the centroid of the places of the particles that
//! are left.
//!
//! Projected XPBD-style with compliance `α` (m/N; 0: hard) and `λ` accumulated over
//! the substep: `∇ₓᵢC = 1/n`, so `Δλ = (−C − α̃λ)/(Σ wᵢ/n² + α̃)` and `Δxᵢ = wᵢ Δλ / n`.
//! The correction moves every member alike (weighted by inverse mass): the set's shape
//! is left to the other terms. No projective-dynamics form (its block would couple every
//! pair of members): projective dynamics projects the holds after its global step.

use super::attachments::Attachment;
use crate::cut::tool::Pose;
use crate::solver::term::{ParticleState, Substep, Term, Topology};
use glam::{Vec3, Vec3A};

/// A hold's particles in the layout, and the centroid of their places.
#[derive(Clone, Debug, Default)]
struct Resolved {
    dense: Vec<u32>,
    /// Mean of the present particles' offsets (in the pose's frame).
    offset: Vec3,
}

/// The centroid-hold term; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Centroids {
    /// The holds, in the attachments' form: the centroid's target is the centroid of
    /// the particles' places, `compliance` the centroid's spring (a velocity, which
    /// only pins have, plays no part).
    list: Vec<Attachment>,
    resolved: Vec<Resolved>,
    /// This substep's target and accumulated `λ` of each hold.
    targets: Vec<Vec3A>,
    lambda: Vec<Vec3A>,
}

impl Centroids {
    /// Replaces the holds by `list` and finds their particles in `topology`.
    pub fn set(&mut self, list: Vec<Attachment>, topology: &Topology) {
        self.list = list;
        self.resolve(topology);
    }

    /// Replaces the holds; their particles are found at the next topology change
    /// ([`Term::topology`]).
    pub fn replace(&mut self, list: Vec<Attachment>) {
        self.list = list;
    }

    /// Moves hold `i` from pose `from` (the frame's start) to `to` (its end).
    pub fn set_poses(&mut self, i: usize, from: Pose, to: Pose) {
        if let Some(c) = self.list.get_mut(i) {
            c.from = from;
            c.to = to;
        }
    }

    fn resolve(&mut self, topology: &Topology) {
        self.resolved = self
            .list
            .iter()
            .map(|c| {
                let (mut dense, mut sum) = (Vec::new(), Vec3::ZERO);
                for (key, offset) in c.particles.iter().zip(&c.offsets) {
                    if let Some(d) = topology.dense(*key) {
                        dense.push(d);
                        sum += *offset;
                    }
                }
                let offset = sum / dense.len().max(1) as f32;
                Resolved { dense, offset }
            })
            .collect();
        self.targets = vec![Vec3A::ZERO; self.list.len()];
        self.lambda = vec![Vec3A::ZERO; self.list.len()];
    }
}

impl Term for Centroids {
    fn name(&self) -> &'static str {
        "centroids"
    }

    fn is_empty(&self) -> bool {
        self.resolved.iter().all(|r| r.dense.is_empty())
    }

    fn topology(&mut self, change: &Topology) {
        self.resolve(change);
    }

    /// Places each hold's target where its pose is at the end of the substep, and
    /// clears the `λ`s.
    fn begin_substep(&mut self, step: &Substep, _state: &mut ParticleState) {
        for ((c, r), target) in self.list.iter().zip(&self.resolved).zip(&mut self.targets) {
            let pose = c.from.lerp(&c.to, step.frame_span[1]);
            *target = Vec3A::from(pose.position + pose.rotation * r.offset);
        }
        self.lambda.iter_mut().for_each(|l| *l = Vec3A::ZERO);
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        for (((c, r), target), lambda) in self
            .list
            .iter()
            .zip(&self.resolved)
            .zip(&self.targets)
            .zip(&mut self.lambda)
        {
            let n = r.dense.len() as f32;
            let weights: f32 = r.dense.iter().map(|&d| state.inv_mass[d as usize]).sum();
            if weights == 0.0 {
                continue;
            }
            let centroid = r
                .dense
                .iter()
                .map(|&d| state.positions[d as usize])
                .sum::<Vec3A>()
                / n;
            let alpha = step.scaled(c.compliance);
            let delta = (*target - centroid - *lambda * alpha) / (weights / (n * n) + alpha);
            *lambda += delta;
            for &d in &r.dense {
                let w = state.inv_mass[d as usize];
                state.shift(d as usize, delta * (w / n));
            }
        }
    }
}
