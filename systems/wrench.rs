//! Stage wrench: what the particles did to each collider over the frame — the impulses
//! the colliders term summed per collider ([`Colliders::frame_impulses`]) over the
//! frame's length — into its [`ColliderWrench`], and a [`ColliderPushed`] message for
//! each collider touched. Writes collider data only.

use crate::ecs::components::ColliderWrench;
use crate::ecs::resources::{ColliderPushed, SimSettings, SolverCache};
use crate::solver::terms::colliders::Colliders;
use bevy_ecs::prelude::*;
use glam::Vec3;

/// Sets every collider's wrench to the frame's mean (zero where nothing touched it).
pub fn collider_wrenches(
    settings: Res<SimSettings>,
    cache: Res<SolverCache>,
    mut colliders: Query<(Entity, &mut ColliderWrench)>,
    mut pushed: MessageWriter<ColliderPushed>,
) {
    let impulses = (cache.solver.terms.get::<Colliders>()).map_or(&[][..], |t| t.frame_impulses());
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
