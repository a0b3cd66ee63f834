//! Advances keyframed colliders before the substeps: the pose at the end of the last
//! frame becomes this frame's start, the path gives its end. Colliders without a path
//! keep whatever game code wrote (and the start follows). Writes collider data only.

use crate::ecs::components::{ColliderPath, ColliderPose};
use crate::ecs::resources::{SimClock, SimSettings};
use bevy_ecs::prelude::*;

/// Updates every collider pose for the frame about to be simulated.
pub fn move_colliders(
    clock: Res<SimClock>,
    settings: Res<SimSettings>,
    mut colliders: Query<(&mut ColliderPose, Option<&ColliderPath>)>,
) {
    let end = clock.time + settings.0.dt as f64;
    for (mut pose, path) in &mut colliders {
        let now = pose.current;
        pose.last = now;
        if let Some(p) = path.and_then(|p| p.0.sample(end as f32)) {
            pose.current = p;
        }
    }
}
