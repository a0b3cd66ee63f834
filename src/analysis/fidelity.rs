//! Does a cut body keep its stiffness? `cleave fidelity` answers by comparing a cut
//! body's rebuilt clusters with a fresh clustering of the same geometry ([`recluster`]'s
//! reference, the clusters the body would have had if it had been spawned with its
//! holes), on two seeded scenes:
//!
//! - [`cut_block_scene`]: a 32×16×16 block, gravity off, cut by a sequence of random
//!   blades (through the block and partway in) and sphere scoops; the clusterings are
//!   compared by their [`ClusterShape`];
//! - [`scooped_cantilever_scene`]: the `cantilever` beam with sphere scoops on its top
//!   face near the middle and on its sides at the neutral axis; the beam's static tip
//!   sag with its rebuilt clusters is compared with its sag with fresh ones (and with
//!   the beam before the scoops), each from a converged static solve
//!   ([`StaticProblem`]).
//!
//! [`recluster`]: crate::ecs::spawn::recluster

use crate::analysis::cluster_shape::{ClusterShape, ShapeRatios};
use crate::analysis::static_solve::StaticProblem;
use crate::body::lattice::{Lattice, Shape};
use crate::clusters::clustering::clusters_on_grid;
use crate::config::{SimConfig, SolverMode};
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::check::check_invariants;
use crate::ecs::components::{Body, BodyLattice};
use crate::ecs::desc::{BodyDesc, ToolDesc};
use crate::error::{CleaveError, Result, check_range};
use crate::io::scene::{Scene, builtin};
use crate::sim::simulation::Simulation;
use bevy_ecs::entity::Entity;
use glam::{Mat3, Quat, UVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

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
    let mut body = BodyDesc::new(Shape::cuboid(cells, H), H);
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

/// The `cantilever` scene with `scoops` sphere scoops (radius 1.2–2 cells, centred
/// within a third of a radius of the face) in its first frames, four at a time: the
/// even ones on the top face in the middle third of the span, the odd ones on the
/// sides at the neutral axis in the middle half.
pub fn scooped_cantilever_scene(seed: u64, scoops: u32) -> Scene {
    let mut scene = builtin("cantilever", seed).expect("the cantilever is built in");
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

/// Settings of `cleave fidelity`.
#[derive(Clone, Copy, Debug)]
pub struct FidelityOptions {
    /// Cuts of the block (1 – [`MAX_CUTS`]).
    pub cuts: u32,
    /// Scoops of the cantilever.
    pub scoops: u32,
    /// Seed of both scenes.
    pub seed: u64,
    /// What the tools do.
    pub cut_mode: CutMode,
}

impl Default for FidelityOptions {
    fn default() -> Self {
        Self {
            cuts: 50,
            scoops: 20,
            seed: 0,
            cut_mode: CutMode::Remove,
        }
    }
}

/// The block's comparison.
#[derive(Clone, Debug, Serialize)]
pub struct BlockFidelity {
    /// Cuts made.
    pub cuts: u32,
    /// Live particles at the end.
    pub particles: usize,
    /// Connected pieces at the end.
    pub pieces: usize,
    /// Invariant violations at the end (0 expected).
    pub violations: usize,
    /// The block's clusters as the cuts rebuilt them.
    pub rebuilt: ClusterShape,
    /// A fresh clustering of the same geometry.
    pub fresh: ClusterShape,
    /// `rebuilt` over `fresh`.
    pub ratio: ShapeRatios,
}

/// The cantilever's comparison.
#[derive(Clone, Debug, Serialize)]
pub struct CantileverFidelity {
    /// Scoops made.
    pub scoops: u32,
    /// Live particles after the scoops.
    pub particles: usize,
    /// Static tip sag of the beam before the scoops, in lattice spacings.
    pub intact_sag_h: f64,
    /// Static tip sag with the clusters the scoops rebuilt.
    pub rebuilt_sag_h: f64,
    /// Static tip sag of the same holes clustered fresh.
    pub fresh_sag_h: f64,
    /// `rebuilt_sag_h / fresh_sag_h`.
    pub ratio: f64,
    /// The clusters' shapes, rebuilt over fresh.
    pub shape_ratio: ShapeRatios,
}

/// What `cleave fidelity` reports.
#[derive(Clone, Debug, Serialize)]
pub struct FidelityReport {
    /// Seed of both scenes.
    pub seed: u64,
    /// What the tools did.
    pub cut_mode: CutMode,
    /// The cut block.
    pub block: BlockFidelity,
    /// The scooped cantilever.
    pub cantilever: CantileverFidelity,
}

/// Runs `scene` for `frames` frames with every tool in `mode`; returns the simulation
/// and its one body.
fn run_scene(mut scene: Scene, frames: u32, mode: CutMode) -> Result<(Simulation, Entity)> {
    for tool in &mut scene.tools {
        tool.cut_mode = mode;
    }
    let mut sim = Simulation::from_scene(&scene)?;
    let body = sim.bodies()[0];
    sim.run(frames);
    Ok((sim, body))
}

/// A body's geometry with its clusters as rebuilt and as a fresh clustering makes them.
struct Clusterings {
    lattice: Lattice,
    rebuilt: Vec<Vec<u32>>,
    fresh: Vec<Vec<u32>>,
}

impl Clusterings {
    /// Those of `body` in `sim`.
    fn of(sim: &mut Simulation, body: Entity) -> Result<Self> {
        let rebuilt = sim.clusters(body)?.into_iter().map(|(_, m)| m).collect();
        let world = sim.world();
        let (Some(b), Some(l)) = (world.get::<Body>(body), world.get::<BodyLattice>(body)) else {
            return Err(CleaveError::InvalidEntity(format!("{body} is not a body")));
        };
        let fresh = clusters_on_grid(&l.lattice, &b.material, b.seed_grid).into_clusters();
        Ok(Self {
            lattice: l.lattice.clone(),
            rebuilt,
            fresh,
        })
    }

    /// The rebuilt and the fresh clusters' shapes.
    fn shapes(&self) -> (ClusterShape, ClusterShape) {
        let shape = |c: &[Vec<u32>]| ClusterShape::of(&self.lattice, c.iter().map(|m| &m[..]));
        (shape(&self.rebuilt), shape(&self.fresh))
    }
}

/// Converged static tip sag (spacings) of `desc` with `lattice` and `clusters`, under
/// `gravity`.
fn static_sag(desc: &BodyDesc, lattice: &Lattice, clusters: &[Vec<u32>], gravity: Vec3) -> f64 {
    StaticProblem::new(
        desc,
        lattice,
        clusters.iter().map(|m| &m[..]),
        SolverMode::Projective,
        gravity,
        |r| r,
    )
    .settled_sag(4000, 1e-6)
}

/// Runs both comparisons.
pub fn fidelity(options: FidelityOptions) -> Result<FidelityReport> {
    check_range(
        "cuts",
        options.cuts as f32,
        1.0,
        MAX_CUTS as f32,
        "1 ≤ cuts ≤ 1000",
    )?;
    check_range(
        "scoops",
        options.scoops as f32,
        0.0,
        100.0,
        "0 ≤ scoops ≤ 100",
    )?;
    let scene = cut_block_scene(options.seed, options.cuts);
    let frames = scene.frames;
    let (mut sim, body) = run_scene(scene, frames, options.cut_mode)?;
    let violations = check_invariants(sim.world()).len();
    let cut = Clusterings::of(&mut sim, body)?;
    let (rebuilt, fresh) = cut.shapes();
    let block = BlockFidelity {
        cuts: options.cuts,
        particles: cut.lattice.live_count(),
        pieces: cut.lattice.piece_count(),
        violations,
        rebuilt,
        fresh,
        ratio: rebuilt.ratios_to(&fresh),
    };
    let scene = scooped_cantilever_scene(options.seed, options.scoops);
    let (desc, gravity) = (scene.bodies[0].clone(), scene.config.gravity);
    // the scoops are over after a frame per four of them, and two more
    let (mut sim, body) = run_scene(scene, options.scoops.div_ceil(4) + 3, options.cut_mode)?;
    let scooped = Clusterings::of(&mut sim, body)?;
    let intact = {
        let lattice = desc.shape.voxelise(desc.spacing)?;
        let seed_grid = sim
            .world()
            .get::<Body>(body)
            .map(|b| b.seed_grid)
            .unwrap_or_default();
        let clusters = clusters_on_grid(&lattice, &desc.material, seed_grid).into_clusters();
        static_sag(&desc, &lattice, &clusters, gravity)
    };
    let (rebuilt_sag, fresh_sag) = (
        static_sag(&desc, &scooped.lattice, &scooped.rebuilt, gravity),
        static_sag(&desc, &scooped.lattice, &scooped.fresh, gravity),
    );
    let (rebuilt, fresh) = scooped.shapes();
    let cantilever = CantileverFidelity {
        scoops: options.scoops,
        particles: scooped.lattice.live_count(),
        intact_sag_h: intact,
        rebuilt_sag_h: rebuilt_sag,
        fresh_sag_h: fresh_sag,
        ratio: rebuilt_sag / fresh_sag,
        shape_ratio: rebuilt.ratios_to(&fresh),
    };
    Ok(FidelityReport {
        seed: options.seed,
        cut_mode: options.cut_mode,
        block,
        cantilever,
    })
}
