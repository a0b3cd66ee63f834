//! The built-in scenes of oriented particles (SPEC §5): `rod` (a 24×1×1 rod clamped at
//! its root, which the cluster model cannot hold out), `sheet` (24×24×1 clamped along one
//! edge).

use crate::body::shape::Shape;
use crate::config::{Material, Model, SimConfig};
use crate::ecs::desc::{BodyDesc, PinRegion, Scene};
use glam::{UVec3, Vec3};

/// Lattice spacing of the scenes (metres).
const H: f32 = 0.1;

/// Rigid groups of the oriented model: every group keeps its rest shape.
pub fn rigid_oriented() -> Material {
    Material {
        model: Model::Oriented,
        ..Material::rigid()
    }
}

/// The cantilever's settings: no ground, 20 iterations, damping 2/s.
fn cantilever_config(config: SimConfig) -> SimConfig {
    SimConfig {
        ground: None,
        iterations: 20,
        damping: 2.0,
        ..config
    }
}

/// A body of `cells`, rigid groups of the oriented model, centred at height 1 m, with the
/// particles of its first `deep` columns along x pinned (its left end at x = −1.2).
fn clamped(cells: UVec3, deep: f32) -> BodyDesc {
    let mut body = BodyDesc::new(Shape::cuboid(cells), H);
    body.position = Vec3::new(0.0, 1.0, 0.0);
    body.material = rigid_oriented();
    body.pins = vec![PinRegion {
        min: Vec3::new(-1.3, -1.0, -2.0),
        max: Vec3::new(-1.2 + deep * H, 3.0, 2.0),
        ..PinRegion::default()
    }];
    body
}

/// `rod`: the cantilever's beam made 24×1×1, its first two particles pinned, rigid groups
/// of the oriented model: it holds out where the cluster model's rod hangs.
pub fn rod_scene(config: SimConfig) -> Scene {
    Scene {
        config: cantilever_config(config),
        bodies: vec![clamped(UVec3::new(24, 1, 1), 2.0)],
        tools: vec![],
        colliders: vec![],
        frames: 600,
    }
}

/// `sheet`: the cantilever's beam made 24×24×1 — a sheet standing in the xy plane —
/// clamped two particles deep along its left edge, rigid groups of the oriented model:
/// it holds out where the cluster model's sheet, whose clusters are all flat, folds out
/// of its plane like cloth.
pub fn sheet_scene(config: SimConfig) -> Scene {
    Scene {
        config: cantilever_config(config),
        bodies: vec![clamped(UVec3::new(24, 24, 1), 2.0)],
        tools: vec![],
        colliders: vec![],
        frames: 600,
    }
}
