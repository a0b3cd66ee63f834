//! Moving kinematic things from game code: the pose a tool, a collider or an attachment
//! target is to reach at the end of the next frame. The frame moves each from where the
//! last frame left it to that pose — tools are tested against all they sweep, colliders
//! move through the substeps — so a pose set from code acts at any speed as a keyframed
//! path does. Something a path (or a velocity) drives refuses a pose from code: say which
//! one moves it by removing the other.

use crate::cut::tool::Pose;
use crate::ecs::components::*;
use crate::ecs::spawn::checked_pose;
use crate::error::{CleaveError, Result};
use bevy_ecs::component::Mutable;
use bevy_ecs::prelude::*;

/// Sets where `tool` is at the end of the next frame.
pub fn set_tool_pose(world: &mut World, tool: Entity, pose: Pose) -> Result<()> {
    set_current::<ToolPose, ToolPath>(world, tool, "tool", pose, |at| &mut at.current)
}

/// Sets where `collider` is at the end of the next frame.
pub fn set_collider_pose(world: &mut World, collider: Entity, pose: Pose) -> Result<()> {
    set_current::<ColliderPose, ColliderPath>(world, collider, "collider", pose, |at| {
        &mut at.current
    })
}

/// Writes the checked `pose` into the pose `P` of `entity`, a `what` no path `D` drives.
fn set_current<P: Component<Mutability = Mutable>, D: Component>(
    world: &mut World,
    entity: Entity,
    what: &str,
    pose: Pose,
    current: impl FnOnce(&mut P) -> &mut Pose,
) -> Result<()> {
    let pose = checked_pose(&format!("{what} pose"), pose)?;
    let entity = kinematic::<P, D>(world, entity, what)?;
    if let Some(mut at) = world.get_mut::<P>(entity) {
        *current(&mut at) = pose;
    }
    Ok(())
}

/// Sets where `attachment`'s target is at the end of the next frame.
pub fn set_attachment_pose(world: &mut World, attachment: Entity, pose: Pose) -> Result<()> {
    if world.get::<AttachmentVelocity>(attachment).is_some() {
        return Err(CleaveError::InvalidEntity(format!(
            "attachment {attachment} moves with a velocity; remove its AttachmentVelocity to move it from code"
        )));
    }
    set_current::<AttachmentTarget, AttachmentPath>(world, attachment, "attachment", pose, |t| {
        &mut t.pose
    })
}

/// `entity`, if it is a live `what` (it has `P`) that no path (`D`) drives.
fn kinematic<P: Component, D: Component>(
    world: &World,
    entity: Entity,
    what: &str,
) -> Result<Entity> {
    let e = world
        .get_entity(entity)
        .ok()
        .filter(|e| e.contains::<P>())
        .ok_or_else(|| {
            CleaveError::not_a(
                format_args!("{} {what}", if what.starts_with('a') { "an" } else { "a" }),
                entity,
            )
        })?;
    if e.contains::<D>() {
        return Err(CleaveError::InvalidEntity(format!(
            "{what} {entity} follows a keyframed path; remove the path to move it from code"
        )));
    }
    Ok(entity)
}
