//! ECS components. Particle side: [`Particle`], [`Position`], [`PrevPosition`],
//! [`Velocity`], [`InvMass`], and the body's [`BodyLattice`] (which holds what never
//! changes: lattice coordinates and rest positions). Cluster side: [`ClusterMembers`],
//! [`ClusterOf`], [`Compliance`], and the body's [`ParticleClusters`] index. Tools:
//! [`Tool`], [`ToolPose`], [`ToolPath`]. Colliders: [`Collider`], [`ColliderPose`],
//! [`ColliderPath`].

use crate::cluster_index::ClusterIndex;
use crate::collider::ColliderShape;
use crate::config::Material;
use crate::lattice::Lattice;
use crate::tool::{CutMode, Path, Pose, ToolShape};
use bevy_ecs::entity::{Entities, EntityIndex};
use bevy_ecs::prelude::*;
use glam::{IVec3, Vec3};

/// A particle: its body and its body-local index (stable for the body's life).
///
/// Its lattice coordinate and rest position never change, so they are stored once per
/// body, not per entity: `lattice.coord(index)` and `lattice.rest_position(index)` of the
/// body's [`BodyLattice`].
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct Particle {
    /// The body entity.
    pub body: Entity,
    /// Index in the body's lattice.
    pub index: u32,
}

/// Current (or, during a substep, predicted) position.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Position(pub Vec3);

/// Position at the start of the current substep.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct PrevPosition(pub Vec3);

/// Velocity.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Velocity(pub Vec3);

/// Inverse mass; 0 pins the particle.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct InvMass(pub f32);

/// A body: its material, and where its clustering's seed grid lies.
#[derive(Component, Clone, Debug)]
pub struct Body {
    /// Material and clustering parameters.
    pub material: Material,
    /// Where the initial clustering placed its seed grid
    /// ([`crate::clustering::seed_grid_offset`]). A fresh clustering of the body's
    /// current geometry ([`crate::sim::recluster`]) places it there too, so that it
    /// differs from the spawned clusters only where the body was cut.
    pub seed_grid: IVec3,
}

/// Particle data of a body: the lattice (coordinate ↔ index, live flags), the entity of
/// each particle index, and the number of connected pieces.
#[derive(Component, Clone, Debug)]
pub struct BodyLattice {
    /// The lattice.
    pub lattice: Lattice,
    /// Particle entity per index (stale for removed particles).
    pub particles: Vec<Entity>,
    /// Connected pieces of the live particle graph.
    pub pieces: usize,
}

/// Cluster data of a body: for each particle index, the clusters that contain it, as
/// cluster entity indices ([`Entity::index_u32`]), ascending.
///
/// An index names the cluster entity that is alive with it (live entities never share
/// an index): [`ParticleClusters::clusters_of`] resolves them. Four bytes per entry
/// instead of an [`Entity`]'s eight keep the index at 32 B per particle.
#[derive(Component, Clone, Debug, Default)]
pub struct ParticleClusters(pub ClusterIndex);

impl ParticleClusters {
    /// The cluster entities that contain particle `p` (none for an index out of range).
    pub fn clusters_of<'a>(
        &'a self,
        p: u32,
        entities: &'a Entities,
    ) -> impl Iterator<Item = Entity> + 'a {
        self.0
            .clusters_of(p)
            .iter()
            .map(|k| cluster_entity(entities, *k))
    }
}

/// The live entity with index `k` (an entry of [`ParticleClusters`]).
#[inline]
pub fn cluster_entity(entities: &Entities, k: u32) -> Entity {
    match EntityIndex::from_raw_u32(k) {
        Some(index) => entities.resolve_from_index(index),
        None => Entity::PLACEHOLDER,
    }
}

/// A cluster's members as body-local particle indices, sorted.
#[derive(Component, Clone, Debug, PartialEq, Eq)]
pub struct ClusterMembers(pub Vec<u32>);

/// The body a cluster belongs to.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClusterOf(pub Entity);

/// Compliance `1/κ` of a cluster's elastic energy in m/N (0: rigid); see
/// [`crate::config::Material::compliance`].
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Compliance(pub f32);

/// A cutting tool: shape, cut width (how far from its surface `remove` and `split` reach)
/// and cut mode.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    /// Shape in the local frame.
    pub shape: ToolShape,
    /// Width of the cut zone (> 0).
    pub cut_width: f32,
    /// What the tool does where it passes.
    pub mode: CutMode,
}

/// The tool's pose now and at the previous frame (for the swept test).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ToolPose {
    /// Current pose.
    pub current: Pose,
    /// Pose at the previous frame.
    pub last: Pose,
}

/// A keyframed path that drives the tool's pose from the simulation clock.
#[derive(Component, Clone, Debug, PartialEq)]
pub struct ToolPath(pub Path);

/// A collider that particles cannot enter: static, moved by a [`ColliderPath`], or
/// moved by game code through its [`ColliderPose`].
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Collider {
    /// Shape in the local frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient (≥ 0).
    pub friction: f32,
}

/// The collider's pose at the end of the current frame and at its start; the substeps
/// move it from one to the other.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ColliderPose {
    /// Pose at the end of the frame being simulated.
    pub current: Pose,
    /// Pose at its start.
    pub last: Pose,
}

/// A keyframed path that drives a collider's pose from the simulation clock (a press, a
/// paddle).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct ColliderPath(pub Path);
