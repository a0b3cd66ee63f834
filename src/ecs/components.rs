//! ECS components. Particle side: [`Particle`], [`Position`], [`Velocity`],
//! [`Orientation`], [`AngularVelocity`], [`InvMass`],
//! and the body's [`BodyLattice`] (which holds what never changes: lattice coordinates
//! and rest positions). Cluster side: [`ClusterMembers`], [`ClusterOf`], [`Compliance`],
//! and the body's [`ParticleClusters`] index. Attachments: [`Attachment`],
//! [`AttachmentTarget`], [`AttachmentPath`], [`AttachmentVelocity`]. Tools: [`Tool`],
//! [`ToolPose`], [`ToolPath`]. Colliders: [`Collider`], [`ColliderPose`],
//! [`ColliderPath`].
//!
//! A particle's components hold its state between frames; within a frame the solver's
//! dense arrays do (loaded at the frame's start, written back after its substeps), so a
//! game reads and writes them between frames.

use crate::body::groups::ParticleGroups;
use crate::body::lattice::Lattice;
use crate::clusters::index::ClusterIndex;
use crate::config::Material;
use crate::cut::tool::{Path, Pose};
use crate::geometry::collider::ColliderShape;
use bevy_ecs::prelude::*;
use glam::{IVec3, Quat, Vec3};

/// A particle: its body and its body-local index (stable for the body's life).
///
/// Its lattice coordinate and rest position never change, so they are stored once per
/// body, not per entity: `lattice.coord(index)` and `lattice.rest_position(index)` of the
/// body's [`BodyLattice`].
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Particle {
    /// The body entity.
    pub body: Entity,
    /// Index in the body's lattice.
    pub index: u32,
}

/// Position.
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Position(pub Vec3);

/// Velocity.
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Velocity(pub Vec3);

/// Orientation: the turn of the particle's frame from its rest frame (a unit
/// quaternion; identity at rest). In the oriented model the groups' shape matching turns
/// it ([`crate::solver::terms::oriented`]); in the cluster model it follows the
/// particle's clusters ([`crate::solver::clusters::term::ClusterTerm::blend_orientations`]).
/// Renderers and skinning read it in both.
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Orientation(pub Quat);

/// Angular velocity of the particle's frame, in rad/s (world frame).
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AngularVelocity(pub Vec3);

/// Inverse mass. 0 makes the particle kinematic: it keeps its velocity whatever acts
/// on it (an [`Attachment`] pins particles without changing their mass).
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InvMass(pub f32);

/// A body: its material, and where its clustering's seed grid lies.
#[derive(Component, Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Body {
    /// Material and clustering parameters.
    pub material: Material,
    /// Where the initial clustering placed its seed grid
    /// ([`crate::clusters::clustering::seed_grid_offset`]). A fresh clustering of the body's
    /// current geometry ([`crate::ecs::spawn::recluster`]) places it there too, so that it
    /// differs from the spawned clusters only where the body was cut.
    pub seed_grid: IVec3,
    /// Explicit groups and per-particle compliances (stiffness regions).
    pub groups: ParticleGroups,
}

/// Particle data of a body: the lattice (coordinate ↔ index, live flags), the entity of
/// each particle index, and the number of connected pieces.
#[derive(Component, Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BodyLattice {
    /// The lattice.
    pub lattice: Lattice,
    /// Particle entity per index (stale for removed particles).
    pub particles: Vec<Entity>,
    /// Connected pieces of the live particle graph.
    pub pieces: usize,
}

/// Cluster data of a body: which clusters hold each particle, and the entity of each
/// cluster.
///
/// A cluster is named by a *key* its body hands out ([`ClusterKeys`]), not by its
/// entity: the particle index, the reconstruction and the cut stages' hand-over all use
/// keys, and entities appear only where clusters meet the ECS. So a body names its
/// clusters alike whatever entities the world hands out, and a saved simulation resumes
/// exactly as it would have gone on.
#[derive(Component, Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ParticleClusters {
    /// For each particle index, the keys of the clusters that hold it, ascending.
    pub index: ClusterIndex,
    /// The entity of each key.
    pub keys: ClusterKeys,
}

impl ParticleClusters {
    /// The cluster entities that contain particle `p` (none for an index out of range).
    pub fn clusters_of(&self, p: u32) -> impl Iterator<Item = Entity> + '_ {
        self.index
            .clusters_of(p)
            .iter()
            .filter_map(|k| self.keys.entity(*k))
    }
}

/// The cluster entity behind each key of one body, and the keys free for reuse. A freed
/// key is handed out again before a new one (the last freed first), so keys stay dense.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ClusterKeys {
    entities: Vec<Entity>,
    free: Vec<u32>,
}

impl ClusterKeys {
    /// Names the cluster entity `e`; returns its key.
    pub fn insert(&mut self, e: Entity) -> u32 {
        match self.free.pop() {
            Some(k) => {
                self.entities[k as usize] = e;
                k
            }
            None => {
                self.entities.push(e);
                self.entities.len() as u32 - 1
            }
        }
    }

    /// Frees key `k`; returns the entity it named.
    pub fn remove(&mut self, k: u32) -> Option<Entity> {
        let e = self.entity(k)?;
        self.entities[k as usize] = Entity::PLACEHOLDER;
        self.free.push(k);
        Some(e)
    }

    /// The entity of key `k`, if it names one.
    pub fn entity(&self, k: u32) -> Option<Entity> {
        self.entities
            .get(k as usize)
            .copied()
            .filter(|e| *e != Entity::PLACEHOLDER)
    }

    /// Every key in use with its entity, by key.
    pub fn iter(&self) -> impl Iterator<Item = (u32, Entity)> + '_ {
        (0..self.entities.len() as u32).filter_map(|k| self.entity(k).map(|e| (k, e)))
    }

    /// The keys in use.
    pub fn len(&self) -> usize {
        self.entities.len() - self.free.len()
    }

    /// Whether no key is in use.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The entity of every key slot (`Entity::PLACEHOLDER` where free) and the free keys,
    /// last freed last: everything that decides the keys handed out next.
    pub fn parts(&self) -> (&[Entity], &[u32]) {
        (&self.entities, &self.free)
    }

    /// Keys as [`ClusterKeys::parts`] gave them (with the entities of another world,
    /// when a saved simulation is loaded).
    pub fn from_parts(entities: Vec<Entity>, free: Vec<u32>) -> Self {
        Self { entities, free }
    }
}

/// A cluster's members as body-local particle indices, sorted.
#[derive(Component, Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ClusterMembers(pub Vec<u32>);

/// The body a cluster belongs to, and the key it names the cluster by (see
/// [`ClusterKeys`]).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ClusterOf {
    /// The body entity.
    pub body: Entity,
    /// The cluster's key in the body.
    pub key: u32,
}

/// Compliance `1/κ` of a cluster's elastic energy in m/N (0: rigid); see
/// [`crate::config::Material::compliance`].
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Compliance(pub f32);

pub use crate::cut::tool::Tool;

// (a tool's data is the cut layer's; the ECS only stores it on the tool's entity)
impl Component for Tool {
    const STORAGE_TYPE: bevy_ecs::component::StorageType = bevy_ecs::component::StorageType::Table;
    type Mutability = bevy_ecs::component::Mutable;
}

/// The tool's pose at the end of the frame being simulated and where the last frame
/// left it: detection tests everything the tool sweeps between the two. Set `current`
/// from game code between frames (or with
/// [`Simulation::set_tool_pose`](crate::sim::simulation::Simulation::set_tool_pose)) to
/// move a tool without a [`ToolPath`]; `last` is the engine's.
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ToolPose {
    /// The pose at the end of the frame being simulated.
    pub current: Pose,
    /// The pose the last frame ended at.
    pub last: Pose,
}

/// A keyframed path that drives the tool's pose from the simulation clock.
#[derive(Component, Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ToolPath(pub Path);

/// A collider that particles cannot enter: static, moved by a [`ColliderPath`], or
/// moved by game code through its [`ColliderPose`] (a rigid body of the game's own
/// engine, which applies the collider's [`ColliderWrench`] to it).
#[derive(Component, Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[require(ColliderWrench)]
pub struct Collider {
    /// Shape in the local frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient (≥ 0).
    pub friction: f32,
}

/// The collider's pose at the end of the frame being simulated and where the last frame
/// left it; the substeps move it from one to the other, so it does not pass through a
/// body however far it moves. Set `current` from game code between frames (or with
/// [`Simulation::set_collider_pose`](crate::sim::simulation::Simulation::set_collider_pose))
/// to move a collider without a [`ColliderPath`]; `last` is the engine's.
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColliderPose {
    /// The pose at the end of the frame being simulated.
    pub current: Pose,
    /// The pose the last frame ended at.
    pub last: Pose,
}

/// What the particles did to a collider over the last frame: the mean force (N) and the
/// mean torque about its centre (N·m) of their contact impulses (friction included), in
/// the world frame. A game whose rigid body stands for the collider applies them to it
/// (the soft body pushes the crate, holds up the box resting on it). Zero where nothing
/// touched it. Written every frame (stage wrench); not kept by saves (a loaded collider
/// starts at zero until its first frame).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq)]
pub struct ColliderWrench {
    /// Mean force over the frame (N).
    pub force: Vec3,
    /// Mean torque over the frame about the collider's centre (N·m).
    pub torque: Vec3,
}

/// Makes a collider a rigid body cleave moves: gravity, the particles' pushes (shared
/// with them by mass, inside the solve) and the ground (without friction) act on it; its
/// [`ColliderPose::current`] and these velocities are its state between frames, which
/// game code may set (checked each frame: a state out of bounds is refused with a
/// logged warning and the collider stays where it is, kinematic, until it is fixed).
/// Build one with [`DynamicCollider::solid`]. See
/// [`crate::solver::terms::colliders::RigidMotion`].
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DynamicCollider {
    /// Mass (kg).
    pub mass: f32,
    /// Principal moments of inertia about the collider's local axes (kg·m²).
    pub inertia: Vec3,
    /// Linear velocity (m/s).
    pub velocity: Vec3,
    /// Angular velocity, world frame (rad/s).
    pub angular_velocity: Vec3,
}

impl DynamicCollider {
    /// A solid `shape` of `mass` (kg) at rest (a capsule as a cylinder and two half
    /// balls, a mesh as its bounding box); an error naming the field when the mass is
    /// out of bounds.
    pub fn solid(shape: &ColliderShape, mass: f32) -> crate::error::Result<Self> {
        let dynamic = Self {
            mass,
            inertia: crate::solver::terms::colliders::solid_inertia(shape, mass),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
        };
        dynamic.check()?;
        Ok(dynamic)
    }

    /// Checks mass, inertia and velocities: finite, the first two in 1e-6 ..= 1e9, the
    /// speeds at most [`crate::error::MAX_SPEED`].
    pub fn check(&self) -> crate::error::Result<()> {
        use crate::error::{check_range, check_vec_within};
        let allowed = "1e-6 ≤ mass ≤ 1e9 (kg)";
        check_range("dynamic.mass", self.mass, 1e-6, 1e9, allowed)?;
        for (axis, value) in ["x", "y", "z"].iter().zip(self.inertia.to_array()) {
            let field = format!("dynamic.inertia.{axis}");
            check_range(&field, value, 1e-9, 1e9, "1e-9 ≤ inertia ≤ 1e9 (kg·m²)")?;
        }
        check_vec_within("dynamic.velocity", self.velocity, &crate::error::VELOCITY)?;
        check_vec_within(
            "dynamic.angular_velocity",
            self.angular_velocity,
            &crate::error::ANGULAR_VELOCITY,
        )
    }

    /// The solver's view of it.
    pub fn motion(&self) -> crate::solver::terms::colliders::RigidMotion {
        crate::solver::terms::colliders::RigidMotion {
            inv_mass: 1.0 / self.mass,
            inv_inertia: (1.0 / self.inertia).into(),
            velocity: self.velocity.into(),
            angular_velocity: self.angular_velocity.into(),
        }
    }
}

/// A keyframed path that drives a collider's pose from the simulation clock (a press, a
/// paddle).
#[derive(Component, Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColliderPath(pub Path);

/// An attachment: particles of one body held, each by its own spring of `compliance`,
/// to targets that move with one pose ([`AttachmentTarget`]). Compliance 0 pins them
/// (hard): they follow their targets exactly; a soft attachment pulls (a drag, a
/// handle). See [`crate::solver::terms::attachments`].
#[derive(Component, Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Attachment {
    /// The body.
    pub body: Entity,
    /// The attached particles, body-local.
    pub particles: Vec<u32>,
    /// Each particle's target in the frame of the target pose.
    pub offsets: Vec<Vec3>,
    /// Compliance of each particle's spring, m/N (≥ 0; 0: hard); of the centroid's
    /// spring for a [`Hold::Centroid`].
    pub compliance: f32,
    /// What is held: each particle, or only their centroid.
    pub hold: Hold,
}

/// What an [`Attachment`] holds to its target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Hold {
    /// Each particle to its own place (a pin, a drag).
    #[default]
    Each,
    /// Only the particles' centroid, to the centroid of their places: the set deforms
    /// freely about it (a grasper holding tissue; SPEC §6.1). See
    /// [`crate::solver::terms::centroids`].
    Centroid,
}

/// Where an attachment pulls: its target pose at the end of the frame being simulated
/// (set it from game code, or let an [`AttachmentPath`] or [`AttachmentVelocity`] move
/// it), and the pose the last frame ended at (the engine's: each frame moves the targets
/// from there to `pose`).
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttachmentTarget {
    /// The target pose at the end of the frame being simulated.
    pub pose: Pose,
    /// The target pose at the end of the last frame.
    pub reached: Pose,
}

impl AttachmentTarget {
    /// A target resting at `pose`.
    pub fn at(pose: Pose) -> Self {
        AttachmentTarget {
            pose,
            reached: pose,
        }
    }
}

/// A keyframed path that drives an attachment's target from the simulation clock.
#[derive(Component, Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttachmentPath(pub Path);

/// A constant velocity (m/s) at which an attachment's target moves (a moving pin).
#[derive(Component, Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttachmentVelocity(pub Vec3);
