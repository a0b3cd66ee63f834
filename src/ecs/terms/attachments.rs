//! The attachments' ECS side: each [`Attachment`] entity, with its target's poses, taken
//! by the [`Attachments`] term (particles held each to its own target) or the
//! [`Centroids`] term (only a set's centroid held), by its [`Hold`].

use crate::cut::tool::Pose;
use crate::ecs::components::{Attachment, AttachmentTarget, AttachmentVelocity, Hold};
use crate::ecs::ecs_term::EcsTerm;
use crate::solver::term::ParticleKey;
use crate::solver::terms::attachments::{self, Attachments};
use crate::solver::terms::centroids::Centroids;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParamItem;

/// An attachment entity as the terms read it.
type AttachmentItem<'a> = (
    Entity,
    &'a Attachment,
    &'a AttachmentTarget,
    Option<&'a AttachmentVelocity>,
);

/// What both terms read: every attachment, and whether any changed or went.
type AttachmentData = (
    Query<'static, 'static, AttachmentItem<'static>>,
    Query<'static, 'static, (), Changed<Attachment>>,
    RemovedComponents<'static, 'static, Attachment>,
);

/// What a term of attachments takes this frame: the attachments held by their
/// particles each (`each`) or by their centroid, in entity order — all of them, as the
/// term takes them, when any attachment changed or went since the last call — and
/// where each one's target goes over the frame.
struct Held {
    changed: Option<Vec<attachments::Attachment>>,
    poses: Vec<(Pose, Pose)>,
}

impl Held {
    fn read(
        (attachments, changed, mut removed): SystemParamItem<AttachmentData>,
        each: bool,
    ) -> Self {
        let changed = !changed.is_empty() || removed.read().count() > 0;
        let mut list: Vec<AttachmentItem> = attachments
            .iter()
            .filter(|(_, a, ..)| (a.hold == Hold::Each) == each)
            .collect();
        list.sort_unstable_by_key(|(e, ..)| *e);
        Held {
            changed: changed.then(|| list.iter().map(as_term).collect()),
            poses: list
                .iter()
                .map(|(_, _, t, _)| (t.reached, t.pose))
                .collect(),
        }
    }

    /// Gives `term` the attachments (by `replace`, when they changed) and their targets'
    /// poses (by `set_poses`); whether they changed.
    fn give<T>(
        self,
        term: &mut T,
        replace: fn(&mut T, Vec<attachments::Attachment>),
        set_poses: fn(&mut T, usize, Pose, Pose),
    ) -> bool {
        let changed = self.changed.map(|list| replace(term, list)).is_some();
        for (i, (from, to)) in self.poses.into_iter().enumerate() {
            set_poses(term, i, from, to);
        }
        changed
    }
}

impl EcsTerm for Attachments {
    type Data = AttachmentData;

    /// Takes the attachments again when any changed; moves their targets every frame.
    fn sync(&mut self, data: SystemParamItem<Self::Data>) -> bool {
        Held::read(data, true).give(self, Attachments::replace, Attachments::set_poses)
    }
}

impl EcsTerm for Centroids {
    type Data = AttachmentData;

    /// Takes the centroid holds again when any attachment changed; moves their targets
    /// every frame.
    fn sync(&mut self, data: SystemParamItem<Self::Data>) -> bool {
        Held::read(data, false).give(self, Centroids::replace, Centroids::set_poses)
    }
}

/// An attachment entity as its term takes it.
fn as_term((_, a, target, velocity): &AttachmentItem) -> attachments::Attachment {
    attachments::Attachment {
        particles: a
            .particles
            .iter()
            .map(|&local| ParticleKey {
                body: a.body.to_bits(),
                local,
            })
            .collect(),
        offsets: a.offsets.clone(),
        compliance: a.compliance,
        from: target.reached,
        to: target.pose,
        velocity: velocity.map(|v| v.0),
    }
}
