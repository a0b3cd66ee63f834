//! What a save holds, part by part: the entities cleave spawned with their components,
//! and the solver's own state. Written by [`super::save`], read back by
//! [`super::restore`].

use crate::config::SimConfig;
use crate::ecs::components::*;
use crate::ecs::handles::SavedHandlePose;
use crate::ecs::layout::saved::LayoutState;
use crate::ecs::resources::{CutReport, SceneLabel, SimClock, SimRng};
use crate::ecs::surface_mesh::SavedSurface;
use crate::error::CleaveError;
use crate::solver::clusters::term::ClusterTerm;
use crate::solver::particles::Particles;
use crate::solver::schemes::gauss_seidel::GaussSeidel;
use bevy_ecs::prelude::*;
use serde::{Deserialize, Serialize};

/// A body and what it owns besides its entities.
#[derive(Serialize, Deserialize)]
pub(super) struct BodyState {
    pub(super) entity: Entity,
    pub(super) body: Body,
    pub(super) lattice: BodyLattice,
    pub(super) clusters: ParticleClusters,
    /// Its drawable surface, when it keeps one.
    pub(super) surface: Option<SavedSurface>,
    /// Its handles, when it is posed by them.
    pub(super) pose: Option<SavedHandlePose>,
}

/// A particle entity.
#[derive(Serialize, Deserialize)]
pub(super) struct ParticleState {
    pub(super) entity: Entity,
    pub(super) particle: Particle,
    pub(super) position: Position,
    pub(super) velocity: Velocity,
    pub(super) orientation: Orientation,
    pub(super) spin: AngularVelocity,
    pub(super) inv_mass: InvMass,
}

/// A cluster entity.
#[derive(Serialize, Deserialize)]
pub(super) struct ClusterState {
    pub(super) entity: Entity,
    pub(super) members: ClusterMembers,
    pub(super) of: ClusterOf,
    pub(super) compliance: Compliance,
}

/// A tool entity.
#[derive(Serialize, Deserialize)]
pub(super) struct ToolState {
    pub(super) entity: Entity,
    pub(super) tool: Tool,
    pub(super) pose: ToolPose,
    pub(super) path: Option<ToolPath>,
}

/// A collider entity.
#[derive(Serialize, Deserialize)]
pub(super) struct ColliderState {
    pub(super) entity: Entity,
    pub(super) collider: Collider,
    pub(super) pose: ColliderPose,
    pub(super) path: Option<ColliderPath>,
    pub(super) dynamic: Option<DynamicCollider>,
}

/// An attachment entity.
#[derive(Serialize, Deserialize)]
pub(super) struct AttachmentState {
    pub(super) entity: Entity,
    pub(super) attachment: Attachment,
    pub(super) target: AttachmentTarget,
    pub(super) path: Option<AttachmentPath>,
    pub(super) velocity: Option<AttachmentVelocity>,
}

/// The solver cache without what is derived from it or from the ECS on the way (the
/// terms other than the clusters are taken again from the ECS).
#[derive(Serialize, Deserialize)]
pub(super) struct CacheState {
    pub(super) clusters_term: ClusterTerm,
    pub(super) gauss_seidel: GaussSeidel,
    /// Each term's own saved state, by name ([`crate::solver::term::Term::saved_state`]).
    pub(super) terms: Vec<(String, Vec<u8>)>,
    pub(super) particles: Particles,
    /// The layout's own state (encoded inline, after the particles).
    pub(super) layout: LayoutState,
}

/// Everything saved.
#[derive(Serialize, Deserialize)]
pub(super) struct Snapshot {
    /// Entity indices the saving world had handed out (every one it ever gave is below).
    pub(super) entity_bound: u32,
    pub(super) config: SimConfig,
    pub(super) clock: SimClock,
    pub(super) rng: SimRng,
    /// In entity order (the solver finds bodies by it).
    pub(super) bodies: Vec<BodyState>,
    /// In the order the world stores them, which decides the order new ones join.
    pub(super) particles: Vec<ParticleState>,
    pub(super) clusters: Vec<ClusterState>,
    pub(super) tools: Vec<ToolState>,
    pub(super) colliders: Vec<ColliderState>,
    pub(super) attachments: Vec<AttachmentState>,
    pub(super) cache: CacheState,
    pub(super) cut: CutReport,
    pub(super) label: SceneLabel,
}

pub(super) fn invalid(what: impl std::fmt::Display) -> CleaveError {
    CleaveError::Save(what.to_string())
}
