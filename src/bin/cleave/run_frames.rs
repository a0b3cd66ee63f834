//! `cleave run`'s frames: the loop that steps the simulation and what it records of
//! each frame (its time, whether it cut, the factorisations, the gaps between pieces),
//! and the summary made of them.

use crate::pictures::Pictures;
use crate::summary::*;
use bevy_ecs::prelude::*;
use cleave::analysis::bench::median;
use cleave::analysis::frames::FrameStats;
use cleave::analysis::stats::BodyStats;
use cleave::ecs::check::check_invariants;
use cleave::ecs::components::BodyLattice;
use cleave::ecs::layout::SolverCache;
use cleave::ecs::resources::{CutReport, CutTimings, ParticlesCut};
use cleave::sim::simulation::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Instant;

/// What the frame loop recorded.
pub(crate) struct FrameLog {
    /// Each frame's wall time.
    step_ms: Vec<f64>,
    /// Whether each frame cut.
    cut_frames: Vec<bool>,
    /// Particles removed by cuts.
    cut_particles: usize,
    /// The smallest gap between pieces seen after any frame, in spacings.
    min_gap: Option<f64>,
    /// Each projective factorisation's time.
    factor_ms: Vec<f64>,
}

impl FrameLog {
    /// Steps `sim` `frames` times, drawing and recording each frame (see the module
    /// docs); reclusters at `--recluster-at`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn simulate(
        sim: &mut Simulation,
        frames: u32,
        recluster_at: Option<u32>,
        quiet: bool,
        bodies: &[Entity],
        tracked: &mut [Tracked],
        pictures: &mut Pictures,
        spacings: &[f32],
    ) -> Result<Self, String> {
        let h = spacings.iter().copied().fold(f32::INFINITY, f32::min);
        let mut log = FrameLog {
            step_ms: Vec::new(),
            cut_frames: Vec::new(),
            cut_particles: 0,
            min_gap: None,
            factor_ms: Vec::new(),
        };
        let mut cursor = sim
            .world()
            .resource::<Messages<ParticlesCut>>()
            .get_cursor();
        pictures.frame(sim.world_mut(), 0)?;
        let recluster = |sim: &mut Simulation, frame: u32| -> Result<(), String> {
            if recluster_at == Some(frame) {
                for &body in bodies {
                    sim.recluster(body).map_err(|e| e.to_string())?;
                }
            }
            Ok(())
        };
        recluster(sim, 0)?;
        let progress = progress_bar(frames, quiet);
        let mut factor_seconds = 0.0;
        for frame in 1..=frames {
            progress.inc(1);
            let t = Instant::now();
            sim.step();
            log.step_ms.push(t.elapsed().as_secs_f64() * 1e3);
            log.cut_frames
                .push(!sim.world().resource::<CutReport>().bodies.is_empty());
            log.note_factorisation(sim, &mut factor_seconds);
            recluster(sim, frame)?;
            pictures.frame(sim.world_mut(), frame)?;
            log.cut_particles += cursor
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
                && let (Some(gap), _) = gaps(sim, h)
            {
                log.min_gap = Some(log.min_gap.map_or(gap, |m| m.min(gap)));
            }
            if frame == frames / 2 {
                for t in tracked.iter_mut() {
                    t.at_half_time(sim)?;
                }
            }
        }
        progress.finish_and_clear();
        Ok(log)
    }

    /// Records the time of a factorisation the frame made (the solver's running total
    /// moved on; a layout built afresh starts its count at zero).
    fn note_factorisation(&mut self, sim: &Simulation, last: &mut f64) {
        let seconds = sim
            .world()
            .resource::<SolverCache>()
            .solver
            .projective
            .factor_seconds;
        if seconds != *last {
            let before = if seconds > *last { *last } else { 0.0 };
            self.factor_ms.push(1e3 * (seconds - before));
            *last = seconds;
        }
    }

    /// The run's summary.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn summary(
        mut self,
        sim: &mut Simulation,
        scene: &str,
        recluster_at: Option<u32>,
        frames: u32,
        threads: usize,
        tracked: Vec<Tracked>,
        pictures: &Pictures,
        spacings: &[f32],
    ) -> Result<Summary, String> {
        let h = spacings.iter().copied().fold(f32::INFINITY, f32::min);
        let h_first = spacings.first().copied().unwrap_or(1.0);
        let violations = check_invariants(sim.world());
        let final_gaps = gaps(sim, h);
        let mut per_body = Vec::with_capacity(tracked.len());
        for t in tracked {
            per_body.push(t.summary(sim)?);
        }
        let mut events = sim.world().resource::<CutTimings>().event_ms.clone();
        let total = |f: fn(&BodyStats) -> usize| per_body.iter().map(|b| f(&b.after)).sum();
        let cut_frames = &self.cut_frames;
        Ok(Summary {
            scene: scene.into(),
            frames,
            seed: sim.config().seed,
            reclustered_at: recluster_at,
            threads,
            particles: total(|s| s.particles),
            clusters: total(|s| s.clusters),
            memberships: total(|s| s.memberships),
            pieces: total(|s| s.pieces),
            cut_particles: self.cut_particles,
            simulate_ms_total: self.step_ms.iter().fold(0.0, |sum, ms| sum + ms),
            frame_ms: FrameStats::of(&self.step_ms),
            cut_frame_ms: FrameStats::of_where(&self.step_ms, |f| cut_frames[f]),
            pictures_ms_total: pictures.ms,
            pictures_written: pictures.files,
            median_ms_per_step: median(&mut self.step_ms),
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
            min_gap_between_pieces_h: self.min_gap,
            final_min_gap_between_bodies_h: final_gaps.1,
            cut_events: events.len(),
            cut_event_ms_max: events.iter().copied().fold(0.0, f64::max),
            cut_event_ms_median: median(&mut events),
            factor_ms: self.factor_ms,
            invariant_violations: violations.len(),
            bodies: per_body,
        })
    }
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
