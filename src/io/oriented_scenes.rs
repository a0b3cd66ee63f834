//! The built-in scenes of oriented particles (SPEC §5): `rod` (a 24×1×1 rod clamped at
//! its root, which the cluster model cannot hold out), `sheet` (24×24×1 clamped along one
//! edge), `wheel` (a rigid disc spinning on an axle: two explicit groups sharing the
//! axle's particles, a joint), `dent` (a plastic block pressed by a kinematic sphere),
//! and `truck` (its own module).

use crate::body::shape::Shape;
use crate::config::{Material, Model, SimConfig};
use crate::cut::tool::{Path, Pose};
use crate::ecs::desc::{BodyDesc, ColliderDesc, GroupDesc, PinRegion, Region, Scene};
use crate::geometry::collider::ColliderShape;
use glam::{UVec3, Vec3};

/// The oriented built-in scene `name` with `config`, or `None`.
pub fn builtin(name: &str, config: SimConfig) -> Option<Scene> {
    Some(match name {
        "rod" => rod_scene(config),
        "sheet" => sheet_scene(config),
        "wheel" => wheel_scene(config),
        "dent" => dent_scene(config),
        "truck" => crate::io::truck_scene::truck_scene(config),
        _ => return None,
    })
}

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

/// The wheel's lattice spacing (metres).
pub const WHEEL_H: f32 = 0.05;

/// The wheel's spin: two turns a second about +z.
pub const WHEEL_SPIN: f32 = 2.0 * std::f32::consts::TAU;

/// `wheel`: a disc 16 spacings across and 4 thick (a cylinder along z) at height 1 m,
/// spinning at two turns a second with gravity off. Two rigid explicit groups: the whole
/// disc, and its axle — the column of particles through its middle, pinned at both
/// ends. They share the axle's particles, which are then non-oriented: a joint about
/// which the disc turns freely. Ten turns in 300 frames.
pub fn wheel_scene(config: SimConfig) -> Scene {
    let h = WHEEL_H;
    let mut body = BodyDesc::new(
        Shape::Cylinder {
            radius: 8.0 * h,
            half_length: 2.0 * h,
        },
        h,
    );
    body.position = Vec3::new(0.0, 1.0, 0.0);
    body.angular_velocity = Vec3::new(0.0, 0.0, WHEEL_SPIN);
    body.material = rigid_oriented();
    // the column of lattice coordinate (0, 0): its particles at x = y = h/2 from the
    // disc's axis
    let axle = |z0: f32, z1: f32| Region {
        min: Vec3::new(0.0, 1.0, z0),
        max: Vec3::new(h, 1.0 + h, z1),
    };
    body.groups = vec![
        GroupDesc {
            region: Region {
                min: Vec3::splat(-10.0),
                max: Vec3::splat(10.0),
            },
            compliance: 0.0,
        },
        GroupDesc {
            region: axle(-1.0, 1.0),
            compliance: 0.0,
        },
    ];
    body.pins = [axle(-1.0, -1.5 * h), axle(1.5 * h, 1.0)]
        .map(|r| PinRegion {
            min: r.min,
            max: r.max,
            ..PinRegion::default()
        })
        .to_vec();
    Scene {
        config: SimConfig {
            gravity: Vec3::ZERO,
            ground: None,
            damping: 0.0,
            ..config
        },
        bodies: vec![body],
        tools: vec![],
        colliders: vec![],
        frames: 300,
    }
}

/// The dent's lattice spacing (metres).
pub const DENT_H: f32 = 0.05;

/// The height of the dent block's top particles' centres (metres).
pub const DENT_TOP: f32 = 0.3 - 0.5 * DENT_H;

/// How deep the dent scene's sphere presses below the block's top (metres).
pub const DENT_DEPTH: f32 = 3.0 * DENT_H;

/// `dent`: a 12×6×12 block of the oriented model resting on the ground, plastic (it
/// yields past a strain of 0.01 and creeps toward its deformed shape at the full rate),
/// pressed 3 spacings deep at the middle of its top by a kinematic sphere 8 spacings
/// across, held there for 1.5 s, then lifted away: the block keeps a dent.
pub fn dent_scene(config: SimConfig) -> Scene {
    let h = DENT_H;
    let mut body = BodyDesc::new(Shape::cuboid(UVec3::new(12, 6, 12)), h);
    body.position = Vec3::new(0.0, 0.15, 0.0);
    body.material = Material {
        model: Model::Oriented,
        yield_strain: 0.01,
        creep: 1.0,
        max_plastic_strain: 0.5,
        ..Material::default()
    };
    let radius = 4.0 * h;
    // the sphere's centre when it just touches the top particles' balls
    let touching = DENT_TOP + 0.5 * h + radius;
    let at = |y: f32| Pose::at(Vec3::new(0.0, y, 0.0));
    let sphere = ColliderDesc {
        shape: ColliderShape::Sphere { radius },
        friction: 0.5,
        pose: at(touching + h),
        path: Path {
            keys: vec![
                (0.5, at(touching + h)),
                (1.5, at(touching - DENT_DEPTH)),
                (3.0, at(touching - DENT_DEPTH)),
                (3.5, at(touching + 4.0 * h)),
            ],
        },
    };
    Scene {
        config,
        bodies: vec![body],
        tools: vec![],
        colliders: vec![sphere],
        frames: 360,
    }
}
