//! The built-in handle scenes: `bend` (a bar posed by two region handles: bent, then
//! twisted, then stretched; `cleave deform bend`) and `grab` (a block dragged through
//! the air by one point handle while it simulates; `cleave run grab`).

use crate::body::shape::Shape;
use crate::config::{Material, SimConfig};
use crate::deform::keys::{HandleKey, HandlePath};
use crate::ecs::desc::{BodyDesc, HandleDesc, Region, Scene};
use glam::{Quat, UVec3, Vec3};
use std::f32::consts::FRAC_PI_2;

/// Lattice spacing of the scenes (metres).
const H: f32 = 0.05;

/// A 32×4×4 bar at height 1 m whose end regions (two layers each) are region handles:
/// the left stays, the right is bent up a quarter turn, twisted a quarter turn about
/// its own axis, then brought back straight and pulled out by a fifth of the bar:
/// stretched. (Its keys only move and turn, so `cleave run bend` simulates the bar
/// driven by the same handles as hard attachments.)
pub fn bend_scene(config: SimConfig) -> Scene {
    let (length, y) = (32.0 * H, 1.0);
    let end = |x0: f32, x1: f32| Region {
        min: Vec3::new(x0, y - 3.0 * H, -3.0 * H),
        max: Vec3::new(x1, y + 3.0 * H, 3.0 * H),
    };
    let half = 0.5 * length;
    // the right end region's centroid: one layer in from the end
    let right = Vec3::new(half - H, y, 0.0);
    let bend = Quat::from_rotation_z(FRAC_PI_2);
    let twist = bend * Quat::from_rotation_x(FRAC_PI_2);
    // a quarter circle as long as the bar between its end regions' centroids: the
    // right end a radius on from the left and a radius up
    let radius = 2.0 * (half - H) / FRAC_PI_2;
    let bent = Vec3::new(-(half - H) + radius, y + radius, 0.0);
    let key = |position: Vec3, rotation: Quat| HandleKey {
        position,
        rotation,
        scale: Vec3::ONE,
    };
    let path = HandlePath {
        keys: vec![
            (0.0, HandleKey::at(right)),
            (1.0, key(bent, bend)),
            (1.5, key(bent, bend)),
            (2.5, key(bent, twist)),
            (3.0, key(bent, twist)),
            (
                4.0,
                HandleKey::at(right + Vec3::new(0.2 * length, 0.0, 0.0)),
            ),
        ],
    };
    let body = BodyDesc {
        position: Vec3::new(0.0, y, 0.0),
        material: Material::default(),
        handles: vec![
            HandleDesc {
                region: end(-half - 0.1, -half + 2.0 * H),
                ..HandleDesc::default()
            },
            HandleDesc {
                region: end(half - 2.0 * H, half + 0.1),
                path,
                ..HandleDesc::default()
            },
        ],
        ..BodyDesc::new(Shape::cuboid(UVec3::new(32, 4, 4)), H)
    };
    Scene {
        config: SimConfig {
            ground: None,
            ..config
        },
        bodies: vec![body],
        tools: vec![],
        colliders: vec![],
        frames: 260,
    }
}

/// A 10×10×10 block of the default material hanging from one point handle at the
/// middle of its top face, dragged along an arc through the air and back down.
pub fn grab_scene(config: SimConfig) -> Scene {
    let y = 1.0;
    let top = Vec3::new(0.0, y + 5.0 * H, 0.0);
    let path = HandlePath {
        keys: vec![
            (0.0, HandleKey::at(top)),
            (1.0, HandleKey::at(top + Vec3::new(0.4, 0.4, 0.0))),
            (2.0, HandleKey::at(top + Vec3::new(0.0, 0.6, 0.4))),
            (3.0, HandleKey::at(top + Vec3::new(-0.4, 0.2, 0.0))),
        ],
    };
    let body = BodyDesc {
        position: Vec3::new(0.0, y, 0.0),
        handles: vec![HandleDesc {
            region: Region {
                min: top - Vec3::splat(1.5 * H),
                max: top + Vec3::splat(1.5 * H),
            },
            point: true,
            path,
            compliance: 1e-6,
        }],
        ..BodyDesc::new(Shape::cuboid(UVec3::splat(10)), H)
    };
    Scene {
        config,
        bodies: vec![body],
        tools: vec![],
        colliders: vec![],
        frames: 240,
    }
}
