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
use bevy_ecs::prelude::*;

/// Sets where `tool` is at the end of the next frame.
pub fn set_tool_pose(world: &mut World, tool: Entity, pose: Pose) -> Result<()> {
    let pose = checked_pose("tool pose", pose)?;
    let entity = kinematic::<ToolPose, ToolPath>(world, tool, "tool")?;
    if let Some(mut at) = world.get_mut::<ToolPose>(entity) {
        at.current = pose;
    }
    Ok(())
}

/// Sets where `collider` is at the end of the next frame.
pub fn set_collider_pose(world: &mut World, collider: Entity, pose: Pose) -> Result<()> {
    let pose = checked_pose("collider pose", pose)?;
    let entity = kinematic::<ColliderPose, ColliderPath>(world, collider, "collider")?;
    if let Some(mut at) = world.get_mut::<ColliderPose>(entity) {
        at.current = pose;
    }
    Ok(())
}

/// Sets where `attachment`'s target is at the end of the next frame.
pub fn set_attachment_pose(world: &mut World, attachment: Entity, pose: Pose) -> Result<()> {
    let pose = checked_pose("attachment pose", pose)?;
    let entity = kinematic::<AttachmentTarget, AttachmentPath>(world, attachment, "attachment")?;
    if world.get::<AttachmentVelocity>(entity).is_some() {
        return Err(CleaveError::InvalidEntity(format!(
            "attachment {entity} moves with a velocity; remove its AttachmentVelocity to move it from code"
        )));
    }
    if let Some(mut target) = world.get_mut::<AttachmentTarget>(entity) {
        target.pose = pose;
    }
    Ok(())
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
