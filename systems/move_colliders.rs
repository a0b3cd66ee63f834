//! Advances keyframed colliders before the substeps: the path gives the pose at the end
//! of the frame. Colliders without a path keep whatever game code wrote; either way the
//! substeps move them from where the last frame left them ([`super::settle_poses`]).
//! Writes collider data only.

use crate::ecs::components::{ColliderPath, ColliderPose};
use crate::ecs::resources::{SimClock, SimSettings};
use bevy_ecs::prelude::*;

/// Updates every keyframed collider's pose for the frame about to be simulated.
pub fn move_colliders(
    clock: Res<SimClock>,
    settings: Res<SimSettings>,
    mut colliders: Query<(&mut ColliderPose, &ColliderPath)>,
) {
    let end = clock.time + settings.0.dt as f64;
    for (mut pose, path) in &mut colliders {
        if let Some(p) = path.0.sample(end as f32) {
            pose.current = p;
        }
    }
}
