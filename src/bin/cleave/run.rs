//! `cleave run`: simulate a built-in scene, write `summary.json` (and optionally the
//! state dump), print a table.

use crate::pictures::{PictureOptions, Pictures};
use crate::run_frames::FrameLog;
use crate::summary::*;
use bevy_ecs::prelude::*;
use cleave::analysis::profile::{StageProfile, solver_table};
use cleave::config::{Model, RelaxOptions, SimConfig, SolverMode};
use cleave::cut::tool::CutMode;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::desc::Scene;
use cleave::ecs::handles::{HandlePose, PoseMethod};
use cleave::ecs::layout::SolverCache;
use cleave::io::dump::dump_world;
use cleave::io::render::Draw;
use cleave::io::scene::{BUILTIN_SCENES, builtin};
use cleave::io::scene_file::{entry_position, load_scene_file};
use cleave::sim::simulation::Simulation;
use std::path::{Path, PathBuf};

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
    // The systems' spans are made when the schedule is built: profile from the start.
    let profile = StageProfile::default();
    let _profiling = args.profile.then(|| profile.install());
    let (scene, frames) = prepared_scene(args)?;
    let (mut sim, bodies) = match &args.load_state {
        Some(path) => resume(path, args, args.seed.is_some(), &scene)?,
        None => start(&scene, &args.scene, args.pose)?,
    };
    let spacings: Vec<f32> = bodies
        .iter()
        .map(|b| {
            sim.world()
                .get::<BodyLattice>(*b)
                .map_or(1.0, |l| l.lattice.spacing())
        })
        .collect();
    let mut pictures = Pictures::new(
        &args.out,
        PictureOptions {
            dt: sim.config().dt,
            ..args.pictures.clone()
        },
    )?;
    let o = &args.pictures;
    if o.draw == Draw::Particles && !o.obj && !o.gltf {
        // (nothing drawn or written needs them)
        sim.drop_surfaces();
    }
    sim.update_surfaces().map_err(|e| e.to_string())?;
    let mut tracked = track_bodies(&mut sim, &scene, args, &bodies, &spacings, &mut pictures)?;
    let run = FrameLog::simulate(
        &mut sim,
        frames,
        args.recluster_at,
        args.quiet,
        &bodies,
        &mut tracked,
        &mut pictures,
        &spacings,
    )?;
    let summary = run.summary(
        &mut sim,
        &args.scene,
        args.recluster_at,
        frames,
        threads,
        tracked,
        &pictures,
        &spacings,
    )?;
    write_outputs(&mut sim, args, &summary)?;
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

/// The scene with the command line's overrides, and the frames to run.
fn prepared_scene(args: &RunArgs) -> Result<(Scene, u32), String> {
    let mut scene = load_scene(&args.scene, args.seed)?;
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
    if args.relax && scene.config.relax.is_none() {
        scene.config.relax = Some(RelaxOptions::default());
    }
    let frames = args
        .frames
        .unwrap_or(if args.relax { 0 } else { scene.frames });
    if let Some(at) = args.recluster_at
        && at > frames
    {
        return Err(format!(
            "--recluster-at: {at} is past the last frame (allowed 0 ≤ recluster-at ≤ {frames})"
        ));
    }
    Ok((scene, frames))
}

/// Relaxes every body if the scene asks (a resumed run was relaxed, if at all, before
/// it was saved) and starts following each one for the summary.
fn track_bodies(
    sim: &mut Simulation,
    scene: &Scene,
    args: &RunArgs,
    bodies: &[Entity],
    spacings: &[f32],
    pictures: &mut Pictures,
) -> Result<Vec<Tracked>, String> {
    let relaxing = scene
        .config
        .relax
        .as_ref()
        .filter(|_| args.load_state.is_none());
    if relaxing.is_some() {
        pictures.still(sim.world_mut(), "before_relax")?;
    }
    let mut tracked = Vec::with_capacity(bodies.len());
    for (i, (body, h)) in bodies.iter().zip(spacings).enumerate() {
        let relaxed = match relaxing {
            Some(options) => Some(
                sim.relax(*body, options)
                    .map_err(|e| format!("{}: settings.relax: bodies[{i}]: {e}", args.scene))?,
            ),
            None => None,
        };
        tracked.push(Tracked::new(sim, *body, *h, relaxed)?);
    }
    Ok(tracked)
}

/// Writes `summary.json`, the saved simulation and the state dump as asked, and prints
/// the table.
fn write_outputs(sim: &mut Simulation, args: &RunArgs, summary: &Summary) -> Result<(), String> {
    let out = &args.out;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let path = out.join("summary.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(summary).map_err(|e| e.to_string())?,
    )
    .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    if let Some(path) = &args.save_state {
        let file = std::fs::File::create(path)
            .map_err(|e| format!("cannot create `{}`: {e}", path.display()))?;
        sim.save(std::io::BufWriter::new(file))
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if let Some(file) = &args.dump_state {
        let state = dump_world(sim.world_mut());
        std::fs::write(
            file,
            serde_json::to_string(&state).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write `{}`: {e}", file.display()))?;
    }
    if !args.quiet {
        print_table(summary, &path, out);
    }
    Ok(())
}
