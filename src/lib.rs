//! # cleave
//!
//! Lattice shape-matching soft bodies with real-time cutting, as ordered bevy_ecs
//! systems. A body is a voxel lattice of particles; overlapping clusters of particles
//! are shape-matching constraints (SPEC §2). Cutting tools remove particles, sever the
//! lattice's edges or split particles in two, and materials may tear; the cut clusters
//! are rebuilt locally by graph algorithms (SPEC §3–4) so pieces separate while the body
//! keeps its stiffness.
//!
//! Pure algorithms live in plain modules ([`lattice`], [`clustering`], [`reconstruct`],
//! [`solver`], [`rotation`]); [`systems`] holds the thin ECS stages; [`sim::Simulation`]
//! is the headless facade.
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
