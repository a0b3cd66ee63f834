//! `cleave run`: simulate a built-in scene, write `summary.json` (and optionally the
//! state dump), print a table.

use crate::pictures::{PictureOptions, Pictures};
use bevy_ecs::prelude::*;
use cleave::bench::median;
use cleave::components::{BodyLattice, InvMass, Position};
use cleave::dump::dump_body;
use cleave::profile::StageProfile;
use cleave::resources::{CutTimings, ParticlesCut};
use cleave::scene::{BUILTIN_SCENES, Scene, builtin};
use cleave::scene_file::load_scene_file;
use cleave::sim::{Simulation, check_invariants, only_body};
use cleave::stats::{BodyStats, body_stats};
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
    threads: usize,
    particles: usize,
    clusters: usize,
    memberships: usize,
    pieces: usize,
    cut_particles: usize,
    median_ms_per_step: f64,
    simulate_ms_total: f64,
    pictures_ms_total: f64,
    pictures_written: usize,
    final_shape_error_h: f64,
    lowest_particle_y_h: f64,
    finite: bool,
    before: BodyStats,
    after: BodyStats,
    half_time: BodyStats,
    tip_drop_h_half: f64,
    tip_drop_h_end: f64,
    pinned_max_displacement_h: f64,
    piece_separation_start_h: f64,
    piece_separation_end_h: f64,
    cut_events: usize,
    cut_event_ms_median: f64,
    cut_event_ms_max: f64,
    invariant_violations: usize,
}

/// Mean pairwise distance between the centroids of the final pieces, in units of h,
/// with the centroids taken over the same particles at the start and at the end.
fn piece_separation(
    lattice: &cleave::lattice::Lattice,
    start: &[glam::Vec3],
    end: &[glam::Vec3],
    h: f32,
) -> (f64, f64) {
    let (labels, pieces) = cleave::graph::body_pieces(lattice);
    if pieces < 2 {
        return (0.0, 0.0);
    }
    let centroids = |pos: &[glam::Vec3]| {
        let mut sum = vec![(glam::Vec3::ZERO, 0usize); pieces];
        for i in lattice.live_particles() {
            let s = &mut sum[labels[i as usize] as usize];
            s.0 += pos[i as usize];
            s.1 += 1;
        }
        sum.into_iter()
            .map(|(v, n)| v / n as f32)
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

/// Arguments of `cleave run`.
#[derive(Clone, Debug)]
pub struct RunArgs {
    /// Built-in scene name.
    pub scene: String,
    /// Frames (default: the scene's).
    pub frames: Option<u32>,
    /// Output directory.
    pub out: PathBuf,
    /// Seed (default: the scene's).
    pub seed: Option<u64>,
    /// State dump file.
    pub dump_state: Option<PathBuf>,
    /// Pictures to write.
    pub pictures: PictureOptions,
    /// Print milliseconds per stage.
    pub profile: bool,
    /// No progress bar and no table.
    pub quiet: bool,
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
    let scene = load_scene(scene_name, seed)?;
    let seed = scene.config.seed;
    let frames = frames.unwrap_or(scene.frames);
    let mut sim = Simulation::new(scene.config.clone()).map_err(|e| e.to_string())?;
    for b in &scene.bodies {
        sim.spawn_body(b).map_err(|e| e.to_string())?;
    }
    for t in &scene.tools {
        sim.spawn_tool(t).map_err(|e| e.to_string())?;
    }
    let body = only_body(sim.world_mut()).map_err(|e| e.to_string())?;
    let h = scene.bodies[0].spacing;
    let lattice = sim
        .world()
        .get::<BodyLattice>(body)
        .ok_or("no lattice")?
        .clone();
    let tip_index = (0..lattice.lattice.len() as u32)
        .max_by_key(|i| (lattice.lattice.coord(*i).x, -(*i as i64)))
        .unwrap_or(0);
    let position_of = |sim: &Simulation, i: u32| {
        sim.world()
            .get::<Position>(lattice.particles[i as usize])
            .map(|p| p.0)
    };
    let tip_start = position_of(&sim, tip_index);
    let pinned: Vec<(u32, glam::Vec3)> = (0..lattice.lattice.len() as u32)
        .filter(|i| {
            sim.world()
                .get::<InvMass>(lattice.particles[*i as usize])
                .is_some_and(|m| m.0 == 0.0)
        })
        .filter_map(|i| Some((i, position_of(&sim, i)?)))
        .collect();
    let before = body_stats(sim.world_mut(), body).ok_or("no body")?;
    let all_positions = |sim: &Simulation| -> Vec<glam::Vec3> {
        (0..lattice.lattice.len() as u32)
            .map(|i| position_of(sim, i).unwrap_or(glam::Vec3::ZERO))
            .collect()
    };
    let start_positions = all_positions(&sim);
    let mut step_ms = Vec::new();
    let mut half = before.clone();
    let mut tip_half = 0.0;
    let mut cut_particles = 0;
    let mut cursor = sim
        .world()
        .resource::<Messages<ParticlesCut>>()
        .get_cursor();
    let mut pictures = Pictures::new(
        &out,
        PictureOptions {
            dt: scene.config.dt,
            ..args.pictures.clone()
        },
    )?;
    pictures.frame(sim.world_mut(), 0)?;
    let progress = progress_bar(frames, args.quiet);
    for frame in 1..=frames {
        progress.inc(1);
        let t = Instant::now();
        sim.step();
        step_ms.push(t.elapsed().as_secs_f64() * 1e3);
        pictures.frame(sim.world_mut(), frame)?;
        cut_particles += cursor
            .read(sim.world().resource::<Messages<ParticlesCut>>())
            .map(|m| m.particles.len())
            .sum::<usize>();
        if frame == frames / 2 {
            half = body_stats(sim.world_mut(), body).ok_or("no body")?;
            if let (Some(a), Some(b)) = (tip_start, position_of(&sim, tip_index)) {
                tip_half = ((a.y - b.y) / h) as f64;
            }
        }
    }
    progress.finish_and_clear();
    let after = body_stats(sim.world_mut(), body).ok_or("no body")?;
    let tip_end = match (tip_start, position_of(&sim, tip_index)) {
        (Some(a), Some(b)) => ((a.y - b.y) / h) as f64,
        _ => f64::NAN,
    };
    let pinned_max = pinned
        .iter()
        .filter_map(|(i, p0)| Some(position_of(&sim, *i)?.distance(*p0) / h))
        .fold(0.0f32, f32::max) as f64;
    let violations = check_invariants(sim.world());
    let final_lattice = sim
        .world()
        .get::<BodyLattice>(body)
        .ok_or("no lattice")?
        .lattice
        .clone();
    let separation = piece_separation(&final_lattice, &start_positions, &all_positions(&sim), h);
    let mut events = sim.world().resource::<CutTimings>().event_ms.clone();
    let summary = Summary {
        scene: scene_name.into(),
        frames,
        seed,
        threads,
        particles: after.particles,
        clusters: after.clusters,
        memberships: after.memberships,
        pieces: after.pieces,
        cut_particles,
        simulate_ms_total: step_ms.iter().sum(),
        pictures_ms_total: pictures.ms,
        pictures_written: pictures.files,
        median_ms_per_step: median(&mut step_ms),
        final_shape_error_h: after.shape_error_h,
        lowest_particle_y_h: after.lowest_y / h as f64,
        finite: after.finite,
        piece_separation_start_h: separation.0,
        piece_separation_end_h: separation.1,
        half_time: half,
        tip_drop_h_half: tip_half,
        tip_drop_h_end: tip_end,
        pinned_max_displacement_h: pinned_max,
        cut_events: events.len(),
        cut_event_ms_max: events.iter().copied().fold(0.0, f64::max),
        cut_event_ms_median: median(&mut events),
        invariant_violations: violations.len(),
        before,
        after: after.clone(),
    };
    std::fs::create_dir_all(&out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let path = out.join("summary.json");
    std::fs::write(
        &path,
        serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?,
    )
    .map_err(|e| format!("cannot write `{}`: {e}", path.display()))?;
    if let Some(file) = dump {
        let state = dump_body(sim.world_mut(), body).ok_or("no body")?;
        std::fs::write(
            &file,
            serde_json::to_string(&state).map_err(|e| e.to_string())?,
        )
        .map_err(|e| format!("cannot write `{}`: {e}", file.display()))?;
    }
    if !args.quiet {
        print_table(&summary, &separation, &path, &out);
    }
    if args.profile {
        print!("{}", profile.table(frames));
    }
    if !summary.finite {
        return Err("non-finite particle positions".into());
    }
    Ok(())
}

/// The short report printed after a run.
fn print_table(s: &Summary, separation: &(f64, f64), path: &Path, out: &Path) {
    println!(
        "scene {}: {} frames, seed {}, {} thread(s)",
        s.scene, s.frames, s.seed, s.threads
    );
    println!("  {:<28} {:>12} {:>12}", "", "start", "end");
    let rows: [(&str, f64, f64); 6] = [
        (
            "particles",
            s.before.particles as f64,
            s.after.particles as f64,
        ),
        (
            "clusters",
            s.before.clusters as f64,
            s.after.clusters as f64,
        ),
        (
            "mean cluster size",
            s.before.mean_cluster_size,
            s.after.mean_cluster_size,
        ),
        (
            "memberships / particle",
            s.before.memberships_per_particle,
            s.after.memberships_per_particle,
        ),
        ("pieces", s.before.pieces as f64, s.after.pieces as f64),
        (
            "shape error (h)",
            s.before.shape_error_h,
            s.after.shape_error_h,
        ),
    ];
    for (name, a, b) in rows {
        println!("  {name:<28} {a:>12.3} {b:>12.3}");
    }
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
        "  piece centroids {:.2} h apart at start, {:.2} h at end",
        separation.0, separation.1
    );
    println!(
        "  tip drop {:.3} h at half time, {:.3} h at end; pinned moved ≤ {:.4} h; invariant violations {}",
        s.tip_drop_h_half, s.tip_drop_h_end, s.pinned_max_displacement_h, s.invariant_violations
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
