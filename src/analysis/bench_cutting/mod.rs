//! `cleave bench --cutting`: what cutting costs a game, frame by frame. Each workload
//! steps a simulation once per frame with its surfaces on, as a game does, and times
//! every frame; the same bodies without their tools give the plain frames every ratio
//! is against (the two runs alternate frames, so a load that drifts weighs on both).
//! Per frame that cuts, the time of each stage of the cut is read from the systems'
//! spans ([`crate::analysis::profile::StageProfile`]): detection, the cut,
//! regroup/split/expand, the layout and terms brought up to date (at the start of the
//! next frame) and the surface's topology update. The ratios are given again for the
//! frames less that cut work: the floor the pieces' own physics sets, which no speed of
//! the cut work goes below.
//!
//! The workloads ([`workloads`]): the `cuts` scene in each cut mode; a 32³ block
//! (h = 0.05) crossed by a blade stroke every 10 frames for 300 frames in each mode; a
//! 64³ box sliced once (sever and split); and, on request, an n³ box diced by 8 blades in
//! one frame (sever and split). Each row also gives the memory its cut frames took at
//! their peak beyond what the process held before them.

use crate::analysis::frames::FrameStats;
use crate::analysis::profile::StageProfile;
use crate::cut::tool::CutMode;
use crate::ecs::components::BodyLattice;
use crate::ecs::desc::ToolDesc;
use crate::ecs::resources::CutReport;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::Result;
use crate::sim::simulation::Simulation;
use bevy_ecs::prelude::Entity;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Instant;

pub mod workloads;

pub use workloads::{Workload, diced_box, sliced_box, stroked_block};

/// Milliseconds of each part of a cut, summed over a run's cut frames or averaged per
/// cut frame.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct CutStages {
    /// The read-only detection stage.
    pub detect_ms: f64,
    /// The cut stage (removing, splitting, severing).
    pub cut_ms: f64,
    /// Regroup, split and expand: the clusters rebuilt.
    pub rebuild_ms: f64,
    /// The solver's layout and its terms brought up to date, at the start of the frame
    /// after the cut.
    pub layout_ms: f64,
    /// The surface's topology update.
    pub surface_ms: f64,
}

impl CutStages {
    fn total(&self) -> f64 {
        self.detect_ms + self.cut_ms + self.rebuild_ms + self.layout_ms + self.surface_ms
    }

    fn add(&mut self, o: &CutStages) {
        self.detect_ms += o.detect_ms;
        self.cut_ms += o.cut_ms;
        self.rebuild_ms += o.rebuild_ms;
        self.layout_ms += o.layout_ms;
        self.surface_ms += o.surface_ms;
    }

    fn scaled(&self, k: f64) -> CutStages {
        CutStages {
            detect_ms: self.detect_ms * k,
            cut_ms: self.cut_ms * k,
            rebuild_ms: self.rebuild_ms * k,
            layout_ms: self.layout_ms * k,
            surface_ms: self.surface_ms * k,
        }
    }
}

/// One workload of `cleave bench --cutting`.
#[derive(Clone, Debug, Serialize)]
pub struct CuttingRow {
    /// Always `"cutting"`.
    pub row: &'static str,
    /// `cuts`, `block32`, `box64` or `diced` followed by the box's edge in particles.
    pub workload: String,
    /// The tools' cut mode.
    pub mode: CutMode,
    /// Live particles at the start.
    pub particles: usize,
    /// Worker threads.
    pub threads: usize,
    /// The same bodies without their tools, every frame.
    pub plain: FrameStats,
    /// Every frame of the cutting run.
    pub all: FrameStats,
    /// The frames that cut (a body changed).
    pub cut: FrameStats,
    /// Per cut frame, the mean time of each part of the cut.
    pub cut_stages: CutStages,
    /// The substeps' mean time per frame of the cutting run.
    pub substeps_ms: f64,
    /// The cut work (detection every frame, and on cut frames the cut,
    /// regroup/split/expand, the layout and terms, the surface's topology) over the
    /// whole run, against the substeps' over the run.
    pub cut_work_over_substeps: f64,
    /// The surface stage's median time in a plain frame (the per-frame update).
    pub surface_frame_ms: f64,
    /// The most memory a cut frame took at its peak beyond what the process held when
    /// the frame began, in MB (on Linux, whose peak is reset before each frame; `null`
    /// where it cannot be).
    pub cut_peak_extra_mb: Option<f64>,
    /// The cutting run's frames against the plain median frame (in JSON, its four keys
    /// at the row's top level).
    #[serde(flatten)]
    pub as_run: Ratios,
    /// The same four ratios for the cutting run's frames less their cut work (detection
    /// in every frame; on a cut frame the cut, regroup/split/expand and the surface's
    /// topology; the layout and terms in the frame after): what is left were the cut work
    /// free — the pieces' own physics and the surfaces' per-frame update —, the floor
    /// under the ratios above that no speed of the cut work goes below.
    pub without_cut_work: Ratios,
}

/// A run's frames against the plain median frame.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Ratios {
    /// The 95th-percentile frame.
    pub p95_over_plain: f64,
    /// The slowest frame after the first.
    pub slowest_over_plain: f64,
    /// The cut frames' median.
    pub cut_median_over_plain: f64,
    /// The slowest cut frame.
    pub cut_slowest_over_plain: f64,
}

impl Ratios {
    /// The ratios of a run's frames `all`, of which `cut` are the cut frames, to
    /// `plain_median` ms.
    fn of(all: &FrameStats, cut: &FrameStats, plain_median: f64) -> Self {
        Self {
            p95_over_plain: all.p95_ms / plain_median,
            slowest_over_plain: all.max_after_first_ms / plain_median,
            cut_median_over_plain: cut.median_ms / plain_median,
            cut_slowest_over_plain: cut.max_ms / plain_median,
        }
    }
}

/// Which workloads to run.
#[derive(Clone, Copy, Debug)]
pub struct CuttingOptions {
    /// The `cuts` scene in each mode.
    pub cuts: bool,
    /// The 32³ block with a stroke every 10 frames, in each mode.
    pub block: bool,
    /// The 64³ box sliced once, sever and split.
    pub slice: bool,
    /// An n³ box diced by 8 blades in one frame, sever and split ([`diced_box`]).
    pub dice: Option<u32>,
}

impl Default for CuttingOptions {
    fn default() -> Self {
        Self {
            cuts: true,
            block: true,
            slice: true,
            dice: None,
        }
    }
}

/// Runs the workloads `options` names and returns a row each, in order.
pub fn bench_cutting(options: CuttingOptions, on_row: &mut dyn FnMut(&CuttingRow)) -> Result<()> {
    if options.cuts {
        let scene = crate::io::scene::builtin("cuts", 0).expect("a built-in scene");
        for mode in [CutMode::Remove, CutMode::Sever, CutMode::Split] {
            let mut scene = scene.clone();
            for tool in &mut scene.tools {
                tool.cut_mode = mode;
            }
            let scene = Workload {
                scene,
                strokes: Vec::new(),
            };
            on_row(&workload("cuts", mode, &scene)?);
        }
    }
    if options.block {
        for mode in [CutMode::Remove, CutMode::Sever, CutMode::Split] {
            on_row(&workload("block32", mode, &stroked_block(mode))?);
        }
    }
    if options.slice {
        for mode in [CutMode::Sever, CutMode::Split] {
            on_row(&workload("box64", mode, &sliced_box(mode))?);
        }
    }
    if let Some(n) = options.dice {
        for mode in [CutMode::Sever, CutMode::Split] {
            on_row(&workload(&format!("diced{n}"), mode, &diced_box(n, mode))?);
        }
    }
    Ok(())
}

/// What one run of a scene measured: every frame's time, whether it cut, and the
/// stages' milliseconds per frame.
#[derive(Default)]
struct Run {
    particles: usize,
    frames: Vec<f64>,
    cut: Vec<bool>,
    stages: Vec<BTreeMap<String, f64>>,
    surface_topology: Vec<f64>,
    /// Per frame, what the process held at its peak beyond what it held before the
    /// frame, in bytes (`None` where the peak cannot be reset).
    extra_bytes: Vec<Option<u64>>,
}

/// One run of a workload, a frame at a time (so that the plain and the cutting run can
/// take their frames in turn).
struct Runner<'w> {
    /// The simulation (taken only to be dropped under its own dispatcher).
    sim: Option<Simulation>,
    strokes: Vec<&'w (u32, ToolDesc)>,
    /// The strokes' tools under way, with the time of their last key.
    under_way: Vec<(Entity, f32)>,
    profile: StageProfile,
    /// The profile as the tracing dispatcher of this run's frames.
    dispatch: tracing::Dispatch,
    /// The profile's totals after the last frame.
    before: BTreeMap<String, f64>,
    /// Each surface's topology version and rebuild time after the last frame.
    seen: Vec<(u64, f64)>,
    dt: f32,
    run: Run,
}

impl<'w> Runner<'w> {
    /// `workload` ready to step, with its tools and strokes or without.
    fn new(workload: &'w Workload, with_tools: bool) -> Result<Self> {
        let mut scene = workload.scene.clone();
        let mut strokes: Vec<&(u32, ToolDesc)> = workload.strokes.iter().collect();
        if !with_tools {
            scene.tools.clear();
            strokes.clear();
        }
        let profile = StageProfile::default();
        let dispatch = profile.dispatch();
        let mut sim = tracing::dispatcher::with_default(&dispatch, || -> Result<Simulation> {
            let mut sim = Simulation::from_scene(&scene)?;
            sim.update_surfaces()?;
            Ok(sim)
        })?;
        let particles = sim
            .world_mut()
            .query::<&BodyLattice>()
            .iter(sim.world())
            .map(|b| b.lattice.live_count())
            .sum();
        let seen = Self::versions(&mut sim);
        Ok(Self {
            sim: Some(sim),
            strokes,
            under_way: Vec::new(),
            before: profile.totals_ms(),
            profile,
            dispatch,
            seen,
            dt: scene.config.dt,
            run: Run {
                particles,
                ..Run::default()
            },
        })
    }

    /// Each surface's topology version and the milliseconds of its last rebuild.
    fn versions(sim: &mut Simulation) -> Vec<(u64, f64)> {
        sim.world_mut()
            .query::<&SurfaceMesh>()
            .iter(sim.world())
            .map(|m| (m.topology_version, m.topology_ms))
            .collect()
    }

    /// Steps frame `frame` (counted from 1) and records it.
    fn frame(&mut self, frame: u32) -> Result<()> {
        let _profiled = tracing::dispatcher::set_default(&self.dispatch);
        let Some(sim) = self.sim.as_mut() else {
            return Ok(());
        };
        for (_, tool) in self.strokes.iter().filter(|(first, _)| *first == frame) {
            let end = tool.path.keys.last().map_or(0.0, |k| k.0);
            self.under_way.push((sim.spawn_tool(tool)?, end));
        }
        let held = crate::analysis::bench::reset_peak_resident();
        let start = Instant::now();
        sim.step();
        let elapsed = start.elapsed();
        let peak = crate::analysis::bench::peak_resident_bytes();
        let run = &mut self.run;
        run.frames.push(elapsed.as_secs_f64() * 1e3);
        run.extra_bytes
            .push(held.zip(peak).map(|(held, peak)| peak.saturating_sub(held)));
        run.cut
            .push(!sim.world().resource::<CutReport>().bodies.is_empty());
        let after = self.profile.totals_ms();
        let before = &self.before;
        run.stages.push(
            (after.iter())
                .map(|(k, v)| (k.clone(), v - before.get(k).copied().unwrap_or(0.0)))
                .collect(),
        );
        self.before = after;
        let now = Self::versions(sim);
        let seen = &self.seen;
        let topology: f64 = (now.iter().enumerate())
            .filter(|(i, (v, _))| seen.get(*i).is_none_or(|s| s.0 != *v))
            .map(|(_, (_, ms))| ms)
            .sum();
        run.surface_topology.push(topology);
        self.seen = now;
        let time = frame as f32 * self.dt;
        self.under_way.retain(|&(tool, end)| {
            let done = end <= time + 1e-6;
            if done {
                sim.world_mut().despawn(tool);
            }
            !done
        });
        Ok(())
    }
}

impl Drop for Runner<'_> {
    /// Drops the simulation, and with it its systems' spans, under the dispatcher they
    /// were made under: the registry closes a span's parent through the default
    /// dispatcher, which must be theirs.
    fn drop(&mut self) {
        let _profiled = tracing::dispatcher::set_default(&self.dispatch);
        self.sim.take();
    }
}

/// Runs `scene` with and without its tools and makes its row.
///
/// The two runs take their frames in turn, a plain frame then a cutting one, so that
/// the machine's load drifting over the runs weighs on both alike.
fn workload(name: &str, mode: CutMode, scene: &Workload) -> Result<CuttingRow> {
    let (mut plain, mut cutting) = (Runner::new(scene, false)?, Runner::new(scene, true)?);
    for frame in 1..=scene.scene.frames {
        plain.frame(frame)?;
        cutting.frame(frame)?;
    }
    let (plain, cutting) = (
        std::mem::take(&mut plain.run),
        std::mem::take(&mut cutting.run),
    );
    let stage = |f: usize, names: &[&str]| -> f64 {
        names
            .iter()
            .map(|n| cutting.stages[f].get(*n).copied().unwrap_or(0.0))
            .sum()
    };
    let mut per_cut = CutStages::default();
    let mut whole_run = CutStages::default();
    let mut cut_frames = 0;
    let mut substeps = 0.0;
    // each frame less its cut work (the layout's in the frame that pays it)
    let mut without = cutting.frames.clone();
    for f in 0..cutting.frames.len() {
        substeps += stage(f, &["run_substeps"]);
        let detect = stage(f, &["detect"]);
        whole_run.detect_ms += detect;
        without[f] -= detect;
        if !cutting.cut[f] {
            continue;
        }
        cut_frames += 1;
        let stages = CutStages {
            detect_ms: detect,
            cut_ms: stage(f, &["cut"]),
            rebuild_ms: stage(f, &["regroup", "split", "expand"]),
            // the layout and the terms hear of the cut at the start of the next frame
            layout_ms: if f + 1 < cutting.frames.len() {
                stage(f + 1, &["sync_solver", "sync_terms"])
            } else {
                0.0
            },
            surface_ms: cutting.surface_topology[f],
        };
        per_cut.add(&stages);
        without[f] -= stages.cut_ms + stages.rebuild_ms + stages.surface_ms;
        if let Some(next) = without.get_mut(f + 1) {
            *next -= stages.layout_ms;
        }
        whole_run.add(&CutStages {
            detect_ms: 0.0,
            ..stages
        });
    }
    let plain_stats = FrameStats::of(&plain.frames);
    let all = FrameStats::of(&cutting.frames);
    let cut = FrameStats::of_where(&cutting.frames, |f| cutting.cut[f]);
    let mut surface: Vec<f64> = (0..plain.frames.len())
        .map(|f| {
            plain.stages[f]
                .get("update_surfaces")
                .copied()
                .unwrap_or(0.0)
        })
        .collect();
    let frames = cutting.frames.len().max(1) as f64;
    let plain_median = plain_stats.median_ms;
    let (all_without, cut_without) = (
        FrameStats::of(&without),
        FrameStats::of_where(&without, |f| cutting.cut[f]),
    );
    let (as_run, without_cut_work) = (
        Ratios::of(&all, &cut, plain_median),
        Ratios::of(&all_without, &cut_without, plain_median),
    );
    Ok(CuttingRow {
        row: "cutting",
        workload: name.into(),
        mode,
        particles: cutting.particles,
        threads: rayon::current_num_threads(),
        plain: plain_stats,
        all,
        cut,
        cut_stages: per_cut.scaled(1.0 / cut_frames.max(1) as f64),
        substeps_ms: substeps / frames,
        cut_work_over_substeps: whole_run.total() / substeps,
        surface_frame_ms: crate::analysis::bench::median(&mut surface),
        cut_peak_extra_mb: (0..cutting.frames.len())
            .filter(|&f| cutting.cut[f])
            .map(|f| cutting.extra_bytes[f].map(|b| b as f64 / 1e6))
            .try_fold(0.0, |most: f64, extra| extra.map(|e| most.max(e))),
        as_run,
        without_cut_work,
    })
}
