//! The workloads of `cleave bench --cutting`: scenes and the blade strokes that cross
//! them, built in code so that every run cuts the same bodies the same way.

use crate::body::shape::Shape;
use crate::config::SimConfig;
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::desc::{BodyDesc, Scene, ToolDesc};
use glam::{Quat, UVec3, Vec3};
use rand::{Rng, SeedableRng};

/// The settings of a body at rest in space: gravity off, no ground.
fn still_config() -> SimConfig {
    SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    }
}

/// A block `n` cells wide at spacing `h`, centred on the origin.
fn block(n: u32, h: f32) -> BodyDesc {
    BodyDesc::new(Shape::cuboid(UVec3::splat(n)), h)
}

/// A blade big enough to cross a block of `size` metres.
fn blade(size: f32) -> ToolShape {
    ToolShape::Blade {
        half_width: size,
        half_height: 0.5 * size,
    }
}

/// A workload: a scene, and blade strokes spawned as tools for the frames they take
/// (from the frame of their first key) and despawned after their last.
pub struct Workload {
    /// The scene (its own tools run throughout).
    pub scene: Scene,
    /// `(first frame, tool)`: the tool follows its path from that frame on.
    pub strokes: Vec<(u32, ToolDesc)>,
}

/// The `slice` scene's pedestal and ground with a 32³ block (h = 0.05) on it, crossed
/// by a blade stroke every 10 frames for 300 frames: each stroke drawn as the viewer
/// draws one ([`crate::cut::stroke::stroke_cut`]), seen from 12 m in front, across the
/// block from a random point of a circle around it to the opposite side, turned at
/// random (seeded).
pub fn stroked_block(mode: CutMode) -> Workload {
    let mut scene = crate::io::scene::builtin("slice", 0).expect("a built-in scene");
    let (h, n) = (0.05, 32);
    let size = n as f32 * h;
    let top = scene.config.boxes.first().map_or(0.0, |b| b.max.y);
    let centre = Vec3::new(0.0, top + 0.5 * size, 0.0);
    let material = scene.bodies[0].material.clone();
    scene.bodies = vec![BodyDesc {
        position: centre,
        material,
        ..block(n, h)
    }];
    scene.tools.clear();
    scene.frames = 300;
    let dt = scene.config.dt;
    let eye = centre + Vec3::new(0.0, 0.0, 12.0);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(61);
    let strokes = (0..scene.frames / 10)
        .filter_map(|k| {
            let angle = rng.random_range(0.0..std::f32::consts::TAU);
            let across = Vec3::new(angle.cos(), angle.sin(), 0.0) * 0.8 * size;
            let offset = Vec3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                0.0,
            ) * size;
            let cut = crate::cut::stroke::stroke_cut(
                eye,
                centre + offset + across - eye,
                centre + offset - across - eye,
                1.0,
                24.0,
            )
            .ok()?;
            let first = k * 10 + 5;
            let keys = (cut.poses.iter().enumerate())
                .map(|(i, p)| ((first - 1 + i as u32) as f32 * dt, *p))
                .collect();
            Some((
                first,
                ToolDesc {
                    shape: cut.shape,
                    cut_width: 2.0 * h,
                    cut_mode: mode,
                    path: Path { keys },
                    pose: cut.poses[0],
                },
            ))
        })
        .collect();
    Workload { scene, strokes }
}

/// A 64³ box (h = 0.05, gravity off) sliced once through its middle by a blade at 30°
/// to the lattice, at frame 10 of 20.
pub fn sliced_box(mode: CutMode) -> Workload {
    let (h, n) = (0.05, 64);
    let shape = blade(n as f32 * h);
    let rotation = Quat::from_rotation_y(std::f32::consts::FRAC_PI_6);
    let up = rotation * Vec3::Y * reach(shape, n, h);
    let tool = stroke(shape, rotation, [up, -up], 10, h, mode);
    still_box(n, h, 20, vec![tool])
}

/// An `n`³ box (h = 0.05, gravity off) diced in one frame, frame 2 of 6, by 8 blades: 4
/// across x and 4 across z, each through a plane of particles (at an eighth, three
/// eighths, five eighths and seven eighths of the box), every blade crossing the whole
/// box within that frame. What a game meets when a huge body is cut everywhere at once.
pub fn diced_box(n: u32, mode: CutMode) -> Workload {
    let h = 0.05;
    let size = n as f32 * h;
    let shape = blade(size);
    let up = Vec3::Y * reach(shape, n, h);
    // the particles' planes lie at (i + 1/2) h from the box's low face
    let plane = |eighth: u32| {
        let i = (eighth as f32 / 8.0 * n as f32).floor();
        (i + 0.5) * h - 0.5 * size
    };
    let across_x = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
    let blades = [1, 3, 5, 7]
        .into_iter()
        .flat_map(|e| {
            [
                (Vec3::new(plane(e), 0.0, 0.0), across_x),
                (Vec3::new(0.0, 0.0, plane(e)), Quat::IDENTITY),
            ]
        })
        .map(|(at, rotation)| stroke(shape, rotation, [at + up, at - up], 2, h, mode))
        .collect();
    still_box(n, h, 6, blades)
}

/// How far from a box `n` cells of `h` wide the blade `shape` starts and ends its stroke
/// across it: clear of the box at both ends.
fn reach(shape: ToolShape, n: u32, h: f32) -> f32 {
    shape.bounding_radius() + n as f32 * h
}

/// A blade stroke at a still box's time step: `shape`, turned by `rotation`, waits at
/// `from` and crosses to `to` within frame `frame`, cutting `2 h` wide.
fn stroke(
    shape: ToolShape,
    rotation: Quat,
    [from, to]: [Vec3; 2],
    frame: u32,
    h: f32,
    mode: CutMode,
) -> ToolDesc {
    let dt = still_config().dt;
    let pose = |position| Pose { position, rotation };
    let t = frame as f32 * dt;
    let keys = vec![(t - dt, pose(from)), (t, pose(to))];
    ToolDesc {
        shape,
        cut_width: 2.0 * h,
        cut_mode: mode,
        pose: keys[0].1,
        path: Path { keys },
    }
}

/// An `n`³ box of spacing `h` at rest at the origin, gravity off, for `frames` frames,
/// crossed by `tools`.
fn still_box(n: u32, h: f32, frames: u32, tools: Vec<ToolDesc>) -> Workload {
    Workload {
        scene: Scene {
            config: still_config(),
            frames,
            bodies: vec![block(n, h)],
            tools,
            colliders: Vec::new(),
        },
        strokes: Vec::new(),
    }
}
