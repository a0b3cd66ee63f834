//! The scene file's schema: every struct and enum a RON scene file is read into, each
//! field checked while it is read ([`super::check`]).

use crate::config::{GroundPlane, Material, SimConfig, SolverMode, StaticBox};
use crate::cut::tool::{CutMode, Pose, ToolShape};
use crate::deform::keys::HandleKey;
use crate::ecs::desc::{GroupDesc, PinRegion, Region, StiffnessRegion};
use glam::{Quat, UVec3, Vec3};
use serde::{Deserialize, Serialize};

fn default_frames() -> u32 {
    300
}

/// A scene file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Random seed (cluster offsets, reconstruction choices).
    #[serde(default, deserialize_with = "super::check::seed")]
    pub seed: u64,
    /// Frames to simulate.
    #[serde(default = "default_frames", deserialize_with = "super::check::frames")]
    pub frames: u32,
    /// Simulation settings.
    #[serde(default)]
    pub settings: SettingsFile,
    /// At least one body.
    #[serde(deserialize_with = "super::check::bodies")]
    pub bodies: Vec<BodyFile>,
    /// Cutting tools.
    #[serde(default)]
    pub tools: Vec<ToolFile>,
    /// Colliders: oriented boxes, balls and capsules, static or on a keyframed path.
    #[serde(default)]
    pub colliders: Vec<ColliderFile>,
}

/// Simulation settings ([`SimConfig`] without the seed).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SettingsFile {
    /// Seconds per frame.
    #[serde(deserialize_with = "super::check::dt")]
    pub dt: f32,
    /// Substeps per frame.
    #[serde(deserialize_with = "super::check::substeps")]
    pub substeps: u32,
    /// Solver iterations per substep.
    #[serde(deserialize_with = "super::check::iterations")]
    pub iterations: u32,
    /// Gravity (m/s²).
    #[serde(deserialize_with = "super::check::gravity")]
    pub gravity: Vec3,
    /// Velocity damping per second.
    #[serde(deserialize_with = "super::check::damping")]
    pub damping: f32,
    /// Ground plane `(height, friction)`, if any.
    #[serde(deserialize_with = "super::check::ground")]
    pub ground: Option<GroundPlane>,
    /// Static boxes `(min, max, friction)`.
    #[serde(deserialize_with = "super::check::boxes")]
    pub boxes: Vec<StaticBox>,
    /// Solver scheme.
    pub solver: SolverMode,
    /// Whether particles collide with each other.
    pub contacts: bool,
    /// Conservative culling of contact pairs and tool tests (exact; on by default).
    pub culling: bool,
    /// Relax every body before the first frame: `relax: Some((tolerance: 1e-3))`, every
    /// field optional (see [`crate::config::RelaxOptions`]).
    #[serde(deserialize_with = "super::check::relax")]
    pub relax: Option<crate::config::RelaxOptions>,
    /// Check the invariants after every frame (slow; for tests).
    pub check_invariants_every_frame: bool,
    /// Memory one body may take, in GB.
    #[serde(deserialize_with = "super::check::memory_budget_gb")]
    pub memory_budget_gb: f32,
}

impl Default for SettingsFile {
    fn default() -> Self {
        Self::from_config(&SimConfig::default())
    }
}

/// A body.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyFile {
    /// Shape to voxelise.
    pub shape: ShapeFile,
    /// Lattice spacing h in metres.
    #[serde(deserialize_with = "super::check::spacing")]
    pub spacing: f32,
    /// Position of the shape's origin.
    #[serde(default, deserialize_with = "super::check::coordinates")]
    pub position: Vec3,
    /// Initial rotation, a quaternion (x, y, z, w).
    #[serde(default, deserialize_with = "super::check::rotation")]
    pub rotation: Quat,
    /// Initial velocity.
    #[serde(default, deserialize_with = "super::check::velocity")]
    pub velocity: Vec3,
    /// Initial angular velocity (rad/s) about the body's position.
    #[serde(default, deserialize_with = "super::check::angular_velocity")]
    pub angular_velocity: Vec3,
    /// Material and clustering.
    #[serde(default)]
    pub material: Material,
    /// Pinned regions (world space).
    #[serde(default, deserialize_with = "super::check::pins")]
    pub pins: Vec<PinRegion>,
    /// Attachments of the body's particles: `(region: (min: …, max: …), path: […],
    /// compliance: …)`.
    #[serde(default)]
    pub attachments: Vec<AttachmentFile>,
    /// Centroid holds: the centroid of a region's particles held to a target (by a
    /// spring of `compliance`, m/N; 0: hard) while the particles deform about it, in the
    /// attachments' form: `(region: …, path: […], compliance: …)`.
    #[serde(default)]
    pub centroids: Vec<AttachmentFile>,
    /// Handles: `(region: …, point: false, path: [(0.0, (position: …, rotation: …,
    /// scale: …))], compliance: 0.0)` — a region's particles (a point handle: the one
    /// nearest its centre) moved along the path; `cleave deform` poses the body by them,
    /// `cleave run` drives it by them as attachments of `compliance`.
    #[serde(default)]
    pub handles: Vec<HandleFile>,
    /// Explicit shape-matching groups (oriented model): `(region: (min: …, max: …),
    /// compliance: …)`, compliance in 1/Pa (0: a rigid part). Particles in two or more
    /// groups turn freely: a joint.
    #[serde(default)]
    pub groups: Vec<RegionCompliance>,
    /// Regions whose particles take their own compliance (1/Pa) instead of the
    /// material's, in the groups' form: `(region: …, compliance: …)`.
    #[serde(default)]
    pub stiffness_regions: Vec<RegionCompliance>,
    /// A closed OBJ mesh (path relative to the scene file, in the shape's local frame)
    /// drawn instead of the lattice's surface: `render_mesh: Some("part.obj")`. A body
    /// whose shape is a mesh draws that mesh without it.
    #[serde(default)]
    pub render_mesh: Option<std::path::PathBuf>,
    /// How the lattice's surface is drawn: `surface: (smooth: true)`.
    #[serde(default)]
    pub surface: SurfaceFile,
    /// Largest random displacement of each particle from its lattice place when
    /// spawned, in lattice spacings (0–0.5): a body out of its rest shape.
    #[serde(default, deserialize_with = "super::check::jitter")]
    pub jitter: f32,
}

/// How a body's lattice surface is drawn.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SurfaceFile {
    /// Round the voxel staircase (rest space, once per topology change).
    #[serde(default)]
    pub smooth: bool,
}

/// A world-space region (after placement) with a compliance in 1/Pa: an explicit group
/// or a stiffness region.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionCompliance {
    /// The region (it must hold at least one of the body's particles).
    #[serde(deserialize_with = "super::check::region")]
    pub region: Region,
    /// Compliance `1/E` in 1/Pa (0–1; 0: rigid).
    #[serde(deserialize_with = "super::check::compliance")]
    pub compliance: f32,
}

impl RegionCompliance {
    /// The file form of a region and its compliance.
    pub fn new(region: Region, compliance: f32) -> Self {
        Self { region, compliance }
    }
}

impl From<RegionCompliance> for GroupDesc {
    fn from(r: RegionCompliance) -> Self {
        GroupDesc {
            region: r.region,
            compliance: r.compliance,
        }
    }
}

impl From<RegionCompliance> for StiffnessRegion {
    fn from(r: RegionCompliance) -> Self {
        StiffnessRegion {
            region: r.region,
            compliance: r.compliance,
        }
    }
}

/// An attachment: the particles in a world-space region (after placement), each held
/// by a spring of `compliance` (m/N; 0: hard) to a target that follows `path` (empty:
/// stays).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttachmentFile {
    /// The region whose particles are attached (it must hold at least one).
    #[serde(deserialize_with = "super::check::region")]
    pub region: Region,
    /// Keyframes `(time, pose)` of the target, strictly ascending times.
    #[serde(default, deserialize_with = "super::check::keys")]
    pub path: Vec<(f32, Pose)>,
    /// Compliance of each particle's spring, m/N (≥ 0; 0: hard).
    #[serde(deserialize_with = "super::check::attachment_compliance")]
    pub compliance: f32,
}

/// A handle (see [`crate::ecs::desc::HandleDesc`]).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandleFile {
    /// The region whose particles the handle moves (it must hold at least one).
    #[serde(deserialize_with = "super::check::region")]
    pub region: Region,
    /// One particle (the nearest the region's centre) instead of the region.
    #[serde(default)]
    pub point: bool,
    /// Keyframes `(time, key)`, strictly ascending times.
    #[serde(default, deserialize_with = "super::check::handle_keys")]
    pub path: Vec<(f32, HandleKey)>,
    /// Compliance of each particle's spring while simulating, m/N (≥ 0; 0: hard).
    #[serde(default, deserialize_with = "super::check::attachment_compliance")]
    pub compliance: f32,
}

/// A shape.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ShapeFile {
    /// Exactly `cells` lattice points per axis, centred on the origin.
    Cells {
        /// Cells per axis.
        #[serde(deserialize_with = "super::check::cells")]
        cells: UVec3,
    },
    /// An axis-aligned box.
    Box {
        /// Half size per axis.
        #[serde(deserialize_with = "super::check::sizes")]
        half_extents: Vec3,
    },
    /// A ball.
    Sphere {
        /// Radius.
        #[serde(deserialize_with = "super::check::size")]
        radius: f32,
    },
    /// A capsule along X.
    Capsule {
        /// Radius.
        #[serde(deserialize_with = "super::check::size")]
        radius: f32,
        /// Half length of the shaft.
        #[serde(deserialize_with = "super::check::size_or_zero")]
        half_length: f32,
    },
    /// A solid cylinder along Z.
    Cylinder {
        /// Radius.
        #[serde(deserialize_with = "super::check::size")]
        radius: f32,
        /// Half its length along Z.
        #[serde(deserialize_with = "super::check::size")]
        half_length: f32,
    },
    /// A closed triangle mesh from an OBJ file (relative to the scene file).
    Mesh {
        /// The OBJ file.
        path: String,
    },
    /// The union of shapes, each placed at its offset (no `Cells` among them).
    Union {
        /// The parts.
        parts: Vec<ShapePartFile>,
    },
}

/// One part of a [`ShapeFile::Union`].
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapePartFile {
    /// The part's shape.
    pub shape: ShapeFile,
    /// Where its local origin sits in the union's frame.
    #[serde(deserialize_with = "super::check::coordinates")]
    pub at: Vec3,
}

/// A tool.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolFile {
    /// Shape: `Sphere(radius)`, `Capsule(radius, half_length)` or
    /// `Blade(half_width, half_height)`.
    #[serde(deserialize_with = "super::check::tool_shape")]
    pub shape: ToolShape,
    /// Width of the cut zone.
    #[serde(deserialize_with = "super::check::size")]
    pub cut_width: f32,
    /// What the tool does where it passes: `"remove"` (the default), `"sever"` or
    /// `"split"`.
    #[serde(default)]
    pub cut_mode: CutMode,
    /// Keyframes `(time in seconds, pose)`, strictly ascending, at most 1e4 m/s between
    /// keys; empty: the tool stays at `pose`.
    #[serde(default, deserialize_with = "super::check::keys")]
    pub path: Vec<(f32, Pose)>,
    /// Pose before the path starts (default: the first key's).
    #[serde(default, deserialize_with = "super::check::pose")]
    pub pose: Option<Pose>,
}

/// A collider.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColliderFile {
    /// Shape: `Box(half_extents)`, `Sphere(radius)`, `Capsule(radius, half_length)`
    /// (along local X) or `Mesh(path, resolution)` (a closed OBJ mesh).
    #[serde(deserialize_with = "super::check::collider_shape")]
    pub shape: ColliderShapeFile,
    /// Coulomb friction coefficient.
    #[serde(
        default = "default_collider_friction",
        deserialize_with = "super::check::friction"
    )]
    pub friction: f32,
    /// Keyframes `(time in seconds, pose)`, strictly ascending, at most 1e4 m/s between
    /// keys; empty: the collider is static.
    #[serde(default, deserialize_with = "super::check::keys")]
    pub path: Vec<(f32, Pose)>,
    /// Pose before the path starts (default: the first key's).
    #[serde(default, deserialize_with = "super::check::pose")]
    pub pose: Option<Pose>,
}

fn default_collider_friction() -> f32 {
    0.5
}

fn default_mesh_resolution() -> u32 {
    64
}

/// A collider's shape in a scene file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ColliderShapeFile {
    /// A box with the given half size per local axis.
    Box {
        /// Half size per axis.
        half_extents: Vec3,
    },
    /// A ball.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// A capsule along the local X axis.
    Capsule {
        /// Radius.
        radius: f32,
        /// Half length of the shaft.
        half_length: f32,
    },
    /// A closed triangle mesh from an OBJ file (relative to the scene file), in the
    /// collider's frame.
    Mesh {
        /// The OBJ file.
        path: String,
        /// Cells of its sampled distance along its longest axis (4–256).
        #[serde(
            default = "default_mesh_resolution",
            deserialize_with = "super::check::mesh_resolution"
        )]
        resolution: u32,
    },
}
