//! ECS resources: settings, RNG, clock, the detect → cut → regroup → split → expand
//! hand-over buffers, the solver cache, statistics, and the messages sent to outside code.

use crate::config::SimConfig;
use crate::solver::SolverLayout;
use bevy_ecs::prelude::*;
use rand_chacha::ChaCha8Rng;

/// The simulation settings.
#[derive(Resource, Clone, Debug, Default)]
pub struct SimSettings(pub SimConfig);

/// The one seeded random stream used by every stage (portable ChaCha8).
#[derive(Resource, Clone, Debug)]
pub struct SimRng(pub ChaCha8Rng);

/// Frame counter and simulated time.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct SimClock {
    /// Frames completed.
    pub frame: u64,
    /// Simulated seconds.
    pub time: f32,
}

/// Particles to cut in one body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyCut {
    /// The body.
    pub body: Entity,
    /// Body-local particle indices, ascending.
    pub particles: Vec<u32>,
}

/// Output of detect (its only output), input of cut.
#[derive(Resource, Clone, Debug, Default)]
pub struct CutList {
    /// Per body, sorted by body entity.
    pub cuts: Vec<BodyCut>,
}

/// What cut did to one body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyCutReport {
    /// The body.
    pub body: Entity,
    /// Removed particle indices.
    pub removed: Vec<u32>,
    /// Clusters that contained a removed particle, sorted.
    pub cut_clusters: Vec<Entity>,
}

/// Output of cut, input of regroup.
#[derive(Resource, Clone, Debug, Default)]
pub struct CutReport {
    /// One entry per body that lost particles this frame.
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
    /// Clusters produced by regroup, then by split.
    pub clusters: Vec<Entity>,
    /// Edges the splits separated (see [`crate::reconstruct::SplitOutcome`]).
    pub cut_edges: Vec<(u32, u32)>,
}

/// Dense solver state kept between steps; rebuilt only when topology changes.
#[derive(Resource, Debug, Default)]
pub struct SolverCache {
    /// Dense arrays.
    pub layout: SolverLayout,
    /// Particle entity per dense index.
    pub particles: Vec<Entity>,
    /// `(body, local index)` per dense index.
    pub owners: Vec<(Entity, u32)>,
    /// Dense index per entity index (`u32::MAX` if none).
    pub dense_of: Vec<u32>,
    /// Whether each dense particle is still in its body (cut particles keep their
    /// dense slot, frozen, until the next full rebuild).
    pub live: Vec<bool>,
    /// Each body's particles in the layout, by body.
    pub body_dense: Vec<BodyDense>,
    /// Cluster entity per cluster slot of the layout (`Entity::PLACEHOLDER` if free).
    pub clusters: Vec<Entity>,
    /// Cluster slot per cluster entity.
    pub slot_of: rustc_hash::FxHashMap<Entity, u32>,
    /// Solver slot ↔ row of the particle table, for the parallel gather and scatter.
    pub rows: crate::table_rows::TableRows,
    /// Whether the layout matches the current topology.
    pub valid: bool,
    /// How the layout was last brought up to date, and how long it took.
    pub last_update: Option<LayoutUpdate>,
}

/// One body's particles in the solver layout.
#[derive(Clone, Debug)]
pub struct BodyDense {
    /// The body.
    pub body: Entity,
    /// Dense particle index per body-local particle index (`u32::MAX` if none).
    pub dense: Vec<u32>,
    /// How many of the body's particles are live in the layout.
    pub live: usize,
}

/// One update of the solver layout after a topology change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayoutUpdate {
    /// True when only the changed clusters were patched in; false for a full rebuild.
    pub patched: bool,
    /// Wall-clock milliseconds it took.
    pub ms: f64,
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
