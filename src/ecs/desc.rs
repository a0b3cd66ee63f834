//! What a body (with its pins and attachments), a tool and a collider are spawned
//! from: plain descriptions, checked when spawned ([`crate::ecs::spawn`]).

use crate::body::shape::Shape;
use crate::config::{Material, SimConfig};
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::components::Hold;
use crate::geometry::collider::ColliderShape;
use crate::geometry::mesh::TriangleMesh;
use glam::{Quat, Vec3};
use std::sync::Arc;

/// An axis-aligned world-space box (bounds included).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Region {
    /// Checks that its corners are finite; errors name `{field}.min` and `{field}.max`.
    pub fn validate(&self, field: &str) -> crate::error::Result<()> {
        crate::error::check_corners(field, self.min, self.max)
    }

    /// Whether the world position `x` lies in the region (bounds included).
    pub fn contains(&self, x: Vec3) -> bool {
        x.cmpge(self.min).all() && x.cmple(self.max).all()
    }
}

/// An explicit shape-matching group: the body's particles in `region` (world space,
/// after placement) move as one part of `compliance` (1/Pa, as the material's; 0: a
/// rigid part) and all take its rotation. Particles in two or more groups are
/// non-oriented, so two parts that share them turn freely about each other (a joint).
/// Oriented model only.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GroupDesc {
    /// Where the group's particles are.
    pub region: Region,
    /// Compliance `1/E` in 1/Pa (≥ 0; 0: rigid).
    pub compliance: f32,
}

/// A region whose particles take their own compliance instead of the material's (both
/// models; where regions overlap, the last one given).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StiffnessRegion {
    /// Where the particles are.
    pub region: Region,
    /// Compliance `1/E` in 1/Pa (0–1; 0: rigid).
    pub compliance: f32,
}

/// An axis-aligned world-space region whose particles are pinned: a hard attachment
/// whose targets move at the region's constant velocity whatever acts on the body (zero:
/// they stay), so pins can hold a body or pull it.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PinRegion {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
    /// Velocity of the pinned particles (m/s).
    #[serde(default)]
    pub velocity: Vec3,
}

impl PinRegion {
    /// Checks that its corners are finite and its velocity within
    /// [`crate::error::VELOCITY`]; errors name `{field}.min` and so on.
    pub fn validate(&self, field: &str) -> crate::error::Result<()> {
        crate::error::check_corners(field, self.min, self.max)?;
        crate::error::check_vec_within(
            &format!("{field}.velocity"),
            self.velocity,
            &crate::error::VELOCITY,
        )
    }

    /// Whether the world position `x` lies in the region (bounds included).
    pub fn contains(&self, x: Vec3) -> bool {
        self.region().contains(x)
    }

    /// The region, without its velocity.
    pub fn region(&self) -> Region {
        Region {
            min: self.min,
            max: self.max,
        }
    }
}

/// Particles of a body (those in `region` when it is spawned) attached to a target
/// pose, each by a spring of `compliance`, or only their centroid by `hold` (see
/// [`crate::ecs::components::Attachment`]; scene files list the two as `attachments`
/// and `centroids`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AttachmentDesc {
    /// World-space region (after the body is placed) whose particles are attached; it
    /// must hold at least one.
    pub region: Region,
    /// The target's keyframed path; its motion moves the particles' targets. Empty: the
    /// target stays where the particles are (until game code moves it).
    pub path: Path,
    /// Compliance of each particle's spring (of the centroid's, for a centroid hold),
    /// m/N (≥ 0; 0: hard, as a pin).
    pub compliance: f32,
    /// What is held: each particle, or only their centroid.
    pub hold: Hold,
}

/// A handle of a body (SPEC §6.3): the particles in `region` when the body is spawned
/// (a point handle: the one nearest the region's centre), moved along `path`. A
/// simulated body is driven by its handles as soft attachments of `compliance` (their
/// keys then move rigidly: no scale); a posed body ([`crate::ecs::handles::pose_by_handles`])
/// follows them exactly.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HandleDesc {
    /// World-space region (after the body is placed) whose particles the handle moves;
    /// it must hold at least one.
    pub region: Region,
    /// A point handle (one particle) instead of a region handle (an affine map).
    pub point: bool,
    /// Keyframes of the handle's target (empty: it stays at rest).
    pub path: crate::deform::keys::HandlePath,
    /// Compliance of each particle's spring while simulating, m/N (≥ 0; 0: hard).
    pub compliance: f32,
}

/// Everything needed to spawn a body.
#[derive(Clone, Debug)]
pub struct BodyDesc {
    /// Shape to voxelise (local frame).
    pub shape: Shape,
    /// Lattice spacing h (> 0).
    pub spacing: f32,
    /// World position of the shape's local origin.
    pub position: Vec3,
    /// Initial rotation (rest shape stays unrotated: a rotated body returns to a
    /// rotated copy of it).
    pub rotation: Quat,
    /// Initial velocity.
    pub velocity: Vec3,
    /// Initial angular velocity (rad/s) about [`BodyDesc::position`]: each particle
    /// starts at `velocity + ω × (x − position)` and turning at `ω`.
    pub angular_velocity: Vec3,
    /// Material and clustering parameters.
    pub material: Material,
    /// Regions of pinned particles (world space, after placement).
    pub pins: Vec<PinRegion>,
    /// Attachments of the body's particles (world space, after placement).
    pub attachments: Vec<AttachmentDesc>,
    /// Handles of the body's particles (world space, after placement).
    pub handles: Vec<HandleDesc>,
    /// Explicit shape-matching groups (oriented model; world space, after placement).
    pub groups: Vec<GroupDesc>,
    /// Regions of particles with their own compliance (world space, after placement).
    pub stiffness_regions: Vec<StiffnessRegion>,
    /// A closed mesh (in the shape's local frame) to draw instead of the lattice's
    /// surface, carried by the particles and opened by cuts
    /// ([`crate::surface::embed`]). A body voxelised from a mesh draws that mesh when
    /// this is `None`.
    pub render_mesh: Option<Arc<TriangleMesh>>,
    /// How the body's lattice surface is drawn.
    pub surface: SurfaceOptions,
    /// Largest distance, in lattice spacings (0–0.5; default 0), each particle is moved
    /// from its lattice place when spawned, in a random direction drawn from the
    /// simulation's seeded stream: a body out of its rest shape, for relaxation
    /// ([`crate::sim::relax`]) to settle.
    pub jitter: f32,
}

/// How a body's lattice surface is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceOptions {
    /// Round the voxel staircase once per topology change, in rest space
    /// ([`crate::surface::smooth`]); a render mesh is drawn as given either way.
    pub smooth: bool,
}

impl BodyDesc {
    /// A body of the given shape and spacing with default material at the origin.
    pub fn new(shape: Shape, spacing: f32) -> Self {
        Self {
            shape,
            spacing,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            material: Material::default(),
            pins: Vec::new(),
            attachments: Vec::new(),
            handles: Vec::new(),
            groups: Vec::new(),
            stiffness_regions: Vec::new(),
            render_mesh: None,
            surface: SurfaceOptions::default(),
            jitter: 0.0,
        }
    }
}

/// Everything needed to spawn a cutting tool.
#[derive(Clone, Debug)]
pub struct ToolDesc {
    /// Shape.
    pub shape: ToolShape,
    /// Width of the cut zone (> 0).
    pub cut_width: f32,
    /// What the tool does where it passes.
    pub cut_mode: CutMode,
    /// Keyframed path; if empty the tool stays at `pose` until game code moves it.
    pub path: Path,
    /// Initial pose.
    pub pose: Pose,
}

/// Everything needed to spawn a collider.
#[derive(Clone, Debug)]
pub struct ColliderDesc {
    /// Shape in the local frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient (≥ 0).
    pub friction: f32,
    /// Pose (before the path starts, or for good without a path).
    pub pose: Pose,
    /// Keyframed path; empty: static, or moved by game code through
    /// [`ColliderPose::current`](crate::ecs::components::ColliderPose::current).
    pub path: Path,
}

/// The most frames a run may be asked for, in a scene file or on the command line.
pub const MAX_FRAMES: u32 = 10_000_000;

/// The frames a run may be given (a scene file's `frames`, `--frames`).
pub const FRAMES: crate::error::allowed::Allowed =
    crate::error::allowed::Allowed::count("frames", 0, MAX_FRAMES);

/// A runnable scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Simulation settings.
    pub config: SimConfig,
    /// Bodies to spawn.
    pub bodies: Vec<BodyDesc>,
    /// Tools to spawn.
    pub tools: Vec<ToolDesc>,
    /// Colliders to spawn (besides the config's ground and static boxes).
    pub colliders: Vec<ColliderDesc>,
    /// Default number of frames.
    pub frames: u32,
}
