//! ECS resources: settings, RNG, clock, the detect → cut → regroup → split → expand
//! hand-over buffers, statistics, and the messages sent to outside code.

use crate::config::SimConfig;
use bevy_ecs::prelude::*;
use glam::Vec3;
use rand_chacha::ChaCha8Rng;

/// The simulation settings.
#[derive(Resource, Clone, Debug, Default)]
pub struct SimSettings(pub SimConfig);

/// The one seeded random stream used by every stage (portable ChaCha8).
#[derive(Resource, Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct SimRng(pub ChaCha8Rng);

/// What the simulation is a run of (a scene's name or file, say), as its maker labelled
/// it: kept in saves, so that a resumed run can say what it resumes.
#[derive(Resource, Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SceneLabel(pub Option<String>);

/// Frame counter and simulated time.
#[derive(Resource, Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SimClock {
    /// Frames completed.
    pub frame: u64,
    /// Simulated seconds (the sum of the frames' `dt`, in f64 so that it keeps
    /// advancing on long runs).
    pub time: f64,
}

/// Which substep of the frame is running (set by the frame schedule before each run of
/// the substep schedule), so that kinematic colliders are placed at the right time.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct SubstepClock {
    /// Substeps done in this frame.
    pub index: u32,
    /// Substeps per frame.
    pub count: u32,
}

/// What to cut in one body.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyCut {
    /// The body.
    pub body: Entity,
    /// Particles to remove (tools in [`crate::cut::tool::CutMode::Remove`]): body-local
    /// indices, ascending.
    pub particles: Vec<u32>,
    /// Edges blades in `Sever` mode cross, to sever: body-local `(a, b)` with `a < b`,
    /// ascending.
    pub edges: Vec<(u32, u32)>,
    /// Edges of voxels stretched past the material's `tear_stretch`, strongest first.
    pub torn: Vec<(u32, u32)>,
    /// What `split` blades do: the particles they split and the edges they cross that no
    /// split takes, to sever.
    pub splits: crate::cut::particle_split::SplitPlan,
    /// Particles inside a sphere or capsule in `sever` or `split` mode this frame, to
    /// carve ([`crate::cut::carve`]), ascending.
    pub carved: Vec<u32>,
    /// Edges such a tool's surface crosses with neither end inside it this frame, to
    /// sever unless both ends are carved: `(a, b)` with `a < b`, ascending.
    pub grazed: Vec<(u32, u32)>,
    /// Where the tools crossed the edges they separate or carve across (every edge of
    /// `edges`, `grazed` and `splits`, and those from a carved particle to one that is
    /// not), in the lattice's rest frame: `((a, b), crossing measured from a)` with
    /// `a < b`, ascending. The cut stage keeps those of the edges it cuts in the lattice.
    pub crossings: Vec<((u32, u32), crate::body::crossings::Crossing)>,
}

impl BodyCut {
    /// Where the tools crossed the edge between `a` and `b`, measured from `a`.
    pub fn crossing(&self, a: u32, b: u32) -> Option<crate::body::crossings::Crossing> {
        let k = self
            .crossings
            .binary_search_by_key(&(a.min(b), a.max(b)), |(e, _)| *e)
            .ok()?;
        let c = self.crossings[k].1;
        Some(if a < b { c } else { c.reversed() })
    }

    /// The entry of `cuts` for `body`, added empty when missing (found at once when the
    /// last entry is the body's, as it is for particles listed in body order).
    pub fn entry(cuts: &mut Vec<BodyCut>, body: Entity) -> &mut BodyCut {
        let k = match cuts.iter().rposition(|c| c.body == body) {
            Some(k) => k,
            None => {
                cuts.push(BodyCut {
                    body,
                    particles: Vec::new(),
                    edges: Vec::new(),
                    torn: Vec::new(),
                    splits: Default::default(),
                    carved: Vec::new(),
                    grazed: Vec::new(),
                    crossings: Vec::new(),
                });
                cuts.len() - 1
            }
        };
        &mut cuts[k]
    }
}

/// What detect keeps from frame to frame: the blocks it tests the dense particles in
/// (see [`crate::cut::blocks`]), its conservative culling (see
/// [`crate::cut::culling`]) and how long it took. Written by detect only.
#[derive(Resource, Clone, Debug, Default)]
pub struct DetectCulling {
    /// The blocks of the solver layout's dense particles.
    pub blocks: crate::cut::blocks::Blocks,
    /// The layout version the blocks were made for (`None`: none yet).
    pub blocks_for: Option<u64>,
    /// The culling memory.
    pub culling: crate::cut::culling::ToolCulling,
    /// Wall-clock milliseconds of the last frame's detection (for reports).
    pub last_ms: f64,
}

/// Output of detect (its only output besides its culling memory), input of cut.
#[derive(Resource, Clone, Debug, Default)]
pub struct CutList {
    /// Per body, sorted by body entity.
    pub cuts: Vec<BodyCut>,
}

/// What cut did to one body.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BodyCutReport {
    /// The body.
    pub body: Entity,
    /// Removed particle indices.
    pub removed: Vec<u32>,
    /// Severed edges `(a, b)`, `a < b` (by a tool or torn).
    pub severed: Vec<(u32, u32)>,
    /// Split particles: `(particle, its new half)`.
    pub splits: Vec<(u32, u32)>,
    /// Edges linked again between carved particles, `(a, b)` with `a < b`: no cluster
    /// covers them yet.
    pub relinked: Vec<(u32, u32)>,
    /// Keys of the clusters that contained a removed particle or both ends of a severed
    /// edge, ascending.
    pub cut_clusters: Vec<u32>,
}

/// Output of cut, input of regroup.
#[derive(Resource, Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct CutReport {
    /// One entry per body that lost particles or edges this frame.
    pub bodies: Vec<BodyCutReport>,
}

/// Clusters produced by the current cut event (regroup → split → expand hand-over).
#[derive(Resource, Clone, Debug, Default)]
pub struct RebuiltClusters {
    /// One entry per body with a cut event.
    pub bodies: Vec<RebuiltBody>,
}

/// The clusters one body's cut event has produced so far.
#[derive(Clone, Debug)]
pub struct RebuiltBody {
    /// The body.
    pub body: Entity,
    /// Keys of the clusters produced by regroup, then by split.
    pub clusters: Vec<u32>,
    /// Edges the splits separated (see [`crate::reconstruct::SplitOutcome`]).
    pub cut_edges: Vec<(u32, u32)>,
    /// Keys of the parts of the clusters split, which the expand stage grows.
    pub split_parts: Vec<u32>,
}

/// Wall-clock timings of cut events, for reports.
#[derive(Resource, Clone, Debug, Default)]
pub struct CutTimings {
    /// Milliseconds of regroup + split + expand per cut event.
    pub event_ms: Vec<f64>,
    /// Milliseconds accumulated by the current event so far.
    pub current_ms: f64,
}

/// Sent by cut: particles removed from a body.
#[derive(Message, Clone, Debug)]
pub struct ParticlesCut {
    /// The body.
    pub body: Entity,
    /// Removed body-local indices.
    pub particles: Vec<u32>,
}

/// Sent by cut: edges severed in a body by a `sever` or `split` tool, or torn.
#[derive(Message, Clone, Debug)]
pub struct EdgesSevered {
    /// The body.
    pub body: Entity,
    /// The edges a tool severed, `(a, b)` of body-local indices, `a < b`, ascending.
    pub edges: Vec<(u32, u32)>,
    /// The edges torn by strain, in the order they tore.
    pub torn: Vec<(u32, u32)>,
}

/// Sent by cut: particles a `split` blade split in two.
#[derive(Message, Clone, Debug)]
pub struct ParticlesSplit {
    /// The body.
    pub body: Entity,
    /// `(particle, its new half)` by body-local index.
    pub pairs: Vec<(u32, u32)>,
}

/// Sent by cut: splitting the particles `split` blades passed through in a body this
/// frame would have taken the body past its memory budget
/// ([`crate::config::SimConfig::memory_budget_gb`], estimated by
/// [`crate::ecs::budget::bytes_after_split`]), so they were not split: the blades severed
/// the edges the split would have handed to new halves, which leaves the pieces the split
/// would have made, less the new halves, and the body kept its particles.
#[derive(Message, Clone, Copy, Debug)]
pub struct SplitsOverBudget {
    /// The body.
    pub body: Entity,
    /// The particles that were not split.
    pub particles: usize,
    /// What the body would have taken once split, in bytes.
    pub bytes: u64,
    /// The body's memory budget, in bytes.
    pub budget: u64,
}

/// Sent by shape-match: particles whose position had become non-finite (a NaN written
/// from outside, say) were put back where they started the substep, with zero velocity,
/// before the NaN could spread through their clusters.
#[derive(Message, Clone, Debug)]
pub struct ParticlesRepaired {
    /// The body.
    pub body: Entity,
    /// The repaired body-local indices, ascending.
    pub particles: Vec<u32>,
}

/// Sent by expand: the clusters rebuilt by a cut event.
#[derive(Message, Clone, Debug)]
pub struct ClustersRebuilt {
    /// The body.
    pub body: Entity,
    /// Clusters created or changed.
    pub clusters: Vec<Entity>,
}

/// Sent by cut when a body's number of connected pieces changes.
#[derive(Message, Clone, Copy, Debug)]
pub struct BodySplit {
    /// The body.
    pub body: Entity,
    /// Pieces before the cut.
    pub pieces_before: usize,
    /// Pieces after the cut.
    pub pieces_after: usize,
}

/// Sent by stage wrench for each collider the particles touched in the frame, with its
/// [`crate::ecs::components::ColliderWrench`].
#[derive(Message, Clone, Copy, Debug)]
pub struct ColliderPushed {
    /// The collider.
    pub collider: Entity,
    /// Mean force over the frame (N).
    pub force: Vec3,
    /// Mean torque about its centre (N·m).
    pub torque: Vec3,
}

/// How large a change of one body's surface the surface stage makes within the frame.
/// A bigger one (a huge body diced at once) is rebuilt beside the frames that follow —
/// the body keeps drawing its last surface, carried by its particles, meanwhile — and
/// put in place `frames` frames after the change (the stage waits for it then, should it
/// not be done), so that no frame stalls for the whole rebuild and a run shows the same
/// surface at the same frame however fast the machine. The stage says so with a
/// [`SurfaceDeferred`]. Not saved: a save taken meanwhile holds the last surface, and the
/// run it resumes rebuilds it in its first frame.
#[derive(Resource, Clone, Copy, Debug, PartialEq)]
pub struct SurfaceBudget {
    /// Quads of surface (an estimate: the faces a local update rebuilds, or the whole
    /// surface for an extraction) above which a rebuild is spread over frames.
    pub quads: usize,
    /// Frames after the change at which the rebuilt surface is put in place (at least
    /// 1).
    pub frames: u64,
}

impl Default for SurfaceBudget {
    /// A change of up to 200 000 quads (the whole surface of a box 180 cells wide)
    /// within the frame; a bigger one put in place two frames later.
    fn default() -> Self {
        Self {
            quads: 200_000,
            frames: 2,
        }
    }
}

/// Sent by the surface stage when a body's surface change passes the
/// [`SurfaceBudget`]: the body draws its last surface until frame `due`.
#[derive(Message, Clone, Copy, Debug)]
pub struct SurfaceDeferred {
    /// The body.
    pub body: Entity,
    /// The estimated quads of the change.
    pub quads: usize,
    /// The frame at whose end the new surface is in place.
    pub due: u64,
}

/// Sent by the surface stage when a body's surface triangles change (its first surface,
/// and after every cut, split or tear that changed its links).
#[derive(Message, Clone, Copy, Debug)]
pub struct SurfaceChanged {
    /// The body.
    pub body: Entity,
    /// The surface's new [`crate::ecs::surface_mesh::SurfaceMesh::topology_version`].
    pub topology_version: u64,
}
