//! Advances attachment targets before the substeps: a keyframed path gives the target's
//! pose at the end of the frame, a velocity moves it on by one frame's worth (a moving
//! pin); a target with neither keeps whatever game code wrote. Writes attachment targets
//! only.

use crate::ecs::components::{AttachmentPath, AttachmentTarget, AttachmentVelocity};
use crate::ecs::resources::{SimClock, SimSettings};
use bevy_ecs::prelude::*;

/// Updates every attachment target for the frame about to be simulated.
pub fn move_attachments(
    clock: Res<SimClock>,
    settings: Res<SimSettings>,
    mut targets: Query<(
        &mut AttachmentTarget,
        Option<&AttachmentPath>,
        Option<&AttachmentVelocity>,
    )>,
) {
    let dt = settings.0.dt;
    let end = clock.time + dt as f64;
    for (mut target, path, velocity) in &mut targets {
        if let Some(pose) = path.and_then(|p| p.0.sample(end as f32)) {
            target.pose = pose;
        } else if let Some(v) = velocity {
            target.pose.position += v.0 * dt;
        }
    }
}
