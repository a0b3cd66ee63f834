//! The state dump (`cleave-state/2`, JSON), the format other tools check the engine
//! with: the frame and time, then per body its spacing, the configuration an invariant
//! checker needs, its live particles (lattice coordinate, position, orientation, mass),
//! its shape-matching groups if it is of the oriented model, its live
//! lattice edges and its clusters. Ids are derived from the state, not from entities, so
//! that the same state dumps to the same bytes however it was reached (straight, or
//! saved and loaded): a body's id is its rank among the bodies (entity order), a
//! particle's is [`particle_id`] of its body and body-local index (a split particle's
//! new half has an index of its own), a cluster's [`cluster_id`] of its body and key.
//! They are unique across the whole dump.

use crate::config::Model;
use crate::ecs::components::*;
use crate::ecs::resources::SimClock;
use crate::solver::term::BodyTopology;
use crate::solver::terms::oriented::groups::{BodyGroups, Turns};
use bevy_ecs::prelude::*;
use serde::{Deserialize, Serialize};

/// The dump's format tag.
pub const FORMAT: &str = "cleave-state/2";

/// Bits of an id above the body's rank.
const BODY_SHIFT: u32 = 40;

/// The bit that marks a cluster's id.
const CLUSTER_BIT: u64 = 1 << 39;

/// The dump id of particle `local` of the body of rank `body`.
pub fn particle_id(body: u64, local: u32) -> u64 {
    (body << BODY_SHIFT) | local as u64
}

/// The dump id of the cluster of key `key` of the body of rank `body`.
pub fn cluster_id(body: u64, key: u32) -> u64 {
    (body << BODY_SHIFT) | CLUSTER_BIT | key as u64
}

/// One particle in the dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpParticle {
    /// Stable id.
    pub id: u64,
    /// Lattice coordinate.
    pub lattice: [i32; 3],
    /// Position.
    pub position: [f32; 3],
    /// Orientation, a unit quaternion `[x, y, z, w]` (absent in dumps written before
    /// particles had one: identity).
    #[serde(default = "identity")]
    pub orientation: [f32; 4],
    /// Mass (also for a pinned particle, which the solver treats as immovable).
    pub mass: f32,
}

fn identity() -> [f32; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

/// One cluster in the dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpCluster {
    /// Stable id.
    pub id: u64,
    /// Member particle ids.
    pub members: Vec<u64>,
}

/// Dumped configuration of one body.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpConfig {
    /// Largest allowed cluster.
    pub max_cluster_size: u32,
    /// The body's model (`"clusters"` or `"oriented"`; absent in older dumps: clusters).
    #[serde(default)]
    pub model: Model,
}

/// One shape-matching group of a body of the oriented model, as its lattice gives them
/// now (the solver takes them up at the next frame's start).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpGroup {
    /// The particle an implicit group is centred on; `None` for a piece of an explicit
    /// group.
    pub centre: Option<u64>,
    /// Member particle ids, ascending.
    pub members: Vec<u64>,
}

/// One body in the dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpBody {
    /// Stable id (the body's rank).
    pub id: u64,
    /// Lattice spacing h.
    pub spacing: f32,
    /// Configuration needed to check invariants.
    pub config: DumpConfig,
    /// Live particles.
    pub particles: Vec<DumpParticle>,
    /// Live lattice edges as id pairs.
    pub edges: Vec<[u64; 2]>,
    /// Clusters, by id.
    pub clusters: Vec<DumpCluster>,
    /// Groups of the oriented model, implicit ones by centre, then explicit pieces
    /// (empty, and absent, for a body of the cluster model).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<DumpGroup>,
}

/// The whole dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StateDump {
    /// Always [`FORMAT`].
    pub format: String,
    /// Frames completed.
    pub frame: u64,
    /// Simulated seconds.
    pub time: f64,
    /// Every body, by id.
    pub bodies: Vec<DumpBody>,
}

/// Dumps every body of `world`.
pub fn dump_world(world: &mut World) -> StateDump {
    let clock = world
        .get_resource::<SimClock>()
        .copied()
        .unwrap_or_default();
    let mut bodies: Vec<Entity> = world
        .query_filtered::<Entity, (With<Body>, With<BodyLattice>)>()
        .iter(world)
        .collect();
    bodies.sort_unstable();
    StateDump {
        format: FORMAT.into(),
        frame: clock.frame,
        time: clock.time,
        bodies: bodies
            .into_iter()
            .enumerate()
            .filter_map(|(rank, b)| dump_body(world, b, rank as u64))
            .collect(),
    }
}

/// Dumps one body, of rank `rank` among the dump's bodies, or `None` if `body` is not a
/// body.
pub fn dump_body(world: &mut World, body: Entity, rank: u64) -> Option<DumpBody> {
    let material = world.get::<Body>(body)?.material.clone();
    let lattice = world.get::<BodyLattice>(body)?.clone();
    let l = &lattice.lattice;
    let id = |i: u32| particle_id(rank, i);
    let particles = l
        .live_particles()
        .map(|i| DumpParticle {
            id: id(i),
            lattice: l.coord(i).to_array(),
            position: world
                .get::<Position>(lattice.particles[i as usize])
                .map_or([f32::NAN; 3], |p| p.0.to_array()),
            orientation: world
                .get::<Orientation>(lattice.particles[i as usize])
                .map_or([f32::NAN; 4], |q| q.0.to_array()),
            // (a split particle's half has half the mass; one made kinematic by hand,
            // inverse mass 0, the material's)
            mass: match world.get::<InvMass>(lattice.particles[i as usize]) {
                Some(w) if w.0 > 0.0 => 1.0 / w.0,
                _ => material.mass_at_spacing(l.spacing()),
            },
        })
        .collect();
    let edges = l.edges().into_iter().map(|(a, b)| [id(a), id(b)]).collect();
    let mut clusters: Vec<DumpCluster> = world
        .query::<(&ClusterMembers, &ClusterOf)>()
        .iter(world)
        .filter(|(_, of)| of.body == body)
        .map(|(m, of)| DumpCluster {
            id: cluster_id(rank, of.key),
            members: m.0.iter().map(|i| id(*i)).collect(),
        })
        .collect();
    clusters.sort_by_key(|c| c.id);
    let groups = world
        .get::<Body>(body)
        .map(|b| dump_groups(b, &lattice, id))
        .unwrap_or_default();
    Some(DumpBody {
        id: rank,
        spacing: l.spacing(),
        config: DumpConfig {
            max_cluster_size: material.max_cluster_size,
            model: material.model,
        },
        particles,
        edges,
        clusters,
        groups,
    })
}

/// The groups of `body` as its lattice gives them now, members named by `id`.
fn dump_groups(body: &Body, lattice: &BodyLattice, id: impl Fn(u32) -> u64) -> Vec<DumpGroup> {
    let l = &lattice.lattice;
    let dense: Vec<u32> = (0..l.len() as u32).collect();
    let view = BodyTopology {
        id: 0,
        lattice: l,
        dense: &dense,
        material: &body.material,
        groups: &body.groups,
        pieces: lattice.pieces,
        changed: true,
    };
    let Some(built) = BodyGroups::build(&view) else {
        return Vec::new();
    };
    let mut out: Vec<DumpGroup> = built
        .groups
        .iter()
        .map(|g| {
            let mut members: Vec<u64> = built.members[built.range(g)]
                .iter()
                .map(|&m| id(m))
                .collect();
            members.sort_unstable();
            let centre = match g.turns {
                Turns::Centre(c) => Some(id(c)),
                Turns::All => None,
            };
            DumpGroup { centre, members }
        })
        .collect();
    // implicit groups by centre, explicit pieces after them in their order
    out.sort_by_key(|g| (g.centre.is_none(), g.centre));
    out
}
