//! The colliders' ECS side: every [`Collider`] entity placed where it is over each
//! substep — kinematic ones between their frame's poses, dynamic ones moved by their
//! own velocities (and by what the particles do to them) — tagged by its entity, for
//! its wrench. A collider whose pose or dynamic state is not usable is left out, or
//! stays kinematic, with one warning until it is usable again.

use crate::config::SimConfig;
use crate::ecs::components::{Collider, ColliderPose, DynamicCollider};
use crate::ecs::ecs_term::EcsSubstepTerm;
use crate::ecs::resources::{SimSettings, SubstepClock};
use crate::ecs::spawn::checked_pose;
use crate::error::CleaveError;
use crate::solver::terms::colliders::{Colliders, PosedCollider};
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParamItem;

/// How fast (m/s) a particle that began a substep inside a collider is pushed out of
/// it (see [`Colliders::depenetration_step`]): a body spawned in a collider comes out at
/// a walk, not shot out.
pub const MAX_DEPENETRATION_SPEED: f32 = 2.0;

/// The collider entities as the term reads them.
type ColliderItem = (
    Entity,
    &'static Collider,
    &'static ColliderPose,
    Option<&'static DynamicCollider>,
);

impl EcsSubstepTerm for Colliders {
    type SubstepData = (
        Res<'static, SimSettings>,
        Res<'static, SubstepClock>,
        Query<'static, 'static, ColliderItem>,
        Local<'static, Vec<Entity>>,
    );

    /// Places every collider for this substep (the frame's first substep starts the
    /// frame's sums of what the particles did to them).
    fn substep(
        &mut self,
        (settings, substep, colliders, mut refused): SystemParamItem<Self::SubstepData>,
    ) {
        let placed = substep_colliders(&settings.0, &substep, &colliders, &mut refused);
        self.place(placed, substep.index == 0);
    }
}

/// The ground, the config's static boxes and every collider entity, placed for this
/// substep (a kinematic collider moves from its frame-start pose to its frame-end pose
/// over the substeps; a dynamic one starts the frame where it is, and the term carries
/// it on from substep to substep). Game code may have written anything into the
/// components: a collider whose pose is out of bounds is left out, a dynamic one whose
/// state is out of bounds is kinematic, each with a warning the first time (`refused`
/// lists them).
fn substep_colliders(
    config: &SimConfig,
    substep: &SubstepClock,
    entities: &Query<ColliderItem>,
    refused: &mut Vec<Entity>,
) -> Colliders {
    let dt = config.dt / config.substeps as f32;
    let count = substep.count.max(1) as f32;
    let (t0, t1) = (
        substep.index as f32 / count,
        (substep.index + 1) as f32 / count,
    );
    let mut refuse = |e: Entity, error: Option<(CleaveError, &str)>| match error {
        Some((error, so)) if !refused.contains(&e) => {
            tracing::warn!("cleave: collider {e} {so}: {error}");
            refused.push(e);
        }
        Some(_) => {}
        None => refused.retain(|r| *r != e),
    };
    let moving = entities.iter().filter_map(|(e, c, pose, dynamic)| {
        let posed = checked_pose("collider.pose.current", pose.current)
            .and_then(|_| checked_pose("collider.pose.last", pose.last));
        if let Err(error) = posed {
            refuse(e, Some((error, "left out")));
            return None;
        }
        // (tagged by its entity, for its wrench: see `systems::wrench`)
        let shape = c.shape.clone();
        match dynamic.map(|d| d.check().map(|()| d.motion())) {
            Some(Ok(motion)) => {
                refuse(e, None);
                let posed = PosedCollider::dynamic(
                    shape,
                    c.friction,
                    pose.current,
                    motion,
                    config.gravity,
                    dt,
                );
                return Some(posed.tagged(e.to_bits()));
            }
            Some(Err(error)) => refuse(e, Some((error, "stays kinematic"))),
            None => refuse(e, None),
        }
        let (start, end) = (
            pose.last.lerp(&pose.current, t0),
            pose.last.lerp(&pose.current, t1),
        );
        Some(PosedCollider::new(shape, c.friction, start, end).tagged(e.to_bits()))
    });
    let mut colliders = Colliders::from_config(config, moving);
    colliders.depenetration_step = MAX_DEPENETRATION_SPEED * config.dt / count;
    colliders
}
