//! The built-in `truck` scene (SPEC §5): one body of oriented particles — a rigid
//! chassis, four rigid hubs each turning on an axle it shares particles with (a joint),
//! and soft tyres round the hubs — rolling down a slope, along the ground and over a
//! bump. Every rigid part is an explicit group; the tyres are the particles left to the
//! implicit groups, so the material's compliance is the tyres'.
//!
//! The groups of [`truck_scene`]'s body come in a fixed order, which tests use to find
//! the parts: the chassis, then the front and the rear axle, then the four hubs (wheels in
//! the order of [`WHEEL_CENTRES`]).

use crate::body::shape::{Shape, ShapePart};
use crate::config::{GroundPlane, Material, Model, SimConfig};
use crate::cut::tool::{Path, Pose};
use crate::ecs::desc::{BodyDesc, ColliderDesc, GroupDesc, Region, Scene};
use crate::geometry::collider::ColliderShape;
use glam::{Quat, Vec3};

/// The truck's lattice spacing (metres).
pub const TRUCK_H: f32 = 0.025;

/// The chassis's half size (a box from the axles' height up, in the truck's frame).
const CHASSIS_HALF: Vec3 = Vec3::new(20.0 * TRUCK_H, 3.0 * TRUCK_H, 6.0 * TRUCK_H);

/// The chassis box's centre in the truck's frame: its bottom layer holds the axles.
const CHASSIS_CENTRE: Vec3 = Vec3::new(0.0, 3.0 * TRUCK_H, 0.0);

/// The wheels' centres in the truck's frame — on lattice points in x and y, so that each
/// axle is a column of particles through its wheel's middle: front left, front right,
/// rear left, rear right (x forward, z left). A wheel's four layers of particles lie
/// beside the chassis past one empty layer.
pub const WHEEL_CENTRES: [Vec3; 4] = [
    Vec3::new(12.5 * TRUCK_H, 0.5 * TRUCK_H, 9.0 * TRUCK_H),
    Vec3::new(12.5 * TRUCK_H, 0.5 * TRUCK_H, -9.0 * TRUCK_H),
    Vec3::new(-12.5 * TRUCK_H, 0.5 * TRUCK_H, 9.0 * TRUCK_H),
    Vec3::new(-12.5 * TRUCK_H, 0.5 * TRUCK_H, -9.0 * TRUCK_H),
];

/// A wheel's radius: its outermost particles lie 8 spacings from its axle. (A wheel
/// rolls on the balls of its rim, each a small impact as it lands: fewer particles round
/// the rim lose more speed per turn.)
pub const WHEEL_RADIUS: f32 = 8.4 * TRUCK_H;

/// How far a wheel reaches from its axle: its outermost particles' balls.
pub const WHEEL_REACH: f32 = 8.5 * TRUCK_H;

/// A wheel's half thickness.
const WHEEL_HALF_THICKNESS: f32 = 2.0 * TRUCK_H;

/// A hub's half size: the particles within 4 spacings of the axle along x and y are
/// rigid; the ring outside them is tyre.
const HUB_HALF: f32 = 4.5 * TRUCK_H;

/// The tyres' compliance (1/Pa): soft enough that they visibly flatten where they touch.
pub const TYRE_COMPLIANCE: f32 = 5e-5;

/// The slope's angle (radians) and its length along its surface (metres).
const SLOPE: (f32, f32) = (0.2, 8.0);

/// Where the bump (a capsule across the way, half buried) lies along x, and its radius.
pub const BUMP: (f32, f32) = (4.5, 0.06);

/// The truck's overall length (metres), for "body lengths": its wheels reach past the
/// chassis.
pub const TRUCK_LENGTH: f32 = 2.0 * (WHEEL_CENTRES[0].x + WHEEL_REACH);

/// The truck's shape in its own frame: the chassis box, the four wheels one empty
/// layer of cells beside it, and the two axles through the chassis bridging that gap.
fn truck_shape() -> Shape {
    let part = |shape, at| ShapePart { shape, at };
    let mut parts = vec![part(
        Shape::Box {
            half_extents: CHASSIS_HALF,
        },
        CHASSIS_CENTRE,
    )];
    parts.extend(WHEEL_CENTRES.iter().map(|c| {
        let wheel = Shape::Cylinder {
            radius: WHEEL_RADIUS,
            half_length: WHEEL_HALF_THICKNESS,
        };
        part(wheel, *c)
    }));
    parts.extend(WHEEL_CENTRES.iter().step_by(2).map(|c| {
        let axle = Shape::Cylinder {
            radius: 0.2 * TRUCK_H,
            half_length: c.z + WHEEL_HALF_THICKNESS,
        };
        part(axle, Vec3::new(c.x, c.y, 0.0))
    }));
    Shape::Union(parts)
}

/// The world box around the truck-frame box `centre ± half`, placed at `at` turned by
/// `turn`.
fn placed_region(at: Vec3, turn: Quat, centre: Vec3, half: Vec3) -> Region {
    let (mut min, mut max) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for corner in 0..8 {
        let sign = Vec3::new(
            if corner & 1 == 0 { -1.0 } else { 1.0 },
            if corner & 2 == 0 { -1.0 } else { 1.0 },
            if corner & 4 == 0 { -1.0 } else { 1.0 },
        );
        let p = at + turn * (centre + sign * half);
        (min, max) = (min.min(p), max.max(p));
    }
    Region { min, max }
}

/// The truck's rigid parts as explicit groups, for the truck placed at `at` turned by
/// `turn` about z: the chassis, the front and the rear axle (each sharing the particles
/// across the chassis's width with it, and those through each wheel with its hub), the
/// four hubs. The axles are the only links between the chassis and the hubs, and all
/// they share are lines of particles: the hubs turn freely on the axles, and the axles in
/// the chassis.
fn truck_groups(at: Vec3, turn: Quat) -> Vec<GroupDesc> {
    let rigid = |region| GroupDesc {
        region,
        compliance: 0.0,
    };
    // (a quarter spacing of slack where a box must take a particle on its edge; none
    // across z, where the chassis ends half a spacing short of the empty layer)
    let slack = Vec3::new(0.25, 0.25, 0.0) * TRUCK_H;
    let mut groups = vec![rigid(placed_region(
        at,
        turn,
        CHASSIS_CENTRE,
        CHASSIS_HALF + slack,
    ))];
    // an axle: its column from one wheel's far side through the chassis to the other's
    let axle_half = Vec3::new(0.0, 0.0, WHEEL_CENTRES[0].z + WHEEL_HALF_THICKNESS) + slack;
    groups.extend(
        WHEEL_CENTRES
            .iter()
            .step_by(2)
            .map(|c| rigid(placed_region(at, turn, Vec3::new(c.x, c.y, 0.0), axle_half))),
    );
    groups.extend(WHEEL_CENTRES.iter().map(|c| {
        let half = Vec3::new(HUB_HALF, HUB_HALF, WHEEL_HALF_THICKNESS);
        // the hub is a world box about the turned centre (not a turned box), so that it
        // holds whole rings of particles about the axle
        let centre = at + turn * *c;
        rigid(Region {
            min: centre - half,
            max: centre + half,
        })
    }));
    groups
}

/// The slope's turn (about z, down toward +x) with its downhill direction and its
/// surface normal.
fn slope_frame() -> (Quat, Vec3, Vec3) {
    let turn = Quat::from_rotation_z(-SLOPE.0);
    (turn, turn * Vec3::X, turn * Vec3::Y)
}

/// The slope: a static box whose top face runs `SLOPE.1` metres down at `SLOPE.0` to meet
/// the ground at x = 0, going toward +x.
fn slope() -> ColliderDesc {
    let length = SLOPE.1;
    let (turn, down, normal) = slope_frame();
    let thickness = 0.1;
    ColliderDesc {
        shape: ColliderShape::Box {
            half_extents: Vec3::new(0.5 * length, thickness, 1.0),
        },
        friction: 0.8,
        pose: Pose {
            position: -down * (0.5 * length) - normal * thickness,
            rotation: turn,
        },
        path: Path::default(),
    }
}

/// The bump: a capsule across the way, its axis on the ground.
fn bump() -> ColliderDesc {
    let (x, radius) = BUMP;
    ColliderDesc {
        shape: ColliderShape::Capsule {
            radius,
            half_length: 1.0,
        },
        friction: 0.8,
        pose: Pose {
            position: Vec3::new(x, 0.0, 0.0),
            rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        },
        path: Path::default(),
    }
}

/// Where the truck starts: its frame turned to the slope, its rear wheels' lowest
/// particles a quarter spacing above the slope near its top.
pub fn truck_start() -> (Vec3, Quat) {
    let length = SLOPE.1;
    let (turn, down, normal) = slope_frame();
    let above = WHEEL_REACH + 0.25 * TRUCK_H;
    let along = length - 1.0;
    let at = -down * along + normal * above - turn * Vec3::new(0.0, WHEEL_CENTRES[0].y, 0.0);
    (at, turn)
}

/// `truck`: a rigid chassis on four wheels — rigid hubs on axles (joints), soft tyres of
/// the oriented model — set on a slope of 0.2 rad: it rolls down, along the ground and
/// over a bump, its tyres flattening where they touch.
pub fn truck_scene(config: SimConfig) -> Scene {
    let (at, turn) = truck_start();
    let mut body = BodyDesc::new(truck_shape(), TRUCK_H);
    body.position = at;
    body.rotation = turn;
    body.material = Material {
        model: Model::Oriented,
        compliance: TYRE_COMPLIANCE,
        density: 1000.0,
        ..Material::default()
    };
    body.groups = truck_groups(at, turn);
    Scene {
        config: SimConfig {
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.8,
            }),
            damping: 0.0,
            ..config
        },
        bodies: vec![body],
        tools: vec![],
        colliders: vec![slope(), bump()],
        frames: 480,
    }
}
