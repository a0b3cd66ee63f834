//! Advances keyframed tools: the path gives the pose at the frame's end. A tool without
//! a path keeps whatever game code wrote; either way detection sweeps it from where the
//! last frame left it ([`super::settle_poses`]).

use crate::ecs::components::{ToolPath, ToolPose};
use crate::ecs::resources::SimClock;
use bevy_ecs::entity_disabling::Disabled;
use bevy_ecs::prelude::*;
use bevy_ecs::query::Allow;

/// Updates every keyframed tool's pose for this frame (a disabled one's too, so that it
/// is where its path says when enabled again). Writes tool data only.
pub fn move_tools(
    clock: Res<SimClock>,
    mut tools: Query<(&mut ToolPose, &ToolPath), Allow<Disabled>>,
) {
    for (mut pose, path) in &mut tools {
        if let Some(p) = path.0.sample(clock.time as f32) {
            pose.current = p;
        }
    }
}
