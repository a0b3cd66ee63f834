//! `cleave bench`'s flags, and the report they choose.

use crate::bench;
use crate::flags::{budget_seconds, frame_count, whole};
use cleave::config::{Model, SimConfig, SolverMode};

/// `cleave bench`'s flags (see each one's help).
#[derive(clap::Args)]
pub struct BenchFlags {
    /// Print one JSON object per row.
    #[arg(long)]
    json: bool,
    /// Box edge lengths in particles.
    #[arg(long, value_delimiter = ',', default_value = "16,32,48,64", value_parser = whole::<u32>, allow_negative_numbers = true)]
    sizes: Vec<u32>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = whole::<usize>, allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// Timed steps per size (median reported).
    #[arg(long, default_value_t = 30, value_parser = whole::<usize>, allow_negative_numbers = true)]
    steps: usize,
    /// Solver scheme: jacobi, gauss-seidel or projective.
    #[arg(long, default_value = "jacobi")]
    solver: SolverMode,
    /// Instead of the sizes and the pile: how fast each solver converges on two static
    /// solves (a twisted box, the `cantilever`), one row per solver.
    #[arg(long)]
    convergence: bool,
    /// With `--convergence`: edge of the twisted box in particles.
    #[arg(long, default_value_t = 32, value_parser = whole::<u32>, allow_negative_numbers = true)]
    convergence_size: u32,
    /// With `--convergence`: wall-clock budget of each run, in seconds.
    #[arg(long, default_value_t = 120.0, value_parser = budget_seconds, allow_negative_numbers = true)]
    budget: f64,
    /// Substeps per frame (step).
    #[arg(long, default_value_t = 2, value_parser = whole::<u32>, allow_negative_numbers = true)]
    substeps: u32,
    /// Solver iterations per substep.
    #[arg(long, default_value_t = 10, value_parser = whole::<u32>, allow_negative_numbers = true)]
    iterations: u32,
    /// Lattice spacing of the contact rows: the `pile` scene (0.025: about 40k particles)
    /// and the crowd.
    #[arg(long, default_value_t = 0.025)]
    pile_spacing: f32,
    /// Frames of each contact row.
    #[arg(long, default_value_t = 160, value_parser = frame_count, allow_negative_numbers = true)]
    pile_frames: u32,
    /// Bodies in the crowd row: the pile's shapes in turn, at `--pile-spacing`, dropped
    /// in layers of four into a bin 3 m wide (18 at 0.025: about 108k particles).
    #[arg(long, default_value_t = 18, value_parser = whole::<usize>, allow_negative_numbers = true)]
    crowd_bodies: usize,
    /// Skip the crowd row.
    #[arg(long)]
    no_crowd: bool,
    /// Skip the contact rows (the pile and the crowd).
    #[arg(long)]
    no_pile: bool,
    /// Skip the edge-constraint row (a box of the largest size with edge constraints).
    #[arg(long)]
    no_edges: bool,
    /// Instead of the engine rows: what each size's drawable surface costs (the
    /// per-frame update, the extraction intact and after a slice).
    #[arg(long)]
    surface: bool,
    /// Instead of the engine rows: whole frames as a game steps them, surfaces on —
    /// the median, 95th percentile and slowest frame, the same for the frames that
    /// cut, and each cut frame's time by stage — for `cuts` in each cut mode, a 32³
    /// block crossed by a blade every 10 frames in each mode and a 64³ box sliced
    /// once, each against the same bodies without their tools.
    #[arg(long)]
    cutting: bool,
    /// With `--cutting`: instead of its workloads, an N³ box (h = 0.05, gravity off)
    /// diced in one frame by 8 blades (4 across x, 4 across z), in sever and split mode,
    /// against the same box without its blades (2 ≤ N ≤ 160; 128 takes about 4 GB).
    #[arg(long, requires = "cutting", value_parser = dice_size)]
    dice: Option<u32>,
    /// Turn conservative culling off (to compare: the results are the same).
    #[arg(long)]
    no_culling: bool,
    /// Instead of the engine rows: what handle deformation costs (the subspace's
    /// weights at 16³ and 32³, the pose at 64³, full ARAP at 32³, reduced ARAP and
    /// reduced projective dynamics at 64³), in one run.
    #[arg(long)]
    deform: bool,
    /// `oriented`: instead of the engine rows, each size's box in both models in one
    /// run — step times, and each model's elastic part per membership-iteration.
    #[arg(long)]
    model: Option<Model>,
}

/// Runs the report the flags choose: handle deformation, whole cutting frames, the
/// solvers' convergence, surfaces, both models, or the engine rows (sizes, edges, pile).
pub fn bench(flags: BenchFlags) -> Result<(), String> {
    let BenchFlags {
        json,
        sizes,
        threads: _,
        steps,
        solver,
        convergence,
        convergence_size,
        budget,
        substeps,
        iterations,
        pile_spacing,
        pile_frames,
        crowd_bodies,
        no_crowd,
        no_pile,
        no_edges,
        surface,
        cutting,
        dice,
        no_culling,
        deform,
        model,
    } = flags;
    if deform {
        return bench::bench_deform(steps, json);
    }
    if cutting {
        return bench::bench_cutting(dice, json);
    }
    let config = SimConfig {
        solver,
        substeps,
        iterations,
        culling: !no_culling,
        ..SimConfig::default()
    };
    config.validate().map_err(|e| e.to_string())?;
    if convergence {
        let options = cleave::analysis::bench::ConvergenceOptions {
            box_size: convergence_size,
            budget_seconds: budget,
        };
        return bench::bench_convergence(options, json);
    }
    if surface {
        return bench::bench_surfaces(&sizes, steps, &config, json);
    }
    if model == Some(Model::Oriented) {
        return bench::bench_models(&sizes, steps, &config, json);
    }
    let pile = bench::PileOptions {
        spacing: (!no_pile).then_some(pile_spacing),
        crowd: (!no_crowd).then_some(crowd_bodies),
        frames: pile_frames,
    };
    bench::bench(&sizes, steps, config, json, pile, no_edges)
}

/// `--dice`: a box edge in particles the cutting bench can dice, 2 to 160.
fn dice_size(s: &str) -> Result<u32, String> {
    let n = whole::<u32>(s)?;
    if (2..=160).contains(&n) {
        Ok(n)
    } else {
        Err(format!("{n} is out of range (allowed: 2 to 160 particles)"))
    }
}
