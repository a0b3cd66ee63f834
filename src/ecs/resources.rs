//! ECS resources: settings, RNG, clock, the detect → cut → regroup → split → expand
//! hand-over buffers, the solver cache, statistics, and the messages sent to outside code.

use crate::config::SimConfig;
use crate::solver::particles::Particles;
use crate::solver::registry::Terms;
use crate::solver::solve::Solver;
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

/// What detect keeps from frame to frame: its conservative culling (see
/// [`crate::cut::culling`]) and how long it took. Written by detect only.
#[derive(Resource, Clone, Debug, Default)]
pub struct DetectCulling {
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

/// The solver and the particles' dense state, and the maps between them and the ECS.
/// The cluster layout is rebuilt only when bodies appear or vanish, and patched after a
/// cut; within a frame the dense arrays hold the particles' state (see
/// [`crate::solver::particles`]).
#[derive(Resource, Debug)]
pub struct SolverCache {
    /// The particles' dense state.
    pub particles: Particles,
    /// The clusters, the other terms and the schemes' state.
    pub solver: Solver,
    /// Particle entity per dense index.
    pub entities: Vec<Entity>,
    /// Body-local particle index per dense index (the body: see [`SolverCache::owner`]).
    pub locals: Vec<u32>,
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
    pub slot_of: ClusterSlots,
    /// Solver slot ↔ row of the particle table, for the parallel load and store.
    pub rows: crate::ecs::table_rows::TableRows,
    /// Whether the layout matches the current topology.
    pub valid: bool,
    /// How the layout was last brought up to date, and how long it took.
    pub last_update: Option<LayoutUpdate>,
    /// Set when a saved simulation is loaded: the layout matches the loaded entities,
    /// which the next layout update only takes note of instead of patching them in.
    pub adopt_changes: bool,
    /// What changed in the layout since the terms last heard of it.
    pub pending_topology: Option<PendingTopology>,
    /// Counts the layout's rebuilds (a patch keeps every particle's dense index): tables
    /// derived from the dense indices are rebuilt when it changes.
    pub layout_version: u64,
}

/// What changed in the solver layout since the terms last heard (they hear of it in
/// [`crate::systems::term_sync`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PendingTopology {
    /// Whether the layout was laid out afresh (every dense index moved).
    pub relaid: bool,
    /// The bodies whose particles or links changed.
    pub bodies: Vec<Entity>,
}

impl Default for SolverCache {
    fn default() -> Self {
        SolverCache {
            particles: Particles::default(),
            solver: Solver::new(Default::default(), Terms::builtin()),
            entities: Vec::new(),
            locals: Vec::new(),
            dense_of: Vec::new(),
            live: Vec::new(),
            body_dense: Vec::new(),
            clusters: Vec::new(),
            slot_of: ClusterSlots::default(),
            rows: Default::default(),
            valid: false,
            last_update: None,
            adopt_changes: false,
            pending_topology: None,
            layout_version: 0,
        }
    }
}

/// The layout slot of each cluster entity, as a table by entity index: a lookup is two
/// array reads where a hash map costs a hash and a probe (the layout patch looks up every
/// cluster of every particle a cut touched). A slot is only reported for the entity that
/// holds it, checked against the layout's entity per slot, so an index reused by another
/// entity never finds a stale slot.
#[derive(Clone, Debug, Default)]
pub struct ClusterSlots {
    by_index: Vec<u32>,
}

impl ClusterSlots {
    /// The table of `clusters` (the entity per slot; placeholders are skipped).
    pub fn from_clusters(clusters: &[Entity]) -> Self {
        let mut slots = Self::default();
        for (k, e) in clusters.iter().enumerate() {
            if *e != Entity::PLACEHOLDER {
                slots.insert(*e, k as u32);
            }
        }
        slots
    }

    /// The slot of `e`, given the entity per slot.
    #[inline]
    pub fn get(&self, e: Entity, clusters: &[Entity]) -> Option<u32> {
        let slot = *self.by_index.get(e.index_u32() as usize)?;
        (clusters.get(slot as usize) == Some(&e)).then_some(slot)
    }

    /// Records that `e` holds `slot` (the caller records `e` as the entity of `slot`).
    pub fn insert(&mut self, e: Entity, slot: u32) {
        let i = e.index_u32() as usize;
        if self.by_index.len() <= i {
            self.by_index.resize(i + 1, u32::MAX);
        }
        self.by_index[i] = slot;
    }

    /// Forgets the slot of `e` and returns it, given the entity per slot.
    pub fn remove(&mut self, e: Entity, clusters: &[Entity]) -> Option<u32> {
        let slot = self.get(e, clusters)?;
        self.by_index[e.index_u32() as usize] = u32::MAX;
        Some(slot)
    }
}

impl SolverCache {
    /// The body and body-local index of dense particle `d` (see [`dense_owner`]).
    pub fn owner(&self, d: usize) -> Option<(Entity, u32)> {
        dense_owner(&self.locals, &self.body_dense, d)
    }
}

/// The body and body-local index of dense particle `d`, given the cache's
/// [`SolverCache::locals`] and [`SolverCache::body_dense`]. Each body's particles hold
/// one range of dense indices, the bodies in entity order, so the body is found by a
/// binary search over the ranges' starts rather than stored per particle.
pub fn dense_owner(locals: &[u32], body_dense: &[BodyDense], d: usize) -> Option<(Entity, u32)> {
    let local = *locals.get(d)?;
    let b = body_dense.partition_point(|b| b.first as usize <= d);
    Some((body_dense.get(b.checked_sub(1)?)?.body, local))
}

/// One body's particles in the solver layout.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BodyDense {
    /// The body.
    pub body: Entity,
    /// The body's first dense index: its particles are `first..first + n`.
    pub first: u32,
    /// Dense particle index per body-local particle index (`u32::MAX` if none).
    pub dense: Vec<u32>,
    /// How many of the body's particles are live in the layout.
    pub live: usize,
}

impl BodyDense {
    /// The dense slot of body-local particle `p`, if it has one.
    pub fn slot(&self, p: u32) -> Option<usize> {
        self.dense
            .get(p as usize)
            .filter(|d| **d != u32::MAX)
            .map(|d| *d as usize)
    }

    /// The position of body-local particle `p` in the dense `positions` (NaN when it
    /// has no slot).
    pub fn position(&self, positions: &[glam::Vec3A], p: u32) -> glam::Vec3 {
        self.slot(p)
            .and_then(|d| positions.get(d))
            .map_or(glam::Vec3::NAN, |x| glam::Vec3::from(*x))
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cluster_slots_never_report_a_slot_to_a_reused_entity_index() {
        let mut world = World::new();
        let (a, b) = (world.spawn_empty().id(), world.spawn_empty().id());
        let mut clusters = vec![a, Entity::PLACEHOLDER, b];
        let mut slots = ClusterSlots::from_clusters(&clusters);
        assert_eq!(slots.get(a, &clusters), Some(0));
        assert_eq!(slots.get(b, &clusters), Some(2));
        // `a` despawned without its slot being freed: a later entity on its index (a new
        // generation) is not `a`
        let c = Entity::from_index_and_generation(a.index(), a.generation().after_versions(1));
        assert_eq!(slots.get(c, &clusters), None);
        // moved to slot 1; removing it forgets it, and only it
        clusters[1] = c;
        slots.insert(c, 1);
        assert_eq!(slots.get(c, &clusters), Some(1));
        assert_eq!(slots.remove(c, &clusters), Some(1));
        assert_eq!(slots.get(c, &clusters), None);
        assert_eq!(slots.remove(a, &clusters), None);
        assert_eq!(slots.get(b, &clusters), Some(2));
    }

    #[test]
    fn owners_are_found_from_the_bodies_dense_ranges() {
        let mut world = World::new();
        let (a, b, c) = (
            world.spawn_empty().id(),
            world.spawn_empty().id(),
            world.spawn_empty().id(),
        );
        let body = |body, first| BodyDense {
            body,
            first,
            dense: Vec::new(),
            live: 0,
        };
        // a: dense 0..3, b: none, c: 3..5
        let cache = SolverCache {
            locals: vec![7, 0, 2, 4, 1],
            body_dense: vec![body(a, 0), body(b, 3), body(c, 3)],
            ..Default::default()
        };
        let owners: Vec<_> = (0..6).map(|d| cache.owner(d)).collect();
        assert_eq!(
            owners,
            [
                Some((a, 7)),
                Some((a, 0)),
                Some((a, 2)),
                Some((c, 4)),
                Some((c, 1)),
                None
            ]
        );
    }
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
