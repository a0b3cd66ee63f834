//! Stage wrench: what the particles did to each collider over the frame — the impulses
//! the colliders term summed per collider ([`Colliders::frame_impulses`]) over the
//! frame's length — into its [`ColliderWrench`], and a [`ColliderPushed`] message for
//! each collider touched; a dynamic collider's pose and velocities where the substeps
//! left it ([`Colliders::rigid_bodies`]). Writes collider data only.

use crate::ecs::components::{ColliderPose, ColliderWrench, DynamicCollider};
use crate::ecs::ecs_term::TermOf;
use crate::ecs::resources::{ColliderPushed, SimSettings};
use crate::solver::terms::colliders::Colliders;
use bevy_ecs::prelude::*;
use glam::Vec3;

/// Sets every dynamic collider's pose and velocities to where the solve moved it.
pub fn dynamic_colliders(
    term: TermOf<Colliders>,
    mut colliders: Query<(Entity, &mut ColliderPose, &mut DynamicCollider)>,
) {
    let Some(term) = term.get() else {
        return;
    };
    for (tag, pose, motion) in term.rigid_bodies() {
        let Some(Ok((_, mut at, mut dynamic))) =
            Entity::try_from_bits(tag).map(|e| colliders.get_mut(e))
        else {
            continue;
        };
        at.current = pose;
        dynamic.velocity = motion.velocity.into();
        dynamic.angular_velocity = motion.angular_velocity.into();
    }
}

/// Sets every collider's wrench to the frame's mean (zero where nothing touched it).
pub fn collider_wrenches(
    settings: Res<SimSettings>,
    term: TermOf<Colliders>,
    mut colliders: Query<(Entity, &mut ColliderWrench)>,
    mut pushed: MessageWriter<ColliderPushed>,
) {
    let impulses = term.get().map_or(&[][..], |t| t.frame_impulses());
    let per_second = 1.0 / settings.0.dt;
    for (collider, mut wrench) in &mut colliders {
        let found = impulses.iter().find(|i| i.tag == collider.to_bits());
        let new = found.map_or(ColliderWrench::default(), |i| ColliderWrench {
            force: Vec3::from(i.linear) * per_second,
            torque: Vec3::from(i.angular) * per_second,
        });
        wrench.set_if_neq(new);
        if new != ColliderWrench::default() {
            pushed.write(ColliderPushed {
                collider,
                force: new.force,
                torque: new.torque,
            });
        }
    }
}
