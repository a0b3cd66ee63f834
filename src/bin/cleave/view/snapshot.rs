//! One frame of `cleave view` as the pages get it: the status (counters, the scene's
//! colliders and tools, per-body centroids) as JSON, the surfaces' positions as a
//! binary message, and their topology as another, re-encoded only when a body's
//! topology version or the scene changed.

use axum::body::Bytes;
use bevy_ecs::prelude::*;
use cleave::cut::tool::{Pose, ToolShape};
use cleave::ecs::components::{
    BodyLattice, ClusterMembers, Collider, ColliderPose, Tool, ToolPose,
};
use cleave::ecs::resources::SimClock;
use cleave::ecs::surface_mesh::SurfaceMesh;
use cleave::geometry::collider::ColliderShape;
use cleave::io::stream::{StreamedSurface, encode_positions, encode_topology};
use cleave::sim::simulation::Simulation;
use serde_json::{Value, json};

/// A published frame.
#[derive(Clone, Debug, Default)]
pub struct Published {
    /// The status, JSON.
    pub status: String,
    /// Which topology the positions need: changes with any body's topology version and
    /// with every scene load.
    pub topology_key: Vec<u64>,
    /// The topology message.
    pub topology: Bytes,
    /// The positions message.
    pub positions: Bytes,
}

/// The viewer's settings that go into the status.
pub struct Settings<'a> {
    /// Scene loads so far.
    pub epoch: u64,
    /// Name of the running scene.
    pub scene: &'a str,
    /// Names of every offered scene.
    pub scenes: &'a [&'a str],
    /// Whether the simulation runs.
    pub playing: bool,
    /// Cut mode of strokes.
    pub cut_mode: &'a str,
    /// Whether the scene's own tools run.
    pub scripted_tools: bool,
    /// Wall time per frame (running mean), ms.
    pub ms_per_step: f64,
}

/// The frame `sim` is at; `last` is the frame published before it, whose topology
/// message is reused when nothing changed.
pub fn take(sim: &mut Simulation, settings: Settings, last: Option<&Published>) -> Published {
    let bodies = sim.bodies();
    let world = sim.world();
    let meshes: Vec<&SurfaceMesh> = bodies
        .iter()
        .filter_map(|&b| world.get::<SurfaceMesh>(b))
        .collect();
    let surfaces: Vec<StreamedSurface> = meshes
        .iter()
        .map(|m| StreamedSurface {
            version: m.topology_version,
            positions: &m.positions,
            triangles: m.triangles(),
            pieces: m.triangle_pieces(),
        })
        .collect();
    let mut topology_key = vec![settings.epoch];
    topology_key.extend(meshes.iter().map(|m| m.topology_version));
    let topology = match last {
        Some(last) if last.topology_key == topology_key => last.topology.clone(),
        _ => Bytes::from(encode_topology(&surfaces)),
    };
    let clock = world
        .get_resource::<SimClock>()
        .copied()
        .unwrap_or_default();
    let positions = Bytes::from(encode_positions(clock.frame, &surfaces));
    let status = status(sim, &bodies, &settings, clock).to_string();
    Published {
        status,
        topology_key,
        topology,
        positions,
    }
}

fn status(sim: &Simulation, bodies: &[Entity], settings: &Settings, clock: SimClock) -> Value {
    let world = sim.world();
    let mut body_status = Vec::new();
    let (mut particles, mut pieces) = (0, 0);
    for &b in bodies {
        let Some(lattice) = world.get::<BodyLattice>(b) else {
            continue;
        };
        particles += lattice.lattice.live_count();
        pieces += lattice.pieces;
        let centroid = sim.centroid(b).map(|c| c.to_array()).ok();
        body_status.push(json!({
            "particles": lattice.lattice.live_count(),
            "pieces": lattice.pieces,
            "centroid": centroid,
        }));
    }
    let mut clusters = 0;
    let mut colliders = Vec::new();
    let config = sim.config();
    for b in &config.boxes {
        colliders.push(json!({
            "shape": {"kind": "box", "half_extents": (0.5 * (b.max - b.min)).to_array()},
            "pose": pose(&Pose::at(0.5 * (b.min + b.max))),
        }));
    }
    let mut tools = Vec::new();
    // one pass over the entities for the clusters, colliders and tools
    for e in world.iter_entities() {
        clusters += usize::from(e.contains::<ClusterMembers>());
        if let (Some(c), Some(p)) = (e.get::<Collider>(), e.get::<ColliderPose>()) {
            colliders.push(json!({"shape": collider_shape(&c.shape), "pose": pose(&p.current)}));
        }
        if let (Some(t), Some(p)) = (e.get::<Tool>(), e.get::<ToolPose>()) {
            tools.push(json!({"shape": tool_shape(&t.shape), "pose": pose(&p.current)}));
        }
    }
    json!({
        "type": "status",
        "frame": clock.frame,
        "time": clock.time,
        "epoch": settings.epoch,
        "scene": settings.scene,
        "scenes": settings.scenes,
        "playing": settings.playing,
        "cut_mode": settings.cut_mode,
        "scripted_tools": settings.scripted_tools,
        "ms_per_step": settings.ms_per_step,
        "particles": particles,
        "clusters": clusters,
        "pieces": pieces,
        "bodies": body_status,
        "ground": config.ground.map(|g| g.height),
        "colliders": colliders,
        "tools": tools,
        "stopped": null,
    })
}

fn pose(p: &Pose) -> Value {
    json!({"position": p.position.to_array(), "rotation": p.rotation.to_array()})
}

fn collider_shape(shape: &ColliderShape) -> Value {
    match shape {
        ColliderShape::Box { half_extents } => {
            json!({"kind": "box", "half_extents": half_extents.to_array()})
        }
        ColliderShape::Sphere { radius } => json!({"kind": "sphere", "radius": radius}),
        ColliderShape::Capsule {
            radius,
            half_length,
        } => json!({"kind": "capsule", "radius": radius, "half_length": half_length}),
        ColliderShape::Mesh(_) => json!({"kind": "mesh"}),
    }
}

fn tool_shape(shape: &ToolShape) -> Value {
    match *shape {
        ToolShape::Sphere { radius } => json!({"kind": "sphere", "radius": radius}),
        ToolShape::Capsule {
            radius,
            half_length,
        } => json!({"kind": "capsule", "radius": radius, "half_length": half_length}),
        ToolShape::Blade {
            half_width,
            half_height,
        } => json!({"kind": "blade", "half_width": half_width, "half_height": half_height}),
    }
}
