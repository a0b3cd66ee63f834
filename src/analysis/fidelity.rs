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
use crate::body::lattice::Lattice;
use crate::clusters::clustering::clusters_on_grid;
use crate::config::SolverMode;
use crate::cut::tool::CutMode;
use crate::ecs::check::check_invariants;
use crate::ecs::components::{Body, BodyLattice};
use crate::ecs::desc::BodyDesc;
use crate::ecs::desc::Scene;
use crate::error::{CleaveError, Result, check_range};
use crate::io::cut_scenes::{MAX_CUTS, cut_block_scene, scooped_cantilever_scene};
use crate::io::scene::builtin;
use crate::sim::simulation::Simulation;
use bevy_ecs::entity::Entity;
use glam::Vec3;
use serde::Serialize;

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
    // (nothing is drawn)
    sim.drop_surfaces();
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
            return Err(CleaveError::not_a("a body", body));
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
    let cantilever = builtin("cantilever", options.seed)
        .ok_or_else(|| CleaveError::InvalidEntity("no cantilever scene".into()))?;
    let scene = scooped_cantilever_scene(cantilever, options.seed, options.scoops);
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
