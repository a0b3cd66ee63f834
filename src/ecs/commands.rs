//! Spawning from ordinary systems, through bevy's `Commands`: one [`EntityCommand`] per
//! kind — [`SpawnBody`], [`SpawnTool`], [`SpawnCollider`], [`AttachParticles`] — and
//! [`CleaveCommands`], which reserves the entity and queues the command in one call:
//!
//! ```
//! # use bevy_ecs::prelude::*;
//! # use cleave::prelude::*;
//! use cleave::ecs::commands::CleaveCommands;
//!
//! fn drop_a_block(mut commands: Commands) {
//!     let body = commands.spawn_soft_body(BodyDesc::new(Shape::cuboid(UVec3::splat(4)), 0.1));
//!     // `body` names the block from now on; it is filled when the commands apply
//! }
//! # bevy_ecs::system::assert_is_system(drop_a_block);
//! ```
//!
//! A command applies as the matching `spawn_*` function does, in the order the commands
//! were queued. A description the function refuses is logged (a `tracing` warning naming
//! the field) and the reserved entity is despawned; the app goes on.

use crate::ecs::attach::attach_into;
use crate::ecs::components::Hold;
use crate::ecs::desc::{BodyDesc, ColliderDesc, ToolDesc};
use crate::ecs::spawn::{spawn_collider_into, spawn_tool_into};
use crate::ecs::spawn_body::spawn_body_into;
use crate::error::Result;
use bevy_ecs::prelude::*;
use bevy_ecs::system::EntityCommands;

/// Makes its entity a body (see [`crate::ecs::spawn::spawn_body`]).
#[derive(Clone, Debug)]
pub struct SpawnBody(pub BodyDesc);

/// Makes its entity a cutting tool (see [`crate::ecs::spawn::spawn_tool`]).
#[derive(Clone, Debug)]
pub struct SpawnTool(pub ToolDesc);

/// Makes its entity a collider (see [`crate::ecs::spawn::spawn_collider`]).
#[derive(Clone, Debug)]
pub struct SpawnCollider(pub ColliderDesc);

/// Makes its entity an attachment of `body`'s particles where they are when it applies
/// (see [`crate::ecs::attach::attach`]).
#[derive(Clone, Debug)]
pub struct AttachParticles {
    /// The body.
    pub body: Entity,
    /// Its particles to hold (body-local indices).
    pub particles: Vec<u32>,
    /// The springs' compliance (m/N; 0: hard).
    pub compliance: f32,
    /// Each particle held, or only their centroid.
    pub hold: Hold,
}

impl EntityCommand for SpawnBody {
    type Out = ();
    fn apply(self, entity: EntityWorldMut) {
        fill(entity, "body", |world, e| {
            spawn_body_into(world, Some(e), &self.0)
        });
    }
}

impl EntityCommand for SpawnTool {
    type Out = ();
    fn apply(self, entity: EntityWorldMut) {
        fill(entity, "tool", |world, e| {
            spawn_tool_into(world, Some(e), &self.0)
        });
    }
}

impl EntityCommand for SpawnCollider {
    type Out = ();
    fn apply(self, entity: EntityWorldMut) {
        fill(entity, "collider", |world, e| {
            spawn_collider_into(world, Some(e), &self.0)
        });
    }
}

impl EntityCommand for AttachParticles {
    type Out = ();
    fn apply(self, entity: EntityWorldMut) {
        fill(entity, "attachment", |world, e| {
            let a = &self;
            attach_into(world, Some(e), a.body, &a.particles, a.compliance, a.hold)
        });
    }
}

/// Runs `spawn` on `entity`'s world; on a refusal logs it and despawns the entity.
fn fill(
    entity: EntityWorldMut,
    what: &str,
    spawn: impl FnOnce(&mut World, Entity) -> Result<Entity>,
) {
    let e = entity.id();
    let world = entity.into_world_mut();
    if let Err(error) = spawn(world, e) {
        tracing::warn!("cleave: the {what} {e} was not spawned: {error}");
        world.despawn(e);
    }
}

/// Spawning cleave's things from `Commands`: each returns the entity the thing will be,
/// reserved now and filled when the commands apply (see the module docs).
pub trait CleaveCommands {
    /// A body ([`SpawnBody`]).
    fn spawn_soft_body(&mut self, desc: BodyDesc) -> Entity;
    /// A cutting tool ([`SpawnTool`]).
    fn spawn_cutting_tool(&mut self, desc: ToolDesc) -> Entity;
    /// A collider ([`SpawnCollider`]).
    fn spawn_collider(&mut self, desc: ColliderDesc) -> Entity;
    /// An attachment ([`AttachParticles`]).
    fn attach_particles(&mut self, attachment: AttachParticles) -> Entity;
}

impl CleaveCommands for Commands<'_, '_> {
    fn spawn_soft_body(&mut self, desc: BodyDesc) -> Entity {
        queued(self.spawn_empty(), SpawnBody(desc))
    }
    fn spawn_cutting_tool(&mut self, desc: ToolDesc) -> Entity {
        queued(self.spawn_empty(), SpawnTool(desc))
    }
    fn spawn_collider(&mut self, desc: ColliderDesc) -> Entity {
        queued(self.spawn_empty(), SpawnCollider(desc))
    }
    fn attach_particles(&mut self, attachment: AttachParticles) -> Entity {
        queued(self.spawn_empty(), attachment)
    }
}

fn queued(mut e: EntityCommands, command: impl EntityCommand<Out = ()>) -> Entity {
    e.queue(command);
    e.id()
}
