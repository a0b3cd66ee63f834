//! The measurements behind `cleave bench`: step time of boxes of n³ particles in the
//! engine and, in the same run, in a bare dense kernel on the same clusters; memory per
//! particle; a full slice cut event against re-clustering; and a convergence table of
//! the two solver schemes. The bodies here keep no drawable surface:
//! [`crate::analysis::bench_surface`] times that on its own.

use crate::analysis::static_solve::StaticProblem;
use crate::body::shape::Shape;
use crate::clusters::clustering::initial_clusters;
use crate::config::{Material, SimConfig, SolverMode};
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::components::{BodyLattice, ClusterMembers};
use crate::ecs::desc::{BodyDesc, ToolDesc};
use crate::ecs::layout::{BodyItem, ClusterItem, SolverCache};
use crate::ecs::resources::{CutTimings, SimSettings};
use crate::error::Result;
use crate::sim::simulation::Simulation;
use crate::solver::particles::Particles;
use crate::solver::registry::{TermSeconds, Terms};
use crate::solver::solve::Solver;
use crate::solver::term::Substep;
use crate::solver::terms::colliders::Colliders;
use glam::{Quat, UVec3, Vec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::time::Instant;

/// Lattice spacing of the bench boxes.
const H: f32 = 0.1;

/// The time one part of the engine's solves took: the clusters, a registered term, or
/// projective dynamics' global step.
#[derive(Clone, Debug, Serialize)]
pub struct KindTime {
    /// The part's name (a term's [`crate::solver::term::Term::name`]).
    pub name: String,
    /// Median milliseconds per step over the timed steps (a median, as the step's own
    /// time is: within every step a part takes no longer than the step, so its median
    /// is no more than the step's, however long a step the machine stalls).
    pub ms_per_step: f64,
}

/// One line of the bench report.
#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    /// Edge length of the box in particles.
    pub size: u32,
    /// Worker threads.
    pub threads: usize,
    /// Solver scheme.
    pub solver: SolverMode,
    /// Particles.
    pub particles: usize,
    /// Clusters.
    pub clusters: usize,
    /// Memberships (sum of cluster sizes).
    pub memberships: usize,
    /// Solver iterations per step (substeps × iterations).
    pub iterations: u32,
    /// Median wall time of one engine step (ECS schedule), ms.
    pub ms_per_step: f64,
    /// `ms_per_step / (memberships × iterations)`, ns.
    pub ns_per_membership_iteration: f64,
    /// Median wall time of one step of the bare kernel, ms.
    pub bare_ms_per_step: f64,
    /// The bare kernel's ns per membership-iteration.
    pub bare_ns_per_membership_iteration: f64,
    /// `ms_per_step / bare_ms_per_step`.
    pub engine_over_bare: f64,
    /// Peak resident memory of the process / particles, read after the engine's steps
    /// and before the bare kernel runs (sizes run ascending, so earlier sizes are smaller).
    pub bytes_per_particle: f64,
    /// Regroup + split + expand of a full slice through the middle, ms.
    pub cut_event_ms: f64,
    /// The whole step in which that slice happens (detection, removal, the cut event,
    /// the deferred despawns, the layout update and the solve), ms.
    pub cut_frame_ms: f64,
    /// Initial clustering of the cut body from scratch, ms.
    pub recluster_ms: f64,
    /// The same slice severing instead of removing (a fresh box): the cut event and
    /// the cut frame, ms.
    pub sever_event_ms: f64,
    /// See [`BenchRow::sever_event_ms`].
    pub sever_frame_ms: f64,
    /// The same slice in split mode (a fresh box; the blade lies on the faces between
    /// two layers of cells, so it severs there rather than splits): event and frame, ms.
    pub split_event_ms: f64,
    /// See [`BenchRow::split_event_ms`].
    pub split_frame_ms: f64,
    /// Bringing the solver layout up to date in the step after the cut, ms.
    pub relayout_ms: f64,
    /// Whether that update patched the layout (false: a full rebuild).
    pub relayout_patched: bool,
    /// A full rebuild of the solver layout of the cut body, for comparison, ms.
    pub rebuild_ms: f64,
    /// Every part of the engine's solves (clusters, each registered term), in order.
    pub kinds: Vec<KindTime>,
}

/// The edge row of the bench: an n³ box whose material has edge distance constraints,
/// stepped as a size row is.
#[derive(Clone, Debug, Serialize)]
pub struct EdgeRow {
    /// Always `"edges"` (tells this row from the others in JSON lines).
    pub row: &'static str,
    /// Edge length of the box in particles.
    pub size: u32,
    /// Particles.
    pub particles: usize,
    /// Edge constraints (live lattice edges).
    pub edges: usize,
    /// Solver iterations per step (substeps × iterations).
    pub iterations: u32,
    /// Median wall time of one engine step, ms.
    pub ms_per_step: f64,
    /// Median time the edge term took in a step, ms (taken inside each timed step, so
    /// never above [`EdgeRow::ms_per_step`]).
    pub edge_ms_per_step: f64,
    /// `edge_ms_per_step / (edges × iterations)`, ns.
    pub ns_per_edge_iteration: f64,
}

/// Steps an n³ box with edge constraints (`edge_compliance` 1e-7) `steps` times after
/// three warm-up steps, and times the edge term.
pub fn bench_edges(n: u32, steps: usize, config: &SimConfig) -> Result<EdgeRow> {
    let mut sim = Simulation::new(config.clone())?;
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(n)), H);
    desc.position = Vec3::new(0.0, n as f32 * H * 0.5 + 0.05, 0.0);
    desc.material = Material {
        edge_compliance: Some(1e-7),
        ..Material::rigid()
    };
    sim.spawn_body(&desc)?;
    // (the surfaces have their own row)
    sim.drop_surfaces();
    for _ in 0..3 {
        sim.step();
    }
    // (per step, the edge term's share of it: a median of those is never above the
    // steps' median, as a mean over a step that the machine stalled could be)
    let (mut samples, mut edge_samples): (Vec<f64>, Vec<f64>) = (0..steps.max(1))
        .map(|_| {
            let before = kind_seconds(&sim, "edges");
            let step = time_ms(1, || sim.step());
            (step, (kind_seconds(&sim, "edges") - before) * 1e3)
        })
        .unzip();
    let edge_ms_per_step = median(&mut edge_samples);
    let cache = sim.world().resource::<SolverCache>();
    let edges = cache
        .solver
        .terms
        .extent("edges")
        .map_or(0, |e| e.constraints);
    let iterations = config.substeps * config.iterations;
    Ok(EdgeRow {
        row: "edges",
        size: n,
        particles: cache.particles.len(),
        edges,
        iterations,
        ms_per_step: median(&mut samples),
        edge_ms_per_step,
        ns_per_edge_iteration: edge_ms_per_step * 1e6 / (edges as f64 * iterations as f64),
    })
}

/// The median of `samples` (0 for none).
pub fn median(samples: &mut [f64]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

/// Milliseconds of `f`, run `runs` times, median.
pub(crate) fn time_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut samples: Vec<f64> = (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    median(&mut samples)
}

/// Peak resident set size of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_resident_bytes() -> Option<u64> {
    process_status_bytes("VmHWM:")
}

/// Starts a new window for [`peak_resident_bytes`]: resets the process's peak to what it
/// holds now (Linux `clear_refs`) and returns that, the resident set size in bytes, or
/// `None` where the peak cannot be reset.
pub fn reset_peak_resident() -> Option<u64> {
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    process_status_bytes("VmRSS:")
}

/// A line `key  N kB` of `/proc/self/status`, in bytes.
fn process_status_bytes(key: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(key))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// A simulation with one rigid n³ box resting just above the ground.
fn box_simulation(n: u32, config: &SimConfig) -> Result<Simulation> {
    let mut sim = Simulation::new(config.clone())?;
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(n)), H);
    desc.material = Material::rigid();
    desc.position = Vec3::new(0.0, n as f32 * H * 0.5 + 0.05, 0.0);
    sim.spawn_body(&desc)?;
    sim.drop_surfaces();
    Ok(sim)
}

/// Seconds the part `name` of `sim`'s solves (a term, or "clusters") has taken so far.
pub fn kind_seconds(sim: &Simulation, name: &str) -> f64 {
    let cache = sim.world().resource::<SolverCache>();
    cache
        .solver
        .seconds()
        .into_iter()
        .find(|(n, _)| *n == name)
        .map_or(0.0, |(_, s)| s)
}

/// Seconds the registered term `name` of `sim`'s solves has taken so far, by phase
/// (zero when none is registered).
pub fn term_seconds(sim: &Simulation, name: &str) -> TermSeconds {
    let cache = sim.world().resource::<SolverCache>();
    let mut terms = cache.solver.terms.phase_seconds();
    terms
        .find(|(n, _)| *n == name)
        .map_or_else(TermSeconds::default, |(_, s)| s)
}

/// One step of the bare kernel: the engine's prediction and solve on dense arrays only.
fn bare_step(solver: &mut Solver, particles: &mut Particles, config: &SimConfig) {
    let dt = config.dt / config.substeps as f32;
    for index in 0..config.substeps {
        let cluster_counts = solver.clusters.member_counts();
        particles.predict(dt, config.gravity, config.damping, cluster_counts);
        let count = config.substeps as f32;
        let step = Substep {
            dt,
            iterations: config.iterations,
            frame_span: [index as f32 / count, (index + 1) as f32 / count],
        };
        solver.solve(particles, &step);
        let ends_frame = index + 1 == config.substeps;
        let cluster_counts = solver.clusters.member_counts();
        particles.update_velocities(1.0 / dt, cluster_counts, ends_frame);
    }
}

/// The time each part of `sim`'s solves took over `f`, ms.
fn kind_ms(sim: &mut Simulation, f: impl FnOnce(&mut Simulation)) -> Vec<(String, f64)> {
    let before = sim.world().resource::<SolverCache>().solver.seconds();
    f(sim);
    let after = sim.world().resource::<SolverCache>().solver.seconds();
    after
        .into_iter()
        .map(|(name, s)| {
            let was = before.iter().find(|(n, _)| *n == name).map_or(0.0, |b| b.1);
            (name.to_string(), (s - was) * 1e3)
        })
        .collect()
}

/// Measures one box size; `steps` ≥ 1 timed steps after 3 warm-up steps.
pub fn bench_size(n: u32, steps: usize, config: &SimConfig) -> Result<BenchRow> {
    let mut sim = box_simulation(n, config)?;
    for _ in 0..3 {
        sim.step();
    }
    let world = sim.world_mut();
    let memberships: usize = world
        .query::<&ClusterMembers>()
        .iter(world)
        .map(|m| m.0.len())
        .sum();
    let cache = world.resource::<SolverCache>();
    let (particles, clusters) = (cache.particles.len(), cache.solver.clusters.cluster_count());
    // before the bare kernel's copy of the layout exists
    let bytes_per_particle = peak_resident_bytes().unwrap_or(0) as f64 / particles as f64;
    // the bare kernel: the same clusters and particles, the ground and no other term
    let mut bare_terms = Terms::builtin();
    bare_terms.replace(Colliders::from_config(config, std::iter::empty()));
    let (mut solver, mut dense) = cache.bare(bare_terms);
    // Engine and bare steps alternate, so both see the same machine noise.
    let (mut engine, mut bare) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
    let mut kinds: Vec<(String, Vec<f64>)> = Vec::new();
    for _ in 0..steps {
        let step_kinds = kind_ms(&mut sim, |sim| engine.push(time_ms(1, || sim.step())));
        for (name, ms) in step_kinds {
            match kinds.iter_mut().find(|(n, _)| *n == name) {
                Some(k) => k.1.push(ms),
                None => kinds.push((name, vec![ms])),
            }
        }
        bare.push(time_ms(1, || bare_step(&mut solver, &mut dense, config)));
    }
    drop((solver, dense));
    let (ms_per_step, bare_ms_per_step) = (median(&mut engine), median(&mut bare));
    let (cut_event_ms, cut_frame_ms, recluster_ms) = slice_event(&mut sim, n, CutMode::Remove)?;
    sim.world_mut()
        .resource_mut::<SolverCache>()
        .layout
        .forget_last_update();
    sim.step();
    let update = sim.world().resource::<SolverCache>().layout.last_update();
    let rebuild_ms = time_ms(1, || {
        let world = sim.world_mut();
        let mut bodies = world.query::<BodyItem>();
        let mut clusters = world.query::<ClusterItem>();
        SolverCache::laid_out(bodies.iter(world), clusters.iter(world), config.solver);
    });
    drop(sim);
    let mut by_mode = Vec::new();
    for mode in [CutMode::Sever, CutMode::Split] {
        let mut sim = box_simulation(n, config)?;
        sim.step();
        let (event, frame, _) = slice_event(&mut sim, n, mode)?;
        by_mode.push((event, frame));
    }
    let [
        (sever_event_ms, sever_frame_ms),
        (split_event_ms, split_frame_ms),
    ] = by_mode[..]
    else {
        unreachable!("two modes")
    };
    let iterations = config.substeps * config.iterations;
    let per_step = (memberships as f64) * iterations as f64;
    Ok(BenchRow {
        size: n,
        threads: rayon::current_num_threads(),
        solver: config.solver,
        particles,
        clusters,
        memberships,
        iterations,
        ms_per_step,
        ns_per_membership_iteration: ms_per_step * 1e6 / per_step,
        bare_ms_per_step,
        bare_ns_per_membership_iteration: bare_ms_per_step * 1e6 / per_step,
        engine_over_bare: ms_per_step / bare_ms_per_step,
        bytes_per_particle,
        cut_event_ms,
        cut_frame_ms,
        recluster_ms,
        sever_event_ms,
        sever_frame_ms,
        split_event_ms,
        split_frame_ms,
        relayout_ms: update.map_or(f64::NAN, |u| u.ms),
        relayout_patched: update.is_some_and(|u| u.patched),
        rebuild_ms,
        kinds: kinds
            .into_iter()
            .map(|(name, mut ms)| KindTime {
                name,
                ms_per_step: median(&mut ms),
            })
            .collect(),
    })
}

/// Drops a blade in cut mode `mode` through the middle of the box in one frame (a full
/// slice), then times re-clustering the cut body from scratch. Returns `(cut event ms,
/// cut frame ms, recluster ms)`.
fn slice_event(sim: &mut Simulation, n: u32, mode: CutMode) -> Result<(f64, f64, f64)> {
    let now = sim
        .world()
        .resource::<crate::ecs::resources::SimClock>()
        .time;
    let dt = sim.world().resource::<SimSettings>().0.dt;
    let half = n as f32 * H;
    let at = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Blade {
            half_width: half + 1.0,
            half_height: 0.05,
        },
        cut_width: 2.0 * H,
        cut_mode: mode,
        path: Path {
            keys: vec![
                (now as f32, at(2.0 * half + 1.0)),
                (now as f32 + dt, at(-1.0)),
            ],
        },
        pose: at(2.0 * half + 1.0),
    })?;
    sim.world_mut()
        .resource_mut::<CutTimings>()
        .event_ms
        .clear();
    let cut_frame_ms = time_ms(1, || sim.step());
    let cut_event_ms = sim
        .world()
        .resource::<CutTimings>()
        .event_ms
        .last()
        .copied()
        .unwrap_or(f64::NAN);
    let world = sim.world_mut();
    let lattice = world
        .query::<&BodyLattice>()
        .iter(world)
        .next()
        .map(|l| l.lattice.clone());
    let recluster_ms = match lattice {
        Some(l) => time_ms(3, || {
            initial_clusters(&l, &Material::default(), &mut ChaCha8Rng::seed_from_u64(1));
        }),
        None => f64::NAN,
    };
    Ok((cut_event_ms, cut_frame_ms, recluster_ms))
}

/// The relative residual `cleave bench --convergence` solves to: the net force on the
/// particles a thousandth of what it was at the start.
pub const CONVERGED_RESIDUAL: f64 = 1e-3;

/// One solver's row of `cleave bench --convergence`.
#[derive(Clone, Debug, Serialize)]
pub struct ConvergenceRow {
    /// `"jacobi"`, `"gauss-seidel"` or `"projective"`.
    pub solver: String,
    /// Milliseconds of iterations until the twisted box's relative residual is below
    /// [`CONVERGED_RESIDUAL`] (`None`: not within the budget).
    pub twisted_box_ms: Option<f64>,
    /// Iterations that took.
    pub twisted_box_iterations: Option<u32>,
    /// The twisted box's relative residual when the run stopped.
    pub twisted_box_final_residual: f64,
    /// The twisted box's shape error (h) when the run stopped.
    pub twisted_box_final_error_h: f64,
    /// The cantilever's relative residual the run solves to: [`CONVERGED_RESIDUAL`], or
    /// twice the converged static solution's where f32 positions cannot hold less.
    pub cantilever_target_residual: f64,
    /// Milliseconds of iterations until the cantilever's relative residual is below its
    /// target (`None`: not within the budget).
    pub cantilever_ms: Option<f64>,
    /// Iterations that took.
    pub cantilever_iterations: Option<u32>,
    /// The cantilever's relative residual when the run stopped.
    pub cantilever_final_residual: f64,
    /// The tip sag (h) when the run stopped.
    pub cantilever_final_sag_h: f64,
    /// The converged static tip sag (h) every solver is measured against.
    pub cantilever_static_sag_h: f64,
}

/// Settings of `cleave bench --convergence`.
#[derive(Clone, Copy, Debug)]
pub struct ConvergenceOptions {
    /// Edge of the twisted box, in particles.
    pub box_size: u32,
    /// Wall-clock budget of each run, in seconds.
    pub budget_seconds: f64,
}

/// How fast each solver converges on two static problems, with the `cantilever`
/// material (compliant; projective dynamics cannot hold a rigid cluster): (a) an n³
/// box twisted a quarter turn end to end, gravity off and nothing pinned; (b) the
/// built-in `cantilever` (its pins and gravity), from straight. Each is one solve with
/// a time step of [`crate::analysis::static_solve::STATIC_DT`], iterated in blocks of
/// [`crate::analysis::static_solve::BLOCK`] iterations until its residual (the net
/// force on the particles, [`Solver::residual`]) is [`CONVERGED_RESIDUAL`] of the
/// starting one — the measure published solver benchmarks use, shared by every scheme
/// since all minimise the same objective. The cantilever's starting residual is its
/// weight alone, small beside its stiffness, so the rounding of its f32 positions leaves
/// a floor near that: its target is no lower than twice the residual of the converged
/// static solution (projective dynamics settled). The times are of the iterations alone
/// (factorisation included) and stop after `budget_seconds`. The static sag is
/// projective dynamics' converged one, for comparison with each run's final sag.
pub fn convergence(options: ConvergenceOptions) -> Result<Vec<ConvergenceRow>> {
    let scene = crate::io::scene::builtin("cantilever", 0)
        .ok_or_else(|| crate::error::CleaveError::InvalidEntity("no cantilever scene".into()))?;
    let beam = &scene.bodies[0];
    let material = beam.material.clone();
    let n = options.box_size;
    let cube = BodyDesc {
        material: material.clone(),
        ..BodyDesc::new(Shape::cuboid(UVec3::splat(n)), H)
    };
    // the static sag: projective dynamics until the sag moves less than 1e-6 h a block
    let mut settled = StaticProblem::fresh(beam, SolverMode::Projective, scene.config.gravity)?;
    let start = settled.residual();
    let reference = settled.settled_sag(2000, 1e-6);
    let cantilever_target = CONVERGED_RESIDUAL.max(2.0 * settled.residual() / start);
    let to_residual = |problem: &mut StaticProblem, target: f64| {
        let start = problem.residual();
        let relative = |p: &StaticProblem| p.residual() / start;
        problem.run(options.budget_seconds, relative, |r| r < target)
    };
    SolverMode::ALL
        .iter()
        .map(|&solver| {
            let mut twisted = StaticProblem::twisted(&cube, n as f32 * H, solver)?;
            let (twisted_ms, twisted_iterations, twisted_residual) =
                to_residual(&mut twisted, CONVERGED_RESIDUAL);
            let mut beam = StaticProblem::fresh(beam, solver, scene.config.gravity)?;
            let (ms, iterations, residual) = to_residual(&mut beam, cantilever_target);
            Ok(ConvergenceRow {
                solver: solver.name().to_string(),
                twisted_box_ms: twisted_ms,
                twisted_box_iterations: twisted_iterations,
                twisted_box_final_residual: twisted_residual,
                twisted_box_final_error_h: twisted.shape_error(),
                cantilever_target_residual: cantilever_target,
                cantilever_ms: ms,
                cantilever_iterations: iterations,
                cantilever_final_residual: residual,
                cantilever_final_sag_h: beam.sag(),
                cantilever_static_sag_h: reference,
            })
        })
        .collect()
}
