//! Built-in scenes: a simulation config, bodies, tools and a default frame count.

use crate::body::shape::Shape;
use crate::config::{Material, SimConfig, StaticBox};
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::desc::Scene;
use crate::ecs::desc::{BodyDesc, ColliderDesc, PinRegion, ToolDesc};
use crate::geometry::collider::ColliderShape;
use crate::io::cut_scenes::{
    bevel_scene, cut_block_scene, random_scene, rigid_body, scooped_cantilever_scene,
};
use glam::{Quat, UVec3, Vec3};

/// Names and one-line descriptions of the built-in scenes.
pub const BUILTIN_SCENES: [(&str, &str); 23] = [
    ("drop", "a 16×8×8 box falls on the ground and settles"),
    (
        "cantilever",
        "a 24×6×6 beam pinned at one end sags under gravity",
    ),
    (
        "slice",
        "a blade sweeps through a 24×12×12 block on a pedestal: two halves tip off",
    ),
    (
        "dice",
        "two perpendicular slices through a 24×12×24 block: four pieces",
    ),
    (
        "scoop",
        "a sphere carves a trench along the top of a block: one piece",
    ),
    (
        "random",
        "a seeded sequence of random blade and sphere cuts (stress test)",
    ),
    (
        "stack",
        "a 16×8×8 box dropped onto an 8×8×8 box resting on the ground comes to rest on top",
    ),
    (
        "pile",
        "boxes, balls and a capsule dropped into a walled bin of tilted static boxes",
    ),
    (
        "press",
        "a moving plate squeezes a block, then a blade cuts it while squeezed",
    ),
    (
        "tear",
        "a 32×6×6 bar whose ends are pulled apart by moving pins tears in two",
    ),
    (
        "notch",
        "the tear bar with a notch at 30 % of its length tears at the notch",
    ),
    (
        "cuts",
        "a 32×16×16 block, gravity off, cut 50 times by random blades and sphere scoops",
    ),
    (
        "bevel",
        "a blade slants through a 16³ block on a pedestal at 30° to its sides: the pieces tip off",
    ),
    (
        "scooped",
        "the cantilever with 20 sphere scoops near the middle of its top and sides",
    ),
    (
        "soft_beam",
        "a 32×3×3 bar of very soft clusters and stiff edges, pinned at one end: it bends like a chain and barely stretches",
    ),
    (
        "jittered",
        "a soft block and ball spawned with every particle jittered by 0.3 h, relaxed into their rest shapes, then dropped",
    ),
    (
        "bend",
        "a 32×4×4 bar posed by its two end regions: bent, twisted, stretched (`cleave deform bend`)",
    ),
    (
        "grab",
        "a 10×10×10 block dragged through the air by one point handle while it simulates",
    ),
    (
        "rod",
        "a 24×1×1 rod of oriented particles clamped at its root holds out under gravity",
    ),
    (
        "dent",
        "a plastic block of oriented particles pressed by a sphere keeps a dent",
    ),
    (
        "wheel",
        "a rigid disc spinning at 2 rev/s on an axle it shares particles with (a joint), gravity off",
    ),
    (
        "sheet",
        "a 24×24×1 sheet of oriented particles standing on edge, clamped along its left edge, holds out under gravity",
    ),
    (
        "truck",
        "a rigid chassis on rigid hubs with soft tyres (oriented particles, axles as joints) rolls down a slope and over a bump",
    ),
];

const H: f32 = 0.1;

/// Where the `notch` scene's notch lies along the bar (x, metres): 30 % of the length.
pub const NOTCH_X: f32 = -1.6 + 0.3 * 3.2;

/// The `soft_beam` scene: a 32×3×3 bar pinned by its first two columns, under gravity,
/// of clusters so soft (compliance 1e-4 1/Pa, E = 10 kPa) that alone they let it stretch
/// to several times its length, with stiff edge distance constraints (edge compliance
/// 7e-8 1/Pa): it bends down like a chain, its edges stretched well under 1 %. 8
/// substeps × 20 iterations; every solver gives the same sag (the edges are in
/// projective dynamics' matrix; much stiffer edges than these need more iterations
/// there).
fn soft_beam(config: SimConfig) -> Scene {
    let mut body = rigid_body(Shape::cuboid(UVec3::new(32, 3, 3)), H);
    body.position = Vec3::new(0.0, 1.0, 0.0);
    body.pins = vec![PinRegion {
        min: Vec3::splat(-9.0),
        max: Vec3::new(-1.6 + 2.0 * H, 9.0, 9.0),
        ..PinRegion::default()
    }];
    body.material = Material {
        compliance: 1e-4,
        edge_compliance: Some(7e-8),
        ..Material::rigid()
    };
    Scene {
        config: SimConfig {
            ground: None,
            substeps: 8,
            iterations: 20,
            damping: 2.0,
            ..config
        },
        bodies: vec![body],
        tools: vec![],
        colliders: vec![],
        frames: 300,
    }
}

/// The `tear` and `notch` scenes: a 32×6×6 rubber bar (E ≈ 0.83 MPa, wave speed
/// √(E/ρ) ≈ 29 m/s) that tears past a principal stretch of 1.1, gravity off, its two
/// end regions (2 cells each) pinned and pulled apart at 2 m/s each from rest. The pull
/// starts as two strain waves of about v/c ≈ 7 % running in from the ends; where they
/// meet, in the middle, the strain doubles past the limit, and the bar tears there.
/// With `notch`, a blade removes the top 4 of the 6 rows over one cell at [`NOTCH_X`]
/// in the first frame, and the ends are pulled at 1 m/s: the doubled waves stay under
/// the limit, the third of the section left at the notch carries three times the
/// strain, and the bar tears at the notch. A smallest torn piece of 300 particles (26 %) keeps the waves that
/// bounce off the new crack faces from chipping thin slabs off the pieces (Gauss–Seidel
/// with 16 substeps carries the waves; Jacobi at 2 substeps smears them and the grips
/// tear first).
fn pulled_bar(config: SimConfig, notch: bool) -> Scene {
    // (the notched bar is pulled slower: its waves alone do not tear the middle)
    let (half, pull) = (1.6, if notch { 1.0 } else { 2.0 });
    let shape = Shape::cuboid(UVec3::new(32, 6, 6));
    let mut body = rigid_body(shape, H);
    body.position = Vec3::new(0.0, 1.0, 0.0);
    let end = |sign: f32| PinRegion {
        min: Vec3::new(if sign < 0.0 { -9.0 } else { half - 2.0 * H }, -9.0, -9.0),
        max: Vec3::new(if sign < 0.0 { -half + 2.0 * H } else { 9.0 }, 9.0, 9.0),
        velocity: Vec3::X * sign * pull,
    };
    body.pins = vec![end(-1.0), end(1.0)];
    body.material = Material {
        compliance: 1.2e-6,
        tear_stretch: Some(1.1),
        tear_min_piece: 300,
        ..Material::rigid()
    };
    // the notch: a blade across the bar at NOTCH_X, its lower edge between the second
    // and third rows from the bottom, there at the first frame and gone up the next
    let tools = if notch {
        let at = |y: f32| Pose {
            position: Vec3::new(NOTCH_X, y, 0.0),
            rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        };
        let edge = body.position.y - 0.1;
        vec![ToolDesc {
            shape: ToolShape::Blade {
                half_width: 0.5,
                half_height: 0.3,
            },
            cut_width: 0.5 * H,
            cut_mode: CutMode::Remove,
            path: Path {
                keys: vec![(0.0, at(edge + 0.3)), (0.05, at(edge + 5.0))],
            },
            pose: at(edge + 0.3),
        }]
    } else {
        Vec::new()
    };
    Scene {
        config: SimConfig {
            ground: None,
            gravity: Vec3::ZERO,
            solver: crate::config::SolverMode::GaussSeidel,
            substeps: 16,
            iterations: 10,
            ..config
        },
        bodies: vec![body],
        tools,
        colliders: vec![],
        frames: 120,
    }
}

/// A blade through the vertical axis, its normal yawed `normal_yaw` from +Z, moving
/// down from `from_y` to `to_y` between times `t0` and `t1`, then leaving below the ground.
fn blade_vertical_cut(
    normal_yaw: f32,
    width: f32,
    from_y: f32,
    to_y: f32,
    t0: f32,
    t1: f32,
) -> ToolDesc {
    // Blade normal is local Z; yaw it about Y so the normal lies in the XZ plane.
    let rotation = Quat::from_rotation_y(normal_yaw);
    let at = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation,
    };
    ToolDesc {
        shape: ToolShape::Blade {
            half_width: 2.0,
            half_height: 0.3,
        },
        cut_width: width,
        cut_mode: CutMode::Remove,
        path: Path {
            keys: vec![(t0, at(from_y)), (t1, at(to_y)), (t1 + 0.05, at(-5.0))],
        },
        pose: at(from_y),
    }
}

fn block_on_pedestal(cells: UVec3, pedestal: Vec3) -> (BodyDesc, StaticBox) {
    let height = 0.6;
    let mut body = rigid_body(Shape::cuboid(cells), H);
    body.position = Vec3::new(0.0, height + cells.y as f32 * H * 0.5, 0.0);
    let pedestal = StaticBox {
        min: Vec3::new(-pedestal.x, 0.0, -pedestal.z),
        max: Vec3::new(pedestal.x, height, pedestal.z),
        friction: 0.2,
    };
    (body, pedestal)
}

fn cutting_config(seed: u64) -> SimConfig {
    SimConfig {
        seed,
        ..SimConfig::default()
    }
}

/// The built-in scene `name`, with the given seed, or `None`.
pub fn builtin(name: &str, seed: u64) -> Option<Scene> {
    let config = SimConfig {
        seed,
        ..SimConfig::default()
    };
    Some(match name {
        "drop" => {
            let mut body = rigid_body(Shape::cuboid(UVec3::new(16, 8, 8)), H);
            body.position = Vec3::new(0.0, 0.4 + 0.5, 0.0);
            Scene {
                config,
                bodies: vec![body],
                tools: vec![],
                colliders: vec![],
                frames: 300,
            }
        }
        "tear" | "notch" => pulled_bar(config, name == "notch"),
        "jittered" => crate::io::relax_scenes::jittered_scene(config),
        "bend" => crate::io::deform_scenes::bend_scene(config),
        "grab" => crate::io::deform_scenes::grab_scene(config),
        "cantilever" => {
            let mut body = rigid_body(Shape::cuboid(UVec3::new(24, 6, 6)), H);
            body.position = Vec3::new(0.0, 1.0, 0.0);
            body.pins = vec![PinRegion {
                min: Vec3::new(-1.3, 0.0, -1.0),
                max: Vec3::new(-1.2 + 2.0 * H, 2.0, 1.0),
                ..PinRegion::default()
            }];
            // rubber-like: E ≈ 0.83 MPa (Euler–Bernoulli tip sag ≈ 11.5 h)
            body.material = Material {
                compliance: 1.2e-6,
                ..Material::rigid()
            };
            let config = SimConfig {
                ground: None,
                iterations: 20,
                damping: 2.0,
                ..config
            };
            Scene {
                config,
                bodies: vec![body],
                tools: vec![],
                colliders: vec![],
                frames: 600,
            }
        }
        "soft_beam" => soft_beam(config),
        "slice" => {
            let (body, pedestal) =
                block_on_pedestal(UVec3::new(24, 12, 12), Vec3::new(0.4, 0.0, 0.8));
            let top = body.position.y + 0.9;
            let config = SimConfig {
                boxes: vec![pedestal],
                ..cutting_config(seed)
            };
            let (bottom, half_pi) = (body.position.y - 0.9, std::f32::consts::FRAC_PI_2);
            let tool = blade_vertical_cut(half_pi, 1.01 * H, top, bottom, 0.2, 0.5);
            Scene {
                config,
                bodies: vec![body],
                tools: vec![tool],
                colliders: vec![],
                frames: 300,
            }
        }
        "dice" => {
            let (body, pedestal) =
                block_on_pedestal(UVec3::new(24, 12, 24), Vec3::new(0.4, 0.0, 0.4));
            let (top, bottom) = (body.position.y + 0.9, body.position.y - 0.9);
            let config = SimConfig {
                boxes: vec![pedestal],
                ..cutting_config(seed)
            };
            let a =
                blade_vertical_cut(std::f32::consts::FRAC_PI_2, 1.5 * H, top, bottom, 0.2, 0.25);
            let b = blade_vertical_cut(0.0, 1.5 * H, top, bottom, 0.2, 0.25);
            Scene {
                config,
                bodies: vec![body],
                tools: vec![a, b],
                colliders: vec![],
                frames: 300,
            }
        }
        "scoop" => {
            let mut body = rigid_body(Shape::cuboid(UVec3::new(24, 12, 12)), H);
            body.position = Vec3::new(0.0, 0.6, 0.0);
            let y = body.position.y + 0.6;
            let at = |x: f32| Pose::at(Vec3::new(x, y, 0.0));
            let tool = ToolDesc {
                shape: ToolShape::Sphere { radius: 0.3 },
                cut_width: 0.5 * H,
                cut_mode: CutMode::Remove,
                path: Path {
                    keys: vec![(0.2, at(-1.6)), (1.2, at(1.6))],
                },
                pose: at(-1.6),
            };
            Scene {
                config: cutting_config(seed),
                bodies: vec![body],
                tools: vec![tool],
                colliders: vec![],
                frames: 120,
            }
        }
        "random" => random_scene(seed),
        "cuts" => cut_block_scene(seed, 50),
        "bevel" => bevel_scene(config),
        "scooped" => scooped_cantilever_scene(builtin("cantilever", seed)?, seed, 20),
        "stack" => stack_scene(config),
        "pile" => pile_scene(config, H),
        "press" => press_scene(config),
        _ => return crate::io::oriented_scenes::builtin(name, config),
    })
}

/// A box of `cells` lattice points whose lowest layer is at height `bottom`.
/// A block of `cells` resting on its contact balls (radius h/2) on a floor at height
/// `bottom`.
fn box_at(cells: UVec3, x: f32, bottom: f32, z: f32) -> BodyDesc {
    let mut body = rigid_body(Shape::cuboid(cells), H);
    body.position = Vec3::new(x, bottom + cells.y as f32 * H * 0.5, z);
    body
}

fn stack_scene(config: SimConfig) -> Scene {
    let lower = box_at(UVec3::new(8, 8, 8), 0.0, 0.0, 0.0);
    let upper = box_at(UVec3::new(16, 8, 8), 0.0, 1.2, 0.0);
    Scene {
        config,
        bodies: vec![lower, upper],
        tools: vec![],
        colliders: vec![],
        frames: 300,
    }
}

/// A walled bin (four static boxes, each tilted 10° outwards about its long axis) and
/// seven bodies of four shapes dropped into it one above another, at spacing `h`; with a
/// smaller `h` the same scene has more particles (the bench's contact row).
pub fn pile_scene(config: SimConfig, h: f32) -> Scene {
    let inner = 1.0; // half width of the bin's floor
    let (height, thickness, tilt) = (1.2, 0.1, 10f32.to_radians());
    let mut colliders = Vec::new();
    for k in 0..4 {
        // wall k faces the centre from the side at angle k·90° about Y
        let yaw = Quat::from_rotation_y(k as f32 * std::f32::consts::FRAC_PI_2);
        let outward = yaw * Vec3::X;
        let lean = Quat::from_axis_angle(yaw * Vec3::Z, -tilt);
        let centre =
            outward * (inner + thickness + height * 0.5 * tilt.sin()) + Vec3::Y * (height * 0.5);
        colliders.push(ColliderDesc {
            shape: ColliderShape::Box {
                half_extents: Vec3::new(thickness, height * 0.5, inner + 2.0 * thickness),
            },
            friction: 0.3,
            pose: Pose {
                position: centre,
                rotation: lean * yaw,
            },
            path: Path::default(),
        });
    }
    let shapes = [
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
    ];
    let bodies = shapes
        .into_iter()
        .enumerate()
        .map(|(i, shape)| {
            let mut body = rigid_body(shape, h);
            let a = i as f32 * 2.4;
            body.position = Vec3::new(0.35 * a.cos(), 0.6 + 0.75 * i as f32, 0.35 * a.sin());
            body.rotation = Quat::from_rotation_y(0.7 * i as f32);
            body
        })
        .collect();
    Scene {
        config,
        bodies,
        tools: vec![],
        colliders,
        frames: 400,
    }
}

fn press_scene(config: SimConfig) -> Scene {
    let block = box_at(UVec3::new(16, 8, 8), 0.0, 0.0, 0.0);
    let top = 0.7;
    let plate_at = |y: f32| Pose::at(Vec3::new(0.0, y + 0.05, 0.0));
    let plate = ColliderDesc {
        shape: ColliderShape::Box {
            half_extents: Vec3::new(1.2, 0.05, 0.8),
        },
        friction: 0.5,
        pose: plate_at(1.2),
        path: Path {
            keys: vec![
                (0.2, plate_at(1.2)),
                (0.8, plate_at(top - 0.1)),
                (2.6, plate_at(top - 0.1)),
                (3.2, plate_at(1.5)),
            ],
        },
    };
    // a blade in the YZ plane (normal X) sweeping along Z through the squeezed block
    let blade_at = |z: f32| Pose {
        position: Vec3::new(0.05, 0.3, z),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    let blade = ToolDesc {
        shape: ToolShape::Blade {
            half_width: 0.3,
            half_height: 0.6,
        },
        cut_width: 1.01 * H,
        cut_mode: CutMode::Remove,
        path: Path {
            keys: vec![
                (1.2, blade_at(1.5)),
                (1.8, blade_at(-1.5)),
                (1.85, blade_at(-5.0)),
            ],
        },
        pose: blade_at(1.5),
    };
    Scene {
        config,
        bodies: vec![block],
        tools: vec![blade],
        colliders: vec![plate],
        frames: 240,
    }
}
