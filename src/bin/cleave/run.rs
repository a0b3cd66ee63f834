//! `cleave run`: simulate a built-in scene, write `summary.json` (and optionally the
//! state dump), print a table.

use crate::pictures::{PictureOptions, Pictures};
use crate::summary::*;
use bevy_ecs::prelude::*;
use cleave::analysis::bench::median;
use cleave::analysis::frames::FrameStats;
use cleave::analysis::profile::{StageProfile, solver_table};
use cleave::analysis::stats::BodyStats;
use cleave::config::{Model, RelaxOptions, SimConfig, SolverMode};
use cleave::cut::tool::CutMode;
use cleave::ecs::check::check_invariants;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::desc::Scene;
use cleave::ecs::handles::{HandlePose, PoseMethod};
use cleave::ecs::layout::SolverCache;
use cleave::ecs::resources::{CutReport, CutTimings, ParticlesCut};
use cleave::io::dump::dump_world;
use cleave::io::render::Draw;
use cleave::io::scene::{BUILTIN_SCENES, builtin};
use cleave::io::scene_file::{entry_position, load_scene_file};
use cleave::sim::simulation::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The built-in scene `name`, or an error listing the built-ins.
pub fn builtin_scene(name: &str, seed: u64) -> Result<Scene, String> {
    builtin(name, seed).ok_or_else(|| {
        let names: Vec<&str> = BUILTIN_SCENES.iter().map(|b| b.name).collect();
        format!("unknown scene `{name}` (built-in: {})", names.join(", "))
    })
}

/// A built-in scene by name, or a scene file (a name ending in `.ron` or an existing
/// file); `seed` overrides the scene's.
pub(crate) fn load_scene(name: &str, seed: Option<u64>) -> Result<Scene, String> {
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
    /// Model of every body.
    pub model: Option<Model>,
    /// Turn conservative culling off.
    pub no_culling: bool,
}

impl SceneOverrides {
    /// `config` with the overrides applied; an out-of-range value is an error naming
    /// its flag.
    fn apply(&self, config: &mut SimConfig) -> Result<(), String> {
        if let Some(solver) = self.solver {
            config.solver = solver;
        }
        if self.no_culling {
            config.culling = false;
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
    /// Relax every body before the first frame even if the scene does not ask for it
    /// (`cleave relax`; then the frames default to 0).
    pub relax: bool,
    /// Pose the bodies with handles by them (`cleave deform`) instead of simulating
    /// them driven by them.
    pub pose: Option<PoseMethod>,
    /// Whether `--method` was given (a resumed `cleave deform` otherwise keeps the
    /// method its save holds).
    pub method_given: bool,
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
fn start(
    scene: &Scene,
    scene_name: &str,
    pose: Option<PoseMethod>,
) -> Result<(Simulation, Vec<Entity>), String> {
    let mut sim = Simulation::new(scene.config.clone()).map_err(|e| e.to_string())?;
    sim.set_label(scene_label(scene_name));
    let fail = |what: &str, i: usize, e: cleave::error::CleaveError| {
        let at = std::fs::read_to_string(scene_name)
            .ok()
            .and_then(|text| entry_position(&text, what, i))
            .map_or(String::new(), |(line, column)| format!(":{line}:{column}"));
        format!("{scene_name}{at}: {what}[{i}]: {e}")
    };
    let mut bodies = Vec::with_capacity(scene.bodies.len());
    for (i, b) in scene.bodies.iter().enumerate() {
        match pose {
            // posed: spawned without its handles' attachments, then posed by them
            Some(method) if !b.handles.is_empty() => {
                let mut bare = b.clone();
                let handles = std::mem::take(&mut bare.handles);
                let body = sim.spawn_body(&bare).map_err(|e| fail("bodies", i, e))?;
                sim.pose_by_handles(body, &handles, method)
                    .map_err(|e| fail("bodies", i, e))?;
                bodies.push(body);
            }
            _ => bodies.push(sim.spawn_body(b).map_err(|e| fail("bodies", i, e))?),
        }
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
    scene: &Scene,
) -> Result<(Simulation, Vec<Entity>), String> {
    let o = &args.overrides;
    let conflicting = [
        ("--seed", seed_given),
        ("--solver", o.solver.is_some()),
        ("--substeps", o.substeps.is_some()),
        ("--iterations", o.iterations.is_some()),
        ("--cut-mode", o.cut_mode.is_some()),
        ("--model", o.model.is_some()),
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
    if let Some(saved) = sim.label()
        && scene_label(saved) != scene_label(&args.scene)
    {
        return Err(format!(
            "--load-state: {} holds a run of scene `{saved}`, not `{}`",
            path.display(),
            scene_label(&args.scene)
        ));
    }
    let bodies = sim.bodies();
    check_posing(&sim, &bodies, args, scene).map_err(|e| format!("--load-state: {e}"))?;
    Ok((sim, bodies))
}

/// What names a scene in a save: a scene file by its canonical path (however it was
/// typed, from wherever), a built-in scene by its name.
fn scene_label(name: &str) -> String {
    match std::fs::canonicalize(name) {
        Ok(path) if path.is_file() => path.display().to_string(),
        _ => name.to_string(),
    }
}

/// A resumed run goes on as the saved one would have: posed by handles with the saved
/// method under `cleave deform`, simulated under `cleave run`.
fn check_posing(
    sim: &Simulation,
    bodies: &[Entity],
    args: &RunArgs,
    scene: &Scene,
) -> Result<(), String> {
    let method_name = |m: &PoseMethod| match m {
        PoseMethod::Linear => "linear",
        PoseMethod::Arap(_) => "arap",
        PoseMethod::Reduced { .. } => "reduced",
    };
    let posed: Vec<&PoseMethod> = bodies
        .iter()
        .filter_map(|b| sim.world().get::<HandlePose>(*b))
        .map(|p| &p.method)
        .collect();
    let has_handles = scene.bodies.iter().any(|b| !b.handles.is_empty());
    match (&args.pose, posed.first()) {
        (None, Some(_)) => Err(
            "the saved run poses its bodies by their handles: resume it with `cleave deform`"
                .into(),
        ),
        (Some(_), None) if has_handles => Err(
            "the saved run simulates its bodies (`cleave run`): resume it with `cleave run`".into(),
        ),
        (Some(given), Some(saved))
            if args.method_given && method_name(given) != method_name(saved) =>
        {
            Err(format!(
                "the saved run poses by `{}`, not `--method {}`",
                method_name(saved),
                method_name(given)
            ))
        }
        _ => Ok(()),
    }
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
    if let Some(model) = args.overrides.model {
        for body in &mut scene.bodies {
            body.material.model = model;
        }
    }
    let seed_given = seed.is_some();
    if args.relax && scene.config.relax.is_none() {
        scene.config.relax = Some(RelaxOptions::default());
    }
    let frames = frames.unwrap_or(if args.relax { 0 } else { scene.frames });
    if let Some(at) = args.recluster_at
        && at > frames
    {
        return Err(format!(
            "--recluster-at: {at} is past the last frame (allowed 0 ≤ recluster-at ≤ {frames})"
        ));
    }
    let (mut sim, bodies) = match &args.load_state {
        Some(path) => resume(path, args, seed_given, &scene)?,
        None => start(&scene, scene_name, args.pose)?,
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
    let mut pictures = Pictures::new(
        &out,
        PictureOptions {
            dt,
            ..args.pictures.clone()
        },
    )?;
    let o = &args.pictures;
    if o.draw == Draw::Particles && !o.obj && !o.gltf {
        // (nothing drawn or written needs them)
        sim.drop_surfaces();
    }
    sim.update_surfaces().map_err(|e| e.to_string())?;
    // a resumed run was relaxed, if at all, before it was saved
    let relaxing = scene
        .config
        .relax
        .as_ref()
        .filter(|_| args.load_state.is_none());
    if relaxing.is_some() {
        pictures.still(sim.world_mut(), "before_relax")?;
    }
    let mut tracked = Vec::with_capacity(bodies.len());
    for (i, (body, h)) in bodies.iter().zip(&spacings).enumerate() {
        let relaxed = match relaxing {
            Some(options) => Some(
                sim.relax(*body, options)
                    .map_err(|e| format!("{scene_name}: settings.relax: bodies[{i}]: {e}"))?,
            ),
            None => None,
        };
        tracked.push(Tracked::new(&mut sim, *body, *h, relaxed)?);
    }
    let h = spacings.iter().copied().fold(f32::INFINITY, f32::min);
    let h_first = spacings.first().copied().unwrap_or(1.0);
    let mut step_ms = Vec::new();
    let mut cut_frames = Vec::new();
    let mut cut_particles = 0;
    let mut min_gap: Option<f64> = None;
    let mut cursor = sim
        .world()
        .resource::<Messages<ParticlesCut>>()
        .get_cursor();
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
        cut_frames.push(!sim.world().resource::<CutReport>().bodies.is_empty());
        // (a layout built afresh starts its count at zero)
        let seconds = sim
            .world()
            .resource::<SolverCache>()
            .solver
            .projective
            .factor_seconds;
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
        // (the statistic of the run, not the engine's work: between frames, outside
        // the timed step)
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
        simulate_ms_total: step_ms.iter().fold(0.0, |sum, ms| sum + ms),
        frame_ms: FrameStats::of(&step_ms),
        cut_frame_ms: FrameStats::of_where(&step_ms, |f| cut_frames[f]),
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
        let parts = sim.world().resource::<SolverCache>().solver.seconds();
        print!("{}", solver_table(&parts, frames));
    }
    if !summary.finite {
        return Err("non-finite particle positions".into());
    }
    Ok(())
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
