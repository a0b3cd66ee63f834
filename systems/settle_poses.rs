//! Stage settle (the frame's last): the poses this frame moved every kinematic thing
//! to — tools, colliders, attachment targets — become where the next frame moves them
//! from. Game code may then write a new pose between frames (or a path gives one), and
//! the next frame sweeps from here to there, so a tool or collider moved by game code is
//! tested along its whole motion, at any speed, like a keyframed one. Writes poses only.

use crate::ecs::components::{AttachmentTarget, ColliderPose, ToolPose};
use bevy_ecs::entity_disabling::Disabled;
use bevy_ecs::prelude::*;
use bevy_ecs::query::Allow;

/// Records where each tool, collider and attachment target ended the frame (a disabled
/// tool's too: enabled again, it sweeps from where it is then, not from where it was
/// disabled).
pub fn settle_poses(
    mut tools: Query<&mut ToolPose, Allow<Disabled>>,
    mut colliders: Query<&mut ColliderPose>,
    mut targets: Query<&mut AttachmentTarget>,
) {
    for mut pose in &mut tools {
        pose.last = pose.current;
    }
    for mut pose in &mut colliders {
        pose.last = pose.current;
    }
    for mut target in &mut targets {
        target.reached = target.pose;
    }
}
