//! # cleave
//!
//! Lattice shape-matching soft bodies with real-time cutting, as ordered bevy_ecs
//! systems.
//!
//! ## The model
//!
//! A body is a voxel lattice of particles: each particle's rest position is its lattice
//! coordinate times the spacing, and two particles are *adjacent* when a voxel edge joins
//! them. The edges are data ([`body::lattice::Lattice`]): a cut may remove a particle, sever an
//! edge or split a particle in two. Overlapping *clusters* of particles — each one
//! connected through the edges — are shape-matching constraints (Müller et al. 2005):
//! each pulls its members toward the best rigid placement of their rest shape, with the
//! stiffness of its material, so the body is elastic ([`clusters::clustering`] builds them).
//! The body's energy is a sum of such terms ([`solver::term`]): the clusters, distance
//! constraints on the edges, attachments that pin or drag particles, contacts and
//! colliders — and whatever a user registers.
//!
//! ## One frame
//!
//! The stages run as ordered ECS systems ([`systems`]): the solver is brought up to date
//! and the particles' state loaded into its dense arrays; `substeps` times, **predict**
//! (forces, damping, inertial prediction) and **shape-match** (the solver's iterations
//! over every term, [`solver`]); the state is written back; then **detect** (read-only: which
//! particles and edges the tools reach, which voxels tear, [`cut::detection`]), **cut**
//! (particle data only), and **regroup**, **split**, **expand** (cluster data only): the
//! cut clusters rebuilt by graph algorithms ([`reconstruct`]) so that pieces separate
//! while the body keeps the clusters, and the stiffness, of its shape built fresh; last,
//! **settle** records where the tools, colliders and attachment targets ended, so that
//! the next frame sweeps them on from there whether a path or game code moves them.
//!
//! ## Example
//!
//! ```
//! use cleave::prelude::*;
//!
//! # fn main() -> cleave::error::Result<()> {
//! let mut sim = Simulation::new(SimConfig::default())?;
//! let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 6)), 0.1);
//! desc.position = Vec3::new(0.0, 0.5, 0.0);
//! let body = sim.spawn_body(&desc)?;
//! // a blade through the middle, moving down
//! let at = |y: f32| Pose { position: Vec3::new(0.0, y, 0.0), rotation: Quat::from_rotation_y(1.5708) };
//! sim.spawn_tool(&ToolDesc {
//!     shape: ToolShape::Blade { half_width: 1.0, half_height: 0.2 },
//!     cut_width: 0.101,
//!     cut_mode: CutMode::Remove,
//!     path: Path { keys: vec![(0.0, at(1.5)), (0.2, at(-0.5))] },
//!     pose: at(1.5),
//! })?;
//! sim.run(30);
//! assert_eq!(sim.pieces(body)?.len(), 2);
//! assert!(check_invariants(sim.world()).is_empty());
//! # Ok(())
//! # }
//! ```
//!
//! The folders are the layers, each importing only those below it: [`util`], [`math`],
//! [`geometry`], [`body`], [`clusters`], [`cut`], [`reconstruct`], [`solver`], [`surface`] hold pure
//! algorithms on plain data; [`ecs`] the components and resources, [`systems`] the thin
//! ECS stages; [`io`] scenes, saves and pictures; [`sim`] the headless facade
//! ([`sim::simulation::Simulation`]) and the Bevy plugin; [`analysis`] the measurements.
#![warn(missing_docs)]

pub mod analysis;
pub mod body;
pub mod clusters;
pub mod config;
pub mod cut;
pub mod deform;
pub mod ecs;
pub mod error;
pub mod geometry;
pub mod io;
pub mod math;
pub mod reconstruct;
pub mod sim;
pub mod solver;
pub mod surface;
#[path = "../systems/mod.rs"]
pub mod systems;
pub mod util;

/// The glam version cleave's types use (vectors, quaternions), so that users need not
/// depend on a matching version themselves.
pub use glam;

/// The bevy_ecs version cleave's systems and components use. Its derive macros
/// (`#[derive(Component)]`, `#[derive(Resource)]`) name the `bevy_ecs` crate, so a crate
/// deriving its own components depends on `bevy_ecs` directly, at this version.
pub use bevy_ecs;

/// The bevy_app version [`sim::plugin::CleavePlugin`] plugs into.
#[cfg(feature = "bevy_app")]
pub use bevy_app;
/// The bevy_time version whose `Time<Fixed>` [`sim::plugin::CleavePlugin`] steps by.
#[cfg(feature = "bevy_app")]
pub use bevy_time;

/// The types most users need. It names no `Result` (cleave's is
/// [`error::Result`]), so it can be glob-imported beside bevy's prelude.
pub mod prelude {
    pub use crate::body::shape::{SdfShape, Shape, ShapePart};
    pub use crate::config::{GroundPlane, Material, Model, SimConfig, SolverMode, StaticBox};
    pub use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
    pub use crate::deform::keys::{HandleKey, HandlePath};
    pub use crate::ecs::check::check_invariants;
    pub use crate::ecs::commands::CleaveCommands;
    pub use crate::ecs::components::*;
    pub use crate::ecs::desc::{
        AttachmentDesc, BodyDesc, ColliderDesc, GroupDesc, HandleDesc, PinRegion, Region,
        StiffnessRegion, ToolDesc,
    };
    pub use crate::ecs::handles::{HandlePose, PoseMethod};
    pub use crate::ecs::resources::{
        BodySplit, ClustersRebuilt, EdgesSevered, ParticlesCut, ParticlesRepaired, SimClock,
        SplitsOverBudget, SurfaceBudget, SurfaceChanged, SurfaceDeferred,
    };
    pub use crate::ecs::surface_mesh::SurfaceMesh;
    pub use crate::error::CleaveError;
    pub use crate::geometry::collider::ColliderShape;
    #[cfg(feature = "bevy_app")]
    pub use crate::sim::plugin::{CleaveFrame, CleavePlugin, CleaveSystems, StepClock};
    pub use crate::sim::simulation::Simulation;
    pub use crate::systems::{CleaveSchedule, SimStage, SubstepSchedule, SyncSchedule, install};
    pub use bevy_ecs::entity::Entity;
    pub use bevy_ecs::message::{MessageReader, Messages};
    pub use glam::{Quat, UVec3, Vec3};
}

/// The README's code blocks, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
