//! Advances keyframed tools: the last pose becomes the previous one, the path gives the
//! new one. Tools without a path keep whatever game code wrote (and the last pose follows).

use crate::ecs::components::{ToolPath, ToolPose};
use crate::ecs::resources::SimClock;
use bevy_ecs::prelude::*;

/// Updates every tool pose for this frame. Writes tool data only.
pub fn move_tools(clock: Res<SimClock>, mut tools: Query<(&mut ToolPose, Option<&ToolPath>)>) {
    for (mut pose, path) in &mut tools {
        let now = pose.current;
        pose.last = now;
        if let Some(p) = path.and_then(|p| p.0.sample(clock.time as f32)) {
            pose.current = p;
        }
    }
}
