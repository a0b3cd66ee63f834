//! The state dump (`cleave-state/1`, JSON): particles with lattice coordinates and
//! positions, live lattice edges, clusters. Ids are entity bits, stable within a run.

use crate::components::*;
use bevy_ecs::prelude::*;
use serde::{Deserialize, Serialize};

/// One particle in the dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpParticle {
    /// Stable id.
    pub id: u64,
    /// Lattice coordinate.
    pub lattice: [i32; 3],
    /// Position.
    pub position: [f32; 3],
}

/// One cluster in the dump.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpCluster {
    /// Stable id.
    pub id: u64,
    /// Member particle ids.
    pub members: Vec<u64>,
}

/// Dumped configuration.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DumpConfig {
    /// Largest allowed cluster.
    pub max_cluster_size: u32,
}

/// The whole dump of one body.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StateDump {
    /// Always `cleave-state/1`.
    pub format: String,
    /// Lattice spacing h.
    pub spacing: f32,
    /// Configuration needed to check invariants.
    pub config: DumpConfig,
    /// Live particles.
    pub particles: Vec<DumpParticle>,
    /// Live lattice edges as id pairs.
    pub edges: Vec<[u64; 2]>,
    /// Clusters.
    pub clusters: Vec<DumpCluster>,
}

/// Dumps one body, or `None` if `body` is not a body.
pub fn dump_body(world: &mut World, body: Entity) -> Option<StateDump> {
    let material = world.get::<Body>(body)?.material.clone();
    let lattice = world.get::<BodyLattice>(body)?.clone();
    let l = &lattice.lattice;
    let id = |i: u32| lattice.particles[i as usize].to_bits();
    let particles = l
        .live_particles()
        .map(|i| DumpParticle {
            id: id(i),
            lattice: l.coord(i).to_array(),
            position: world
                .get::<Position>(lattice.particles[i as usize])
                .map_or([f32::NAN; 3], |p| p.0.to_array()),
        })
        .collect();
    let edges = l.edges().into_iter().map(|(a, b)| [id(a), id(b)]).collect();
    let mut clusters: Vec<DumpCluster> = world
        .query::<(Entity, &ClusterMembers, &ClusterOf)>()
        .iter(world)
        .filter(|(_, _, of)| of.0 == body)
        .map(|(e, m, _)| DumpCluster {
            id: e.to_bits(),
            members: m.0.iter().map(|i| id(*i)).collect(),
        })
        .collect();
    clusters.sort_by_key(|c| c.id);
    Some(StateDump {
        format: "cleave-state/1".into(),
        spacing: l.spacing(),
        config: DumpConfig {
            max_cluster_size: material.max_cluster_size,
        },
        particles,
        edges,
        clusters,
    })
}
