//! Scenes of cuts: a block cut by random blades and sphere scoops (built-in `cuts`), the
//! cantilever scooped near the middle of its top and sides (built-in `scooped`) —
//! `cleave fidelity` compares their rebuilt clusters with fresh ones —, a seeded run of
//! random blades and spheres through a block on the ground (`random`).

use crate::body::shape::Shape;
use crate::config::{Material, SimConfig};
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::desc::{BodyDesc, Scene, ToolDesc};
use glam::{Mat3, Quat, UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A body of `shape` at spacing `h`, of rigid clusters (the built-in scenes name their
/// material; the library's default is rubber).
pub(crate) fn rigid_body(shape: Shape, h: f32) -> BodyDesc {
    BodyDesc {
        material: Material::rigid(),
        ..BodyDesc::new(shape, h)
    }
}

/// Lattice spacing of the fidelity scenes (metres).
const H: f32 = 0.1;

/// Frames a plunging tool takes in and out again.
const PLUNGE_FRAMES: f32 = 6.0;

/// Most cuts of one [`cut_block_scene`].
pub const MAX_CUTS: u32 = 1000;

/// A tool that moves from `outside` to `inside` and back between `t0` and `t0 + span`.
fn plunge(
    shape: ToolShape,
    cut_width: f32,
    outside: Pose,
    inside: Pose,
    t0: f32,
    span: f32,
) -> ToolDesc {
    ToolDesc {
        shape,
        cut_width,
        cut_mode: CutMode::Remove,
        path: Path {
            keys: vec![
                (t0, outside),
                (t0 + 0.5 * span, inside),
                (t0 + span, outside),
            ],
        },
        pose: outside,
    }
}

/// The rotation whose local Y is `along` and local Z is `normal` (unit, orthogonal): a
/// blade in that pose slices along `along`.
fn blade_rotation(along: Vec3, normal: Vec3) -> Quat {
    Quat::from_mat3(&Mat3::from_cols(along.cross(normal), along, normal))
}

/// A random unit vector orthogonal to the unit vector `e`.
fn orthogonal_to(e: Vec3, rng: &mut impl Rng) -> Vec3 {
    let angle = rng.random_range(0.0..std::f32::consts::TAU);
    let u = e.any_orthonormal_vector();
    let v = e.cross(u);
    u * angle.cos() + v * angle.sin()
}

/// A 32×16×16 block at rest, gravity off, cut `cuts` times in sequence, one cut every 7
/// frames: every tenth cut is a blade through the block, the odd ones are sphere scoops
/// (radius 1.5–3 cells, centred within half a radius of a face), the others blades
/// 2–8 cells deep into a face and out again (half width 3–10 cells). Each enters a
/// random face at a random point, along the face's normal; blades lie in random planes
/// that hold that normal.
pub fn cut_block_scene(seed: u64, cuts: u32) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xf1de_117e);
    let cells = UVec3::new(32, 16, 16);
    let half = cells.as_vec3() * (0.5 * H);
    let mut body = rigid_body(Shape::cuboid(cells), H);
    body.position = Vec3::new(0.0, 1.0, 0.0);
    let config = SimConfig {
        seed,
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    };
    let dt = config.dt;
    let tools = (0..cuts)
        .map(|i| {
            let axis = rng.random_range(0..3);
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            let mut inward = Vec3::ZERO;
            inward[axis] = -sign;
            let mut entry = Vec3::new(
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.8..0.8),
            ) * half;
            entry[axis] = sign * half[axis];
            let entry = body.position + entry;
            let t0 = (1.0 + 7.0 * i as f32) * dt;
            let span = PLUNGE_FRAMES * dt;
            if i % 2 == 1 {
                let radius = rng.random_range(1.5..3.0) * H;
                let depth = rng.random_range(-0.5..0.5) * radius;
                let shape = ToolShape::Sphere { radius };
                let outside = Pose::at(entry - inward * (radius + H));
                let inside = Pose::at(entry + inward * depth);
                return plunge(shape, 0.5 * H, outside, inside, t0, span);
            }
            let rotation = blade_rotation(inward, orthogonal_to(inward, &mut rng));
            let half_height = 0.3;
            let at = |d: f32| Pose {
                position: entry + inward * d,
                rotation,
            };
            let outside = at(-(half_height + H));
            if i % 10 == 0 {
                // through: to beyond the opposite face, and back
                let shape = ToolShape::Blade {
                    half_width: 2.0,
                    half_height,
                };
                let beyond = at(2.0 * half[axis] + half_height + H);
                plunge(shape, 1.01 * H, outside, beyond, t0, span)
            } else {
                let shape = ToolShape::Blade {
                    half_width: rng.random_range(3.0..10.0) * H,
                    half_height,
                };
                let depth = rng.random_range(2.0..8.0) * H;
                plunge(shape, 1.01 * H, outside, at(depth - half_height), t0, span)
            }
        })
        .collect();
    Scene {
        config,
        bodies: vec![body],
        tools,
        colliders: vec![],
        frames: 7 * cuts + 5,
    }
}

/// The `cantilever` scene (`cantilever`, as built in) with `scoops` sphere scoops (radius 1.2–2 cells, centred
/// within a third of a radius of the face) in its first frames, four at a time: the
/// even ones on the top face in the middle third of the span, the odd ones on the
/// sides at the neutral axis in the middle half.
pub fn scooped_cantilever_scene(cantilever: Scene, seed: u64, scoops: u32) -> Scene {
    let mut scene = cantilever;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x05c0_09ed);
    let beam = &scene.bodies[0];
    let (centre, h) = (beam.position, beam.spacing);
    let half = Vec3::new(12.0, 3.0, 3.0) * h;
    let dt = scene.config.dt;
    scene.tools = (0..scoops)
        .map(|i| {
            let radius = rng.random_range(1.2..2.0) * h;
            let (entry, inward) = if i % 2 == 0 {
                let x = rng.random_range(-1.0..1.0) * half.x / 3.0;
                let z = rng.random_range(-0.6..0.6) * half.z;
                (Vec3::new(x, half.y, z), Vec3::NEG_Y)
            } else {
                let x = rng.random_range(-0.5..0.5) * half.x;
                let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                (Vec3::new(x, 0.0, side * half.z), Vec3::Z * -side)
            };
            let entry = centre + entry;
            let depth = rng.random_range(-1.0..1.0) * radius / 3.0;
            let t0 = (1 + i / 4) as f32 * dt;
            plunge(
                ToolShape::Sphere { radius },
                0.5 * h,
                Pose::at(entry - inward * (radius + h)),
                Pose::at(entry + inward * depth),
                t0,
                2.0 * dt,
            )
        })
        .collect();
    scene
}

/// A seeded sequence of random blade and sphere cuts through a block on the ground.
pub fn random_scene(seed: u64) -> Scene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let mut body = rigid_body(Shape::cuboid(UVec3::new(20, 10, 10)), H);
    body.position = Vec3::new(0.0, 0.5, 0.0);
    let mut tools = Vec::new();
    for i in 0..8 {
        let t0 = 0.2 + i as f32 * 0.3;
        let dir = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize_or(Vec3::X);
        let start = body.position + dir * 2.0;
        let end = body.position - dir * 2.0
            + Vec3::new(
                rng.random_range(-0.5..0.5),
                0.0,
                rng.random_range(-0.5..0.5),
            );
        let rotation = Quat::from_rotation_arc(
            Vec3::Z,
            Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(Vec3::Y),
        );
        let (shape, width) = if rng.random_bool(0.5) {
            (
                ToolShape::Blade {
                    half_width: 0.8,
                    half_height: 0.8,
                },
                1.01 * H,
            )
        } else {
            (
                ToolShape::Sphere {
                    radius: rng.random_range(0.1..0.3),
                },
                0.5 * H,
            )
        };
        let path = Path {
            keys: vec![
                (
                    t0,
                    Pose {
                        position: start,
                        rotation,
                    },
                ),
                (
                    t0 + 0.25,
                    Pose {
                        position: end,
                        rotation,
                    },
                ),
            ],
        };
        tools.push(ToolDesc {
            shape,
            cut_width: width,
            cut_mode: CutMode::Remove,
            path,
            pose: Pose {
                position: start,
                rotation,
            },
        });
    }
    Scene {
        config: SimConfig {
            seed,
            ..SimConfig::default()
        },
        bodies: vec![body],
        tools,
        colliders: vec![],
        frames: 300,
    }
}
