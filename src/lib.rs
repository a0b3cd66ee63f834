//! # cleave
//!
//! Lattice shape-matching soft bodies with real-time cutting, as ordered bevy_ecs
//! systems.
//!
//! ## The model
//!
//! A body is a voxel lattice of particles: each particle's rest position is its lattice
//! coordinate times the spacing, and two particles are *adjacent* when a voxel edge joins
//! them. The edges are data ([`lattice::Lattice`]): a cut may remove a particle, sever an
//! edge or split a particle in two. Overlapping *clusters* of particles — each one
//! connected through the edges — are shape-matching constraints (Müller et al. 2005):
//! each pulls its members toward the best rigid placement of their rest shape, with the
//! stiffness of its material, so the body is elastic ([`clustering`] builds them).
//!
//! ## One frame
//!
//! The stages run as ordered ECS systems ([`systems`]): `substeps` times, **predict**
//! (forces, damping, inertial prediction) and **shape-match** (the solver's iterations
//! over clusters, contacts and colliders, [`solver`]); then **detect** (read-only: which
//! particles and edges the tools reach, which voxels tear, [`detection`]), **cut**
//! (particle data only), and **regroup**, **split**, **expand** (cluster data only): the
//! cut clusters rebuilt by graph algorithms ([`reconstruct`]) so that pieces separate
//! while the body keeps the clusters, and the stiffness, of its shape built fresh.
//!
//! ## Example
//!
//! ```
//! use cleave::prelude::*;
//!
//! # fn main() -> cleave::error::Result<()> {
//! let mut sim = Simulation::new(SimConfig::default())?;
//! let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 6), 0.1), 0.1);
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
//! Pure algorithms live in plain modules ([`lattice`], [`clustering`], [`reconstruct`],
//! [`solver`], [`rotation`]); [`systems`] holds the thin ECS stages; [`sim::Simulation`]
//! is the headless facade; [`save`] writes and resumes a simulation.
#![warn(missing_docs)]

pub mod bench;
pub mod carve;
pub mod cluster_edits;
pub mod cluster_index;
pub mod cluster_shape;
pub mod cluster_store;
pub mod clustering;
pub mod collider;
pub mod components;
pub mod config;
pub mod convex;
pub mod detection;
pub mod dump;
pub mod error;
#[cfg(feature = "render")]
pub mod export;
pub mod fidelity;
pub mod graph;
pub mod invariants;
pub mod lanes;
pub mod lattice;
pub mod mesh;
pub mod mesh_sdf;
mod named_enum;
pub mod particle_split;
#[cfg(feature = "bevy_app")]
pub mod plugin;
pub mod prefetch;
pub mod profile;
pub mod reconstruct;
#[cfg(feature = "render")]
pub mod render;
pub mod resources;
pub mod rotation;
pub mod save;
pub mod scene;
pub mod scene_file;
pub mod sim;
pub mod simd;
pub mod solver;
pub mod static_solve;
pub mod stats;
#[path = "../systems/mod.rs"]
pub mod systems;
pub mod table_rows;
pub mod tear;
pub mod tool;

/// The glam version cleave's types use (vectors, quaternions), so that users need not
/// depend on a matching version themselves.
pub use glam;

/// The bevy_ecs version cleave's systems and components use.
pub use bevy_ecs;

/// The types most users need.
pub mod prelude {
    pub use crate::collider::ColliderShape;
    pub use crate::components::*;
    pub use crate::config::{GroundPlane, Material, SimConfig, SolverMode, StaticBox};
    pub use crate::error::{CleaveError, Result};
    pub use crate::lattice::{SdfShape, Shape};
    pub use crate::resources::{
        BodySplit, ClustersRebuilt, EdgesSevered, ParticlesCut, ParticlesRepaired,
    };
    pub use crate::sim::{
        BodyDesc, ColliderDesc, PinRegion, Simulation, ToolDesc, check_invariants,
    };
    pub use crate::systems::{CleaveSchedule, SimStage, SubstepSchedule, SyncSchedule, install};
    pub use crate::tool::{CutMode, Path, Pose, ToolShape};
    pub use bevy_ecs::message::MessageReader;
    pub use glam::{Quat, UVec3, Vec3};
}

/// The README's code blocks, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
