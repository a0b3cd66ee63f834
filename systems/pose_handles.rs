//! The pose stage: every body posed by handles ([`crate::ecs::handles::HandlePose`])
//! has its handles' targets moved to the frame's end, its subspace rebuilt if a cut
//! changed it (a particle the cut made resting where it was made), and each of its
//! (kinematic) particles given the velocity that carries it to its posed place by the
//! frame's end. Writes particle velocities and the poses'
//! own data only.

use crate::ecs::components::{BodyLattice, Position, Velocity};
use crate::ecs::handles::{HandlePose, signature};
use crate::ecs::resources::{SimClock, SimSettings};
use bevy_ecs::prelude::*;

/// Moves every posed body's particles toward their pose for the frame's end.
pub fn pose_handles(
    clock: Res<SimClock>,
    settings: Res<SimSettings>,
    mut bodies: Query<(Ref<BodyLattice>, &mut HandlePose)>,
    mut particles: Query<(&Position, &mut Velocity)>,
) {
    let dt = settings.0.dt;
    let end = (clock.time + dt as f64) as f32;
    let memory = settings.0.memory_budget_bytes();
    for (lattice, mut pose) in &mut bodies {
        // a particle a cut made (a split's new half) rests where it was made
        while pose.rest.len() < lattice.lattice.len() {
            let e = lattice.particles[pose.rest.len()];
            let at = particles.get(e).map_or(glam::Vec3::ZERO, |(x, _)| x.0);
            pose.rest.push(at);
        }
        // only an edited lattice can have a new topology: the signature walks the body
        if lattice.is_changed()
            && signature(&lattice.lattice) != pose.topology
            && let Err(e) = pose.rebuild(&lattice.lattice, memory)
        {
            tracing::warn!("a posed body's handles after a cut: {e}; the body stays still");
            continue;
        }
        pose.follow_paths(end);
        let posed = match pose.posed() {
            Ok(posed) => posed,
            Err(e) => {
                tracing::warn!("a posed body's handles: {e}; the body stays still");
                continue;
            }
        };
        for i in lattice.lattice.live_particles() {
            if let Ok((x, mut v)) = particles.get_mut(lattice.particles[i as usize]) {
                v.0 = (posed[i as usize] - x.0) / dt;
            }
        }
    }
}
