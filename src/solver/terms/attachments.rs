//! Attachments: particles held to targets that move with a pose. Each attachment names
//! its particles (by [`ParticleKey`]) with their targets in the pose's frame; over a
//! frame the pose moves from where the frame starts to where it ends (set by a path, a
//! velocity, or user code), and each substep places the targets at its end.
//!
//! Each attached particle is held by its own zero-length spring of compliance `α`
//! (m/N): the constraint `C = x − t`, energy `|x − t|²/(2α)`, projected XPBD-style with
//! its `λ` accumulated over the substep. A hard attachment (`α = 0`) makes its particles
//! kinematic: the solver gives them inverse mass 0 and the attachment puts them on their
//! targets before the iterations, so nothing else moves them — which is what pinning a
//! particle means. A hard attachment that moves at a constant velocity (a moving pin)
//! moves each of its particles from where the substep starts by that velocity: exactly
//! as a particle of that velocity moves, with no rounding of a pose in between. In projective dynamics a soft attachment's springs are in the global
//! matrix (`w = 1/α` on the particle's diagonal, its target the projection).

use crate::cut::tool::Pose;
use crate::solver::term::{
    NO_DENSE, ParticleKey, ParticleState, ProjectiveTerm, Substep, Term, Topology, Unknowns,
};
use glam::{DVec3, Vec3, Vec3A};

/// One attachment as the solver takes it.
#[derive(Clone, Debug, PartialEq)]
pub struct Attachment {
    /// The attached particles.
    pub particles: Vec<ParticleKey>,
    /// Each particle's target in the pose's frame.
    pub offsets: Vec<Vec3>,
    /// Compliance of each particle's spring, m/N; 0: hard.
    pub compliance: f32,
    /// The pose at the frame's start.
    pub from: Pose,
    /// The pose at the frame's end.
    pub to: Pose,
    /// The constant velocity the targets move at, when that is what moves them (a
    /// moving pin).
    pub velocity: Option<Vec3>,
}

impl Attachment {
    /// The pose `fraction` of the way through the frame.
    fn pose_at(&self, fraction: f32) -> Pose {
        self.from.lerp(&self.to, fraction)
    }
}

/// One attached particle that is in the layout.
#[derive(Clone, Copy, Debug)]
struct Held {
    /// Its dense index.
    dense: u32,
    /// Its attachment.
    attachment: u32,
    /// Its target in the pose's frame.
    offset: Vec3A,
}

/// The attachment term; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Attachments {
    list: Vec<Attachment>,
    /// The particles of hard attachments, and of soft ones, that are in the layout.
    hard: Vec<Held>,
    soft: Vec<Held>,
    /// The hard ones' dense indices (the kinematic particles).
    kinematic: Vec<u32>,
    /// This substep's target and accumulated `λ` of each soft particle.
    targets: Vec<Vec3A>,
    lambda: Vec<Vec3A>,
    /// Changes with the soft springs (for projective dynamics' matrix).
    version: u64,
}

impl Attachments {
    /// Replaces the attachments by `list` and finds their particles in `topology`.
    pub fn set(&mut self, list: Vec<Attachment>, topology: &Topology) {
        self.list = list;
        self.resolve(topology);
    }

    /// Replaces the attachments; their particles are found at the next topology change
    /// ([`Term::topology`]).
    pub fn replace(&mut self, list: Vec<Attachment>) {
        self.list = list;
    }

    /// Moves attachment `i` from pose `from` (the frame's start) to `to` (its end).
    pub fn set_poses(&mut self, i: usize, from: Pose, to: Pose) {
        if let Some(a) = self.list.get_mut(i) {
            a.from = from;
            a.to = to;
        }
    }

    /// Number of attached particles in the layout.
    pub fn len(&self) -> usize {
        self.hard.len() + self.soft.len()
    }

    /// Whether no particle is attached.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Finds every attached particle's dense index.
    fn resolve(&mut self, topology: &Topology) {
        self.hard.clear();
        self.soft.clear();
        for (a, attachment) in self.list.iter().enumerate() {
            let held = attachment
                .particles
                .iter()
                .zip(&attachment.offsets)
                .filter_map(|(key, offset)| {
                    let dense = topology.dense(*key)?;
                    Some(Held {
                        dense,
                        attachment: a as u32,
                        offset: Vec3A::from(*offset),
                    })
                });
            if attachment.compliance > 0.0 {
                self.soft.extend(held);
            } else {
                self.hard.extend(held);
            }
        }
        self.kinematic = self.hard.iter().map(|h| h.dense).collect();
        self.targets = vec![Vec3A::ZERO; self.soft.len()];
        self.lambda = vec![Vec3A::ZERO; self.soft.len()];
        self.version += 1;
    }

    /// The targets of `held` particles at the end of `step`.
    fn targets_of<'a>(
        &'a self,
        held: &'a [Held],
        step: &Substep,
    ) -> impl Iterator<Item = Vec3A> + 'a {
        let poses: Vec<Pose> = self
            .list
            .iter()
            .map(|a| a.pose_at(step.frame_span[1]))
            .collect();
        held.iter().map(move |h| {
            let pose = poses[h.attachment as usize];
            Vec3A::from(pose.position) + Vec3A::from(pose.rotation * Vec3::from(h.offset))
        })
    }
}

impl Term for Attachments {
    fn name(&self) -> &'static str {
        "attachments"
    }

    fn is_empty(&self) -> bool {
        Attachments::is_empty(self)
    }

    fn kinematic(&self) -> &[u32] {
        &self.kinematic
    }

    fn topology(&mut self, change: &Topology) {
        self.resolve(change);
    }

    /// Puts the hard attachments' particles on their targets; places the soft ones'
    /// targets and clears their `λ`.
    fn begin_substep(&mut self, step: &Substep, state: &mut ParticleState) {
        let hard: Vec<Vec3A> = self.targets_of(&self.hard, step).collect();
        for (h, target) in self.hard.iter().zip(hard) {
            let d = h.dense as usize;
            let target = match self.list[h.attachment as usize].velocity {
                Some(v) => state.previous[d] + Vec3A::from(v) * step.dt,
                None => target,
            };
            state.shift(d, target - state.positions[d]);
        }
        let soft: Vec<Vec3A> = self.targets_of(&self.soft, step).collect();
        self.targets = soft;
        self.lambda.iter_mut().for_each(|l| *l = Vec3A::ZERO);
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        let list = &self.list;
        for ((h, target), lambda) in self.soft.iter().zip(&self.targets).zip(&mut self.lambda) {
            let d = h.dense as usize;
            let w = state.inv_mass[d];
            if w == 0.0 {
                continue;
            }
            let alpha = step.scaled(list[h.attachment as usize].compliance);
            let c = state.positions[d] - *target;
            let delta = (-c - *lambda * alpha) / (w + alpha);
            *lambda += delta;
            state.shift(d, delta * w);
        }
    }

    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        Some(self)
    }
}

impl ProjectiveTerm for Attachments {
    fn version(&self) -> u64 {
        self.version
    }

    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    ) {
        for h in &self.soft {
            if let Some(row) = unknowns.row(h.dense) {
                let compliance = self.list[h.attachment as usize].compliance;
                let w = unknowns.weight(compliance, &[h.dense], step.dt);
                entries.push((row, row, w));
            }
        }
    }

    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        _orientations: &mut [glam::Quat],
        forces: &mut [DVec3],
    ) {
        for (h, target) in self.soft.iter().zip(&self.targets) {
            if h.dense == NO_DENSE || unknowns.row(h.dense).is_none() {
                continue;
            }
            let compliance = self.list[h.attachment as usize].compliance;
            let w = unknowns.weight(compliance, &[h.dense], step.dt);
            let d = h.dense as usize;
            forces[d] += (*target - positions[d]).as_dvec3() * w;
        }
    }
}
