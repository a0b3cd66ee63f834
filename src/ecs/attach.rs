//! Attachments as entities: spawned from a body's description (its `attachments` and
//! its `pins`) or by game code ([`attach`]), each an [`Attachment`] with its
//! [`AttachmentTarget`] and what moves the target (an [`AttachmentPath`], an
//! [`AttachmentVelocity`], or nothing: game code).

use crate::config::ranges;
use crate::cut::tool::{Path, Pose};
use crate::ecs::components::*;
use crate::error::{CleaveError, Result};
use bevy_ecs::prelude::*;
use glam::Vec3;

/// What moves an attachment's target.
#[derive(Clone, Debug, PartialEq)]
pub enum TargetMotion {
    /// Nothing: it stays until game code moves it.
    Still,
    /// A keyframed path (its poses move the target; checked by the caller).
    Path(Path),
    /// A constant velocity, m/s.
    Velocity(Vec3),
}

/// Checks an attachment's compliance ([`ranges::ATTACHMENT_COMPLIANCE`]); the error
/// names `{field}.compliance`.
pub fn check_compliance(field: &str, compliance: f32) -> Result<()> {
    ranges::ATTACHMENT_COMPLIANCE.check(&format!("{field}.compliance"), compliance)
}

/// Makes `e` (a new entity: `world.spawn_empty()`) an attachment of `body`'s particles
/// `particles` (body-local), which are at the world positions `positions` now, each
/// (or, by `hold`, only their centroid) held by a spring of `compliance` to its place
/// relative to the target `pose`, which `motion` moves.
#[allow(clippy::too_many_arguments)]
pub fn spawn_attachment(
    mut e: EntityWorldMut,
    body: Entity,
    particles: Vec<u32>,
    positions: &[Vec3],
    compliance: f32,
    hold: Hold,
    pose: Pose,
    motion: TargetMotion,
) -> Entity {
    let inverse = pose.rotation.inverse();
    let offsets = positions
        .iter()
        .map(|x| inverse * (*x - pose.position))
        .collect();
    e.insert((
        Attachment {
            body,
            particles,
            offsets,
            compliance,
            hold,
        },
        AttachmentTarget::at(pose),
    ));
    match motion {
        TargetMotion::Still => {}
        TargetMotion::Path(path) => {
            e.insert(AttachmentPath(path));
        }
        TargetMotion::Velocity(v) => {
            e.insert(AttachmentVelocity(v));
        }
    }
    e.id()
}

/// The pose at the centroid of `positions`, unrotated.
pub fn centroid_pose(positions: &[Vec3]) -> Pose {
    let sum: Vec3 = positions.iter().sum();
    Pose::at(sum / positions.len().max(1) as f32)
}

/// Attaches `body`'s live particles `particles` (body-local) where they are now, each
/// (or, by `hold`, only their centroid) by a spring of `compliance` (m/N; 0: hard), to a
/// target at their centroid; returns the attachment. Move it through its
/// [`AttachmentTarget`]; despawn it to let go.
pub fn attach(
    world: &mut World,
    body: Entity,
    particles: &[u32],
    compliance: f32,
    hold: Hold,
) -> Result<Entity> {
    attach_into(world, None, body, particles, compliance, hold)
}

/// [`attach`], making the entity `into` (if given, else a new one) the attachment.
pub(crate) fn attach_into(
    world: &mut World,
    into: Option<Entity>,
    body: Entity,
    particles: &[u32],
    compliance: f32,
    hold: Hold,
) -> Result<Entity> {
    check_compliance("attachment", compliance)?;
    let lattice = world
        .get::<BodyLattice>(body)
        .ok_or_else(|| CleaveError::not_a("a body", body))?;
    if particles.is_empty() {
        return Err(CleaveError::InvalidEntity(
            "an attachment needs at least one particle".into(),
        ));
    }
    let mut positions = Vec::with_capacity(particles.len());
    for &p in particles {
        let position = lattice
            .lattice
            .is_live(p)
            .then(|| lattice.particles[p as usize])
            .and_then(|e| world.get::<Position>(e))
            .ok_or_else(|| {
                CleaveError::InvalidEntity(format!("particle {p} of body {body} is not live"))
            })?;
        positions.push(position.0);
    }
    let pose = centroid_pose(&positions);
    let e = match into {
        Some(e) => world.entity_mut(e),
        None => world.spawn_empty(),
    };
    Ok(spawn_attachment(
        e,
        body,
        particles.to_vec(),
        &positions,
        compliance,
        hold,
        pose,
        TargetMotion::Still,
    ))
}

/// The particles (body-local, ascending, once each) that `body`'s hard attachments hold:
/// its pinned particles.
pub fn pinned_particles(world: &mut World, body: Entity) -> Vec<u32> {
    let mut pinned: Vec<u32> = world
        .query::<&Attachment>()
        .iter(world)
        .filter(|a| a.body == body && a.compliance == 0.0 && a.hold == Hold::Each)
        .flat_map(|a| a.particles.iter().copied())
        .collect();
    pinned.sort_unstable();
    pinned.dedup();
    pinned
}
