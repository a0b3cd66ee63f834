//! Bodies dropped into a walled bin: the built-in `pile` (seven bodies), and the crowd
//! of the bench's contact rows (as many bodies as asked, in a wider bin), both at any
//! lattice spacing, so the same scene can be made with more particles.

use crate::body::shape::Shape;
use crate::config::SimConfig;
use crate::cut::tool::{Path, Pose};
use crate::ecs::desc::{BodyDesc, ColliderDesc, Scene};
use crate::geometry::collider::ColliderShape;
use crate::io::cut_scenes::rigid_body;
use glam::{Quat, Vec3};

/// The bodies' shapes, dropped in this order (and again from the first, in a crowd).
fn pile_shapes() -> [Shape; 7] {
    [
        Shape::Box {
            half_extents: Vec3::new(0.35, 0.2, 0.25),
        },
        Shape::Sphere { radius: 0.3 },
        Shape::Capsule {
            radius: 0.18,
            half_length: 0.35,
        },
        Shape::Box {
            half_extents: Vec3::splat(0.22),
        },
        Shape::Sphere { radius: 0.22 },
        Shape::Box {
            half_extents: Vec3::new(0.5, 0.12, 0.15),
        },
        Shape::Sphere { radius: 0.25 },
    ]
}

/// A bin whose floor (the ground) is `2·inner` wide: four static walls 1.2 m high, each
/// tilted 10° outwards about its long axis.
fn bin_walls(inner: f32) -> Vec<ColliderDesc> {
    let (height, thickness, tilt) = (1.2, 0.1, 10f32.to_radians());
    (0..4)
        .map(|k| {
            // wall k faces the centre from the side at angle k·90° about Y
            let yaw = Quat::from_rotation_y(k as f32 * std::f32::consts::FRAC_PI_2);
            let outward = yaw * Vec3::X;
            let lean = Quat::from_axis_angle(yaw * Vec3::Z, -tilt);
            let centre = outward * (inner + thickness + height * 0.5 * tilt.sin())
                + Vec3::Y * (height * 0.5);
            ColliderDesc {
                shape: ColliderShape::Box {
                    half_extents: Vec3::new(thickness, height * 0.5, inner + 2.0 * thickness),
                },
                friction: 0.3,
                pose: Pose {
                    position: centre,
                    rotation: lean * yaw,
                },
                path: Path::default(),
            }
        })
        .collect()
}

/// Body `i` of a bin: a rigid `shape` at spacing `h`, at `position`, turned 0.7 rad
/// about Y per place in the order.
fn dropped(shape: Shape, h: f32, position: Vec3, i: usize) -> BodyDesc {
    let mut body = rigid_body(shape, h);
    body.position = position;
    body.rotation = Quat::from_rotation_y(0.7 * i as f32);
    body
}

/// `bodies` in a bin whose floor is `2·inner` wide.
fn in_bin(config: SimConfig, bodies: Vec<BodyDesc>, inner: f32) -> Scene {
    Scene {
        config,
        bodies,
        tools: vec![],
        colliders: bin_walls(inner),
        frames: 400,
    }
}

/// A walled bin (four static boxes, each tilted 10° outwards about its long axis) and
/// seven bodies of four shapes dropped into it one above another, at spacing `h`; with a
/// smaller `h` the same scene has more particles (the bench's contact row).
pub fn pile_scene(config: SimConfig, h: f32) -> Scene {
    let bodies = pile_shapes()
        .into_iter()
        .enumerate()
        .map(|(i, shape)| {
            let a = i as f32 * 2.4;
            let position = Vec3::new(0.35 * a.cos(), 0.6 + 0.75 * i as f32, 0.35 * a.sin());
            dropped(shape, h, position, i)
        })
        .collect();
    in_bin(config, bodies, 1.0)
}

/// A crowd: `bodies` bodies (the pile's seven shapes in turn) dropped into a bin 3 m wide,
/// at spacing `h`, in layers of four 0.75 m apart, one body in each quarter of the bin
/// (every shape fits a quarter at any turn about Y, so no two start overlapping).
pub fn crowd_scene(config: SimConfig, h: f32, bodies: usize) -> Scene {
    let inner = 1.5;
    let quarter = inner * 0.5;
    let shapes = pile_shapes();
    let bodies = (0..bodies)
        .map(|i| {
            let (layer, corner) = (i / 4, i % 4);
            let side = |bit: usize| if corner & bit == 0 { -quarter } else { quarter };
            let position = Vec3::new(side(1), 0.6 + 0.75 * layer as f32, side(2));
            dropped(shapes[i % shapes.len()].clone(), h, position, i)
        })
        .collect();
    in_bin(config, bodies, inner)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::simulation::Simulation;

    /// Every particle of a crowd starts inside the bin, above the ground, and more than a
    /// lattice spacing from every particle of every other body: nothing starts
    /// overlapping, at any count (the layers stack four quarters at a time).
    #[test]
    fn a_crowd_starts_apart_and_inside_its_bin() {
        let h = 0.1;
        let scene = crowd_scene(SimConfig::default(), h, 23);
        assert_eq!(scene.bodies.len(), 23);
        let mut sim = Simulation::new(scene.config.clone()).expect("default settings");
        let bodies: Vec<Vec<Vec3>> = scene
            .bodies
            .iter()
            .map(|desc| {
                let body = sim.spawn_body(desc).expect("a crowd body spawns");
                let positions = sim.positions(body).expect("a live body");
                positions.into_iter().map(|(_, x)| x).collect()
            })
            .collect();
        for (i, a) in bodies.iter().enumerate() {
            for x in a {
                assert!(x.x.abs() < 1.5 && x.z.abs() < 1.5 && x.y > 0.0, "{i}: {x}");
            }
            for b in &bodies[..i] {
                let gap = a
                    .iter()
                    .flat_map(|x| b.iter().map(move |y| x.distance(*y)))
                    .fold(f32::INFINITY, f32::min);
                assert!(gap > h, "body {i}: gap {gap}");
            }
        }
    }
}
