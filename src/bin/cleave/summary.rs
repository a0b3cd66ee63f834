//! What `cleave run` reports: `summary.json` (per body: pieces, gaps, tip drop, …,
//! tracked over the run) and the table printed at the end.

use bevy_ecs::prelude::*;
use cleave::analysis::frames::FrameStats;
use cleave::analysis::stats::{
    BodyStats, body_stats, labelled_positions, min_distance_between_labels,
};
use cleave::ecs::attach::pinned_particles;
use cleave::ecs::components::{BodyLattice, Position};
use cleave::sim::relax_report::RelaxReport;
use cleave::sim::simulation::Simulation;
use serde::Serialize;
use std::path::Path;

#[derive(Serialize)]
pub(crate) struct Summary {
    pub(crate) scene: String,
    pub(crate) frames: u32,
    pub(crate) seed: u64,
    /// The frame after which every body was clustered afresh (`--recluster-at`).
    pub(crate) reclustered_at: Option<u32>,
    pub(crate) threads: usize,
    /// Totals over every body at the end.
    pub(crate) particles: usize,
    pub(crate) clusters: usize,
    pub(crate) memberships: usize,
    pub(crate) pieces: usize,
    pub(crate) cut_particles: usize,
    pub(crate) median_ms_per_step: f64,
    /// Every frame's `Simulation::step` as a game feels it: median, 95th percentile,
    /// slowest, slowest after the first (ms).
    pub(crate) frame_ms: FrameStats,
    /// The same over the frames that cut (a body changed).
    pub(crate) cut_frame_ms: FrameStats,
    pub(crate) simulate_ms_total: f64,
    pub(crate) pictures_ms_total: f64,
    pub(crate) pictures_written: usize,
    /// The largest over the bodies.
    pub(crate) final_shape_error_h: f64,
    /// The lowest over the bodies, in units of the first body's spacing.
    pub(crate) lowest_particle_y_h: f64,
    pub(crate) finite: bool,
    /// Smallest distance between particles of different pieces (of one body or of two),
    /// over every frame from the first with two pieces in the scene, in units of the
    /// smallest spacing; `null` when no two pieces came within 2 h. Measured between
    /// frames, outside the timed steps (a sort of the particles into cells, linear in
    /// them), so it is in none of the frame times.
    pub(crate) min_gap_between_pieces_h: Option<f64>,
    /// The same between particles of different bodies, at the end.
    pub(crate) final_min_gap_between_bodies_h: Option<f64>,
    pub(crate) cut_events: usize,
    pub(crate) cut_event_ms_median: f64,
    pub(crate) cut_event_ms_max: f64,
    /// Projective dynamics: milliseconds of each factorization of the global matrix, in
    /// order — the first for the bodies as spawned, each later one after a cut (or a
    /// change of pins) changed it; empty under the other solvers.
    pub(crate) factor_ms: Vec<f64>,
    pub(crate) invariant_violations: usize,
    /// Per body, in spawn order.
    pub(crate) bodies: Vec<BodySummary>,
}

/// What the summary reports of one body.
#[derive(Serialize)]
pub(crate) struct BodySummary {
    /// The relaxation before the first frame, if the body was relaxed.
    pub(crate) relax: Option<RelaxReport>,
    pub(crate) before: BodyStats,
    pub(crate) half_time: BodyStats,
    pub(crate) after: BodyStats,
    /// Drop of the particle with the largest lattice x (a cantilever's tip), in h.
    pub(crate) tip_drop_h_half: f64,
    pub(crate) tip_drop_h_end: f64,
    pub(crate) pinned_max_displacement_h: f64,
    pub(crate) piece_separation_start_h: f64,
    pub(crate) piece_separation_end_h: f64,
}

/// What a run follows of one body.
pub(crate) struct Tracked {
    pub(crate) body: Entity,
    pub(crate) h: f32,
    pub(crate) lattice: BodyLattice,
    pub(crate) tip: u32,
    pub(crate) tip_start: Option<glam::Vec3>,
    pub(crate) pinned: Vec<(u32, glam::Vec3)>,
    pub(crate) start_positions: Vec<glam::Vec3>,
    pub(crate) before: BodyStats,
    pub(crate) half: BodyStats,
    pub(crate) tip_half: f64,
    pub(crate) relax: Option<RelaxReport>,
}

impl Tracked {
    /// Starts following `body` (relaxed by `relax`, if it was).
    pub(crate) fn new(
        sim: &mut Simulation,
        body: Entity,
        h: f32,
        relax: Option<RelaxReport>,
    ) -> Result<Self, String> {
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
            relax,
        };
        tracked.tip_start = tracked.position(sim, tip);
        tracked.pinned = pinned_particles(sim.world_mut(), body)
            .into_iter()
            .filter_map(|i| Some((i, tracked.position(sim, i)?)))
            .collect();
        tracked.start_positions = tracked.all_positions(sim);
        Ok(tracked)
    }

    pub(crate) fn position(&self, sim: &Simulation, i: u32) -> Option<glam::Vec3> {
        sim.world()
            .get::<Position>(self.lattice.particles[i as usize])
            .map(|p| p.0)
    }

    pub(crate) fn all_positions(&self, sim: &Simulation) -> Vec<glam::Vec3> {
        (0..self.lattice.lattice.len() as u32)
            .map(|i| self.position(sim, i).unwrap_or(glam::Vec3::ZERO))
            .collect()
    }

    pub(crate) fn tip_drop(&self, sim: &Simulation) -> f64 {
        match (self.tip_start, self.position(sim, self.tip)) {
            (Some(a), Some(b)) => ((a.y - b.y) / self.h) as f64,
            _ => f64::NAN,
        }
    }

    pub(crate) fn at_half_time(&mut self, sim: &mut Simulation) -> Result<(), String> {
        self.half = body_stats(sim.world_mut(), self.body).ok_or("no body")?;
        self.tip_half = self.tip_drop(sim);
        Ok(())
    }

    pub(crate) fn summary(self, sim: &mut Simulation) -> Result<BodySummary, String> {
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
        let tip_drop_h_end = self.tip_drop(sim);
        Ok(BodySummary {
            relax: self.relax,
            tip_drop_h_half: self.tip_half,
            tip_drop_h_end,
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
pub(crate) fn gaps(sim: &mut Simulation, h: f32) -> (Option<f64>, Option<f64>) {
    let labelled = labelled_positions(sim.world());
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
pub(crate) fn piece_separation(
    lattice: &cleave::body::lattice::Lattice,
    start: &[glam::Vec3],
    end: &[glam::Vec3],
    h: f32,
) -> (f64, f64) {
    let (labels, pieces) = (&lattice.pieces().label, lattice.pieces().count);
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

/// A row of the report: its name and what it reads of a body's statistics.
pub(crate) type Row = (&'static str, fn(&BodyStats) -> f64);

/// The short report printed after a run: totals, then one block per body.
pub(crate) fn print_table(s: &Summary, path: &Path, out: &Path) {
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
        if let Some(r) = &b.relax {
            println!(
                "  relaxed in {} frames{}: shape error {:.4} h → {:.4} h, boundary drift {:.1e} h over {} sets, rms speed {:.4} h/s",
                r.frames,
                if r.converged { "" } else { " (not converged)" },
                r.shape_error_before,
                r.shape_error,
                r.boundary_drift,
                r.boundary_sets,
                r.rms_speed
            );
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
        "  frames: median {:.3} ms, 95th percentile {:.3} ms, slowest {:.3} ms; the {} that cut: median {:.3} ms, slowest {:.3} ms",
        s.frame_ms.median_ms,
        s.frame_ms.p95_ms,
        s.frame_ms.max_ms,
        s.cut_frame_ms.frames,
        s.cut_frame_ms.median_ms,
        s.cut_frame_ms.max_ms
    );
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
