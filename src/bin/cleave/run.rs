//! `cleave run`: simulate a built-in scene, write `summary.json` (and optionally the
//! state dump), print a table.

use crate::pictures::{PictureOptions, Pictures};
use bevy_ecs::prelude::*;
use cleave::analysis::bench::median;
use cleave::analysis::profile::StageProfile;
use cleave::analysis::stats::{
    BodyStats, body_stats, labelled_positions, min_distance_between_labels,
};
use cleave::config::{SimConfig, SolverMode};
use cleave::cut::tool::CutMode;
use cleave::ecs::check::check_invariants;
use cleave::ecs::components::{BodyLattice, InvMass, Position};
use cleave::ecs::resources::{CutTimings, ParticlesCut, SolverCache};
use cleave::io::dump::dump_world;
use cleave::io::scene::{BUILTIN_SCENES, Scene, builtin};
use cleave::io::scene_file::{entry_position, load_scene_file};
use cleave::sim::simulation::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Serialize)]
struct Summary {
    scene: String,
    frames: u32,
    seed: u64,
    /// The frame after which every body was clustered afresh (`--recluster-at`).
    reclustered_at: Option<u32>,
    threads: usize,
    /// Totals over every body at the end.
    particles: usize,
    clusters: usize,
    memberships: usize,
    pieces: usize,
    cut_particles: usize,
    median_ms_per_step: f64,
    simulate_ms_total: f64,
    pictures_ms_total: f64,
    pictures_written: usize,
    /// The largest over the bodies.
    final_shape_error_h: f64,
    /// The lowest over the bodies, in units of the first body's spacing.
    lowest_particle_y_h: f64,
    finite: bool,
    /// Smallest distance between particles of different pieces (of one body or of two),
    /// over every frame from the first with two pieces in the scene, in units of the
    /// smallest spacing; `null` when no two pieces came within 2 h.
    min_gap_between_pieces_h: Option<f64>,
    /// The same between particles of different bodies, at the end.
    final_min_gap_between_bodies_h: Option<f64>,
    cut_events: usize,
    cut_event_ms_median: f64,
    cut_event_ms_max: f64,
    /// Projective dynamics: milliseconds of each factorization of the global matrix, in
    /// order — the first for the bodies as spawned, each later one after a cut (or a
    /// change of pins) changed it; empty under the other solvers.
    factor_ms: Vec<f64>,
    invariant_violations: usize,
    /// Per body, in spawn order.
    bodies: Vec<BodySummary>,
}

/// What the summary reports of one body.
#[derive(Serialize)]
struct BodySummary {
    before: BodyStats,
    half_time: BodyStats,
    after: BodyStats,
    /// Drop of the particle with the largest lattice x (a cantilever's tip), in h.
    tip_drop_h_half: f64,
    tip_drop_h_end: f64,
    pinned_max_displacement_h: f64,
    piece_separation_start_h: f64,
    piece_separation_end_h: f64,
}

/// What a run follows of one body.
struct Tracked {
    body: Entity,
    h: f32,
    lattice: BodyLattice,
    tip: u32,
    tip_start: Option<glam::Vec3>,
    pinned: Vec<(u32, glam::Vec3)>,
    start_positions: Vec<glam::Vec3>,
    before: BodyStats,
    half: BodyStats,
    tip_half: f64,
}

impl Tracked {
    fn new(sim: &mut Simulation, body: Entity, h: f32) -> Result<Self, String> {
        let lattice = sim
            .world()
            .get::<BodyLattice>(body)
            .ok_or("no lattice")?
            .clone();
        let l = &lattice.lattice;
        let tip = (0..l.len() as u32)
            .max_by_key(|i| (l.coord(*i).x, -(*i as i64)))
            .unwrap_or(0);
        let mut tracked = Self {
            body,
            h,
            tip,
            tip_start: None,
            pinned: Vec::new(),
            start_positions: Vec::new(),
            before: body_stats(sim.world_mut(), body).ok_or("no body")?,
            half: BodyStats::default(),
            tip_half: 0.0,
            lattice,
        };
        tracked.tip_start = tracked.position(sim, tip);
        tracked.pinned = (0..tracked.lattice.lattice.len() as u32)
            .filter(|i| {
                sim.world()
                    .get::<InvMass>(tracked.lattice.particles[*i as usize])
                    .is_some_and(|m| m.0 == 0.0)
            })
            .filter_map(|i| Some((i, tracked.position(sim, i)?)))
            .collect();
        tracked.start_positions = tracked.all_positions(sim);
        Ok(tracked)
    }

    fn position(&self, sim: &Simulation, i: u32) -> Option<glam::Vec3> {
        sim.world()
            .get::<Position>(self.lattice.particles[i as usize])
            .map(|p| p.0)
    }

    fn all_positions(&self, sim: &Simulation) -> Vec<glam::Vec3> {
        (0..self.lattice.lattice.len() as u32)
            .map(|i| self.position(sim, i).unwrap_or(glam::Vec3::ZERO))
            .collect()
    }

    fn tip_drop(&self, sim: &Simulation) -> f64 {
        match (self.tip_start, self.position(sim, self.tip)) {
            (Some(a), Some(b)) => ((a.y - b.y) / self.h) as f64,
            _ => f64::NAN,
        }
    }

    fn at_half_time(&mut self, sim: &mut Simulation) -> Result<(), String> {
        self.half = body_stats(sim.world_mut(), self.body).ok_or("no body")?;
        self.tip_half = self.tip_drop(sim);
        Ok(())
    }

    fn summary(self, sim: &mut Simulation) -> Result<BodySummary, String> {
        let after = body_stats(sim.world_mut(), self.body).ok_or("no body")?;
        let pinned_max = self
            .pinned
            .iter()
            .filter_map(|(i, p0)| Some(self.position(sim, *i)?.distance(*p0) / self.h))
            .fold(0.0f32, f32::max) as f64;
        let final_lattice = &sim
            .world()
            .get::<BodyLattice>(self.body)
            .ok_or("no lattice")?
            .lattice;
        let separation = piece_separation(
            final_lattice,
            &self.start_positions,
            &self.all_positions(sim),
            self.h,
        );
        Ok(BodySummary {
            tip_drop_h_half: self.tip_half,
            tip_drop_h_end: self.tip_drop(sim),
            pinned_max_displacement_h: pinned_max,
            piece_separation_start_h: separation.0,
            piece_separation_end_h: separation.1,
            before: self.before,
            half_time: self.half,
            after,
        })
    }
}

/// The smallest distances between particles of different pieces and of different
/// bodies, in units of `h`, among pairs closer than 2 h.
fn gaps(sim: &mut Simulation, h: f32) -> (Option<f64>, Option<f64>) {
    let labelled = labelled_positions(sim.world_mut());
    let points: Vec<glam::Vec3> = labelled.iter().map(|(p, ..)| *p).collect();
    let pieces: Vec<u64> = labelled
        .iter()
        .map(|(_, body, piece)| ((*body as u64) << 32) | *piece as u64)
        .collect();
    let bodies: Vec<u64> = labelled.iter().map(|(_, body, _)| *body as u64).collect();
    let gap = |labels: &[u64]| {
        min_distance_between_labels(&points, labels, 2.0 * h).map(|d| (d / h) as f64)
    };
    (gap(&pieces), gap(&bodies))
}

/// Mean pairwise distance between the centroids of the final pieces, in units of h,
/// with the centroids taken over the same particles at the start and at the end (the
/// particles there at the start: not the new halves of split particles).
fn piece_separation(
    lattice: &cleave::body::lattice::Lattice,
    start: &[glam::Vec3],
    end: &[glam::Vec3],
    h: f32,
) -> (f64, f64) {
    let (labels, pieces) = cleave::body::graph::body_pieces(lattice);
    if pieces < 2 {
        return (0.0, 0.0);
    }
    let centroids = |pos: &[glam::Vec3]| {
        let mut sum = vec![(glam::Vec3::ZERO, 0usize); pieces];
        for i in lattice
            .live_particles()
            .filter(|i| (*i as usize) < start.len())
        {
            let s = &mut sum[labels[i as usize] as usize];
            s.0 += pos[i as usize];
            s.1 += 1;
        }
        sum.into_iter()
            .map(|(v, n)| v / n.max(1) as f32)
            .collect::<Vec<_>>()
    };
    let mean_distance = |c: &[glam::Vec3]| {
        let mut total = 0.0;
        let mut pairs = 0;
        for a in 0..c.len() {
            for b in a + 1..c.len() {
                total += c[a].distance(c[b]);
                pairs += 1;
            }
        }
        (total / pairs as f32 / h) as f64
    };
    (
        mean_distance(&centroids(start)),
        mean_distance(&centroids(end)),
    )
}

/// The built-in scene `name`, or an error listing the built-ins.
pub fn builtin_scene(name: &str, seed: u64) -> Result<Scene, String> {
    builtin(name, seed).ok_or_else(|| {
        let names: Vec<&str> = BUILTIN_SCENES.iter().map(|(n, _)| *n).collect();
        format!("unknown scene `{name}` (built-in: {})", names.join(", "))
    })
}

/// A built-in scene by name, or a scene file (a name ending in `.ron` or an existing
/// file); `seed` overrides the scene's.
fn load_scene(name: &str, seed: Option<u64>) -> Result<Scene, String> {
    let path = Path::new(name);
    let mut scene = if name.ends_with(".ron") || path.is_file() {
        load_scene_file(path)?
    } else {
        builtin_scene(name, seed.unwrap_or(0))?
    };
    if let Some(seed) = seed {
        scene.config.seed = seed;
    }
    Ok(scene)
}

/// Settings given on the command line, overriding the scene's.
#[derive(Clone, Copy, Debug, Default)]
pub struct SceneOverrides {
    /// Solver scheme.
    pub solver: Option<SolverMode>,
    /// Substeps per frame.
    pub substeps: Option<u32>,
    /// Iterations per substep.
    pub iterations: Option<u32>,
    /// Cut mode of every tool.
    pub cut_mode: Option<CutMode>,
}

impl SceneOverrides {
    /// `config` with the overrides applied; an out-of-range value is an error naming
    /// its flag.
    fn apply(&self, config: &mut SimConfig) -> Result<(), String> {
        if let Some(solver) = self.solver {
            config.solver = solver;
        }
        for (flag, value, slot, max) in [
            ("--substeps", self.substeps, &mut config.substeps, 1000),
            (
                "--iterations",
                self.iterations,
                &mut config.iterations,
                10_000,
            ),
        ] {
            if let Some(v) = value {
                if !(1..=max).contains(&v) {
                    return Err(format!(
                        "{flag}: {v} is out of range (allowed 1 ≤ {} ≤ {max})",
                        &flag[2..]
                    ));
                }
                *slot = v;
            }
        }
        Ok(())
    }
}

/// Arguments of `cleave run`.
#[derive(Clone, Debug)]
pub struct RunArgs {
    /// Built-in scene name.
    pub scene: String,
    /// Frame after which every body is clustered afresh.
    pub recluster_at: Option<u32>,
    /// Solver settings overriding the scene's.
    pub overrides: SceneOverrides,
    /// Frames (default: the scene's).
    pub frames: Option<u32>,
    /// Output directory.
    pub out: PathBuf,
    /// Seed (default: the scene's).
    pub seed: Option<u64>,
    /// State dump file.
    pub dump_state: Option<PathBuf>,
    /// Where to save the simulation at the end (`--save-state`).
    pub save_state: Option<PathBuf>,
    /// A saved simulation to run on instead of the scene's start (`--load-state`).
    pub load_state: Option<PathBuf>,
    /// Pictures to write.
    pub pictures: PictureOptions,
    /// Print milliseconds per stage.
    pub profile: bool,
    /// No progress bar and no table.
    pub quiet: bool,
}

/// A new simulation of `scene` (errors name the scene, the entry's line and column in a
/// scene file, and the entry); returns it and its bodies.
fn start(scene: &Scene, scene_name: &str) -> Result<(Simulation, Vec<Entity>), String> {
    let mut sim = Simulation::new(scene.config.clone()).map_err(|e| e.to_string())?;
    let fail = |what: &str, i: usize, e: cleave::error::CleaveError| {
        let at = std::fs::read_to_string(scene_name)
            .ok()
            .and_then(|text| entry_position(&text, what, i))
            .map_or(String::new(), |(line, column)| format!(":{line}:{column}"));
        format!("{scene_name}{at}: {what}[{i}]: {e}")
    };
    let mut bodies = Vec::with_capacity(scene.bodies.len());
    for (i, b) in scene.bodies.iter().enumerate() {
        bodies.push(sim.spawn_body(b).map_err(|e| fail("bodies", i, e))?);
    }
    for (i, t) in scene.tools.iter().enumerate() {
        sim.spawn_tool(t).map_err(|e| fail("tools", i, e))?;
    }
    for (i, c) in scene.colliders.iter().enumerate() {
        sim.spawn_collider(c).map_err(|e| fail("colliders", i, e))?;
    }
    Ok((sim, bodies))
}

/// The simulation saved in `path` (`--load-state`), which brings its own settings: the
/// flags that would change them are refused.
fn resume(
    path: &Path,
    args: &RunArgs,
    seed_given: bool,
) -> Result<(Simulation, Vec<Entity>), String> {
    let o = &args.overrides;
    let conflicting = [
        ("--seed", seed_given),
        ("--solver", o.solver.is_some()),
        ("--substeps", o.substeps.is_some()),
        ("--iterations", o.iterations.is_some()),
        ("--cut-mode", o.cut_mode.is_some()),
    ];
    if let Some((flag, _)) = conflicting.iter().find(|(_, given)| *given) {
        return Err(format!(
            "--load-state: {flag} cannot be combined with it (a saved simulation keeps its settings)"
        ));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| format!("{}: cannot be opened: {e}", path.display()))?;
    let mut sim = Simulation::load(std::io::BufReader::new(file))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let bodies = sim.bodies();
    Ok((sim, bodies))
}

/// Runs the scene and writes the outputs.
pub fn run(args: &RunArgs, threads: usize) -> Result<(), String> {
    let (scene_name, frames, out, seed, dump) = (
        args.scene.as_str(),
        args.frames,
        args.out.clone(),
        args.seed,
        args.dump_state.clone(),
    );
    // The systems' spans are made when the schedule is built: profile from the start.
    let profile = StageProfile::default();
    let _profiling = args.profile.then(|| profile.install());
    let mut scene = load_scene(scene_name, seed)?;
    args.overrides.apply(&mut scene.config)?;
    if let Some(mode) = args.overrides.cut_mode {
        for tool in &mut scene.tools {
            tool.cut_mode = mode;
        }
    }
    let seed_given = seed.is_some();
    let frames = frames.unwrap_or(scene.frames);
    if let Some(at) = args.recluster_at
        && at > frames
    {
        return Err(format!(
            "--recluster-at: {at} is past the last frame (allowed 0 ≤ recluster-at ≤ {frames})"
        ));
    }
    let (mut sim, bodies) = match &args.load_state {
        Some(path) => resume(path, args, seed_given)?,
        None => start(&scene, scene_name)?,
    };
    let seed = sim.config().seed;
    let dt = sim.config().dt;
    let spacings: Vec<f32> = bodies
        .iter()
        .map(|b| {
            sim.world()
                .get::<BodyLattice>(*b)
                .map_or(1.0, |l| l.lattice.spacing())
        })
        .collect();
    let mut tracked = Vec::with_capacity(bodies.len());
    for (body, h) in bodies.iter().zip(&spacings) {
        tracked.push(Tracked::new(&mut sim, *body, *h)?);
    }
    let h = spacings.iter().copied().fold(f32::INFINITY, f32::min);
    let h_first = spacings.first().copied().unwrap_or(1.0);
    let mut step_ms = Vec::new();
    let mut cut_particles = 0;
    let mut min_gap: Option<f64> = None;
    let mut cursor = sim
        .world()
        .resource::<Messages<ParticlesCut>>()
        .get_cursor();
    let mut pictures = Pictures::new(
        &out,
        PictureOptions {
            dt,
            ..args.pictures.clone()
        },
    )?;
    pictures.frame(sim.world_mut(), 0)?;
    let recluster = |sim: &mut Simulation, frame: u32| -> Result<(), String> {
        if args.recluster_at == Some(frame) {
            for &body in &bodies {
                sim.recluster(body).map_err(|e| e.to_string())?;
            }
        }
        Ok(())
    };
    recluster(&mut sim, 0)?;
    let progress = progress_bar(frames, args.quiet);
    let mut factor_ms = Vec::new();
    let mut factor_seconds = 0.0;
    for frame in 1..=frames {
        progress.inc(1);
        let t = Instant::now();
        sim.step();
        step_ms.push(t.elapsed().as_secs_f64() * 1e3);
        // (a layout built afresh starts its count at zero)
        let seconds = sim.world().resource::<SolverCache>().layout.factor_seconds;
        if seconds != factor_seconds {
            factor_ms.push(
                1e3 * (seconds
                    - if seconds > factor_seconds {
                        factor_seconds
                    } else {
                        0.0
                    }),
            );
            factor_seconds = seconds;
        }
        recluster(&mut sim, frame)?;
        pictures.frame(sim.world_mut(), frame)?;
        cut_particles += cursor
            .read(sim.world().resource::<Messages<ParticlesCut>>())
            .map(|m| m.particles.len())
            .sum::<usize>();
        let pieces: usize = sim
            .world_mut()
            .query::<&BodyLattice>()
            .iter(sim.world())
            .map(|b| b.pieces)
            .sum();
        if pieces > 1
            && let (Some(gap), _) = gaps(&mut sim, h)
        {
            min_gap = Some(min_gap.map_or(gap, |m| m.min(gap)));
        }
        if frame == frames / 2 {
            for t in &mut tracked {
                t.at_half_time(&mut sim)?;
            }
        }
    }
    progress.finish_and_clear();
    let violations = check_invariants(sim.world());
    let final_gaps = gaps(&mut sim, h);
    let mut per_body = Vec::with_capacity(tracked.len());
    for t in tracked {
        per_body.push(t.summary(&mut sim)?);
    }
    let mut events = sim.world().resource::<CutTimings>().event_ms.clone();
    let total = |f: fn(&BodyStats) -> usize| per_body.iter().map(|b| f(&b.after)).sum();
    let summary = Summary {
        scene: scene_name.into(),
        frames,
        seed,
        reclustered_at: args.recluster_at,
        threads,
        particles: total(|s| s.particles),
        clusters: total(|s| s.clusters),
        memberships: total(|s| s.memberships),
        pieces: total(|s| s.pieces),
        cut_particles,
        simulate_ms_total: step_ms.iter().sum(),
        pictures_ms_total: pictures.ms,
        pictures_written: pictures.files,
        median_ms_per_step: median(&mut step_ms),
        final_shape_error_h: per_body
            .iter()
            .map(|b| b.after.shape_error_h)
            .fold(0.0, f64::max),
        lowest_particle_y_h: per_body
            .iter()
            .map(|b| b.after.lowest_y)
            .fold(f64::INFINITY, f64::min)
            / h_first as f64,
        finite: per_body.iter().all(|b| b.after.finite),
        min_gap_between_pieces_h: min_gap,
        final_min_gap_between_bodies_h: final_gaps.1,
        cut_events: events.len(),
        cut_event_ms_max: events.iter().copied().fold(0.0, f64::max),
        cut_event_ms_median: median(&mut events),
        factor_ms,
        invariant_violations: violations.len(),
        bodies: per_body,
    };
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let path = out.join("summary.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?,
    )
    .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    if let Some(path) = &args.save_state {
        let file = std::fs::File::create(path)
            .map_err(|e| format!("cannot create `{}`: {e}", path.display()))?;
        sim.save(std::io::BufWriter::new(file))
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if let Some(file) = dump {
        let state = dump_world(sim.world_mut());
        std::fs::write(
            &file,
            serde_json::to_string(&state).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write `{}`: {e}", file.display()))?;
    }
    if !args.quiet {
        print_table(&summary, &path, &out);
    }
    if args.profile {
        print!("{}", profile.table(frames));
    }
    if !summary.finite {
        return Err("non-finite particle positions".into());
    }
    Ok(())
}

/// A row of the report: its name and what it reads of a body's statistics.
type Row = (&'static str, fn(&BodyStats) -> f64);

/// The short report printed after a run: totals, then one block per body.
fn print_table(s: &Summary, path: &Path, out: &Path) {
    println!(
        "scene {}: {} frames, seed {}, {} thread(s), {} bod{}",
        s.scene,
        s.frames,
        s.seed,
        s.threads,
        s.bodies.len(),
        if s.bodies.len() == 1 { "y" } else { "ies" }
    );
    let sum = |f: fn(&BodyStats) -> f64, before: bool| -> f64 {
        s.bodies
            .iter()
            .map(|b| f(if before { &b.before } else { &b.after }))
            .sum()
    };
    let rows: [Row; 6] = [
        ("particles", |b| b.particles as f64),
        ("clusters", |b| b.clusters as f64),
        ("mean cluster size", |b| b.mean_cluster_size),
        ("memberships / particle", |b| b.memberships_per_particle),
        ("pieces", |b| b.pieces as f64),
        ("shape error (h)", |b| b.shape_error_h),
    ];
    println!("  {:<28} {:>12} {:>12}", "", "start", "end");
    for (i, b) in s.bodies.iter().enumerate() {
        if s.bodies.len() > 1 {
            println!("  body {i}");
        }
        for (name, f) in &rows {
            println!("  {name:<28} {:>12.3} {:>12.3}", f(&b.before), f(&b.after));
        }
        println!(
            "  piece centroids {:.2} h apart at start, {:.2} h at end; tip drop {:.3} h at half time, {:.3} h at end; pinned moved ≤ {:.4} h",
            b.piece_separation_start_h,
            b.piece_separation_end_h,
            b.tip_drop_h_half,
            b.tip_drop_h_end,
            b.pinned_max_displacement_h
        );
    }
    if s.bodies.len() > 1 {
        println!("  total");
        for (name, f) in &rows[..2] {
            println!(
                "  {name:<28} {:>12.0} {:>12.0}",
                sum(*f, true),
                sum(*f, false)
            );
        }
        println!(
            "  {:<28} {:>12.0} {:>12.0}",
            "pieces",
            sum(|b| b.pieces as f64, true),
            s.pieces
        );
    }
    let gap = |g: Option<f64>| g.map_or("none within 2 h".to_string(), |g| format!("{g:.2} h"));
    println!(
        "  median step {:.3} ms; lowest particle {:.3} h; cut particles {}; cut events {} (median {:.3} ms, max {:.3} ms)",
        s.median_ms_per_step,
        s.lowest_particle_y_h,
        s.cut_particles,
        s.cut_events,
        s.cut_event_ms_median,
        s.cut_event_ms_max
    );
    println!(
        "  smallest gap between pieces {}; between bodies at the end {}; invariant violations {}",
        gap(s.min_gap_between_pieces_h),
        gap(s.final_min_gap_between_bodies_h),
        s.invariant_violations
    );
    println!(
        "  simulated in {:.0} ms; {} picture file(s) in {:.0} ms",
        s.simulate_ms_total, s.pictures_written, s.pictures_ms_total
    );
    println!(
        "  wrote {} (and pictures in {})",
        path.display(),
        out.display()
    );
}

/// A progress bar on stderr when it is a terminal (hidden otherwise or with `--quiet`).
fn progress_bar(frames: u32, quiet: bool) -> ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(frames as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames {elapsed_precise} (eta {eta})")
    {
        bar.set_style(style);
    }
    bar
}
