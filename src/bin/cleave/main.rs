//! The `cleave` command-line program: run scenes, list them, benchmark the engine.

mod bench;
mod run;

use clap::{Parser, Subcommand};
use cleave::config::SolverMode;
use cleave::scene::BUILTIN_SCENES;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "cleave",
    version,
    about = "Lattice soft bodies with real-time cutting"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a built-in scene and write a summary.
    Run {
        /// Scene name (see `cleave scenes`).
        scene: String,
        /// Frames to simulate (default: the scene's).
        #[arg(long)]
        frames: Option<u32>,
        /// Output directory for summary.json.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Random seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Write the final state (cleave-state/1 JSON) to this file.
        #[arg(long)]
        dump_state: Option<PathBuf>,
    },
    /// List the built-in scenes.
    Scenes,
    /// Benchmark boxes of n³ particles: engine vs bare kernel, memory, cut event.
    Bench {
        /// Print one JSON object per size (the convergence table goes to stderr).
        #[arg(long)]
        json: bool,
        /// Box edge lengths in particles.
        #[arg(long, value_delimiter = ',', default_value = "16,32,48,64")]
        sizes: Vec<u32>,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Timed steps per size (median reported).
        #[arg(long, default_value_t = 30)]
        steps: usize,
        /// Solver scheme.
        #[arg(long, value_enum, default_value = "jacobi")]
        solver: SolverArg,
        /// Skip the convergence table.
        #[arg(long)]
        no_convergence: bool,
    },
}

/// Solver scheme on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
enum SolverArg {
    Jacobi,
    GaussSeidel,
}

impl From<SolverArg> for SolverMode {
    fn from(s: SolverArg) -> Self {
        match s {
            SolverArg::Jacobi => SolverMode::Jacobi,
            SolverArg::GaussSeidel => SolverMode::GaussSeidel,
        }
    }
}

/// Runs `f` on a rayon pool of `threads` threads (default: all cores).
fn with_threads<T>(
    threads: Option<usize>,
    f: impl FnOnce(usize) -> Result<T, String> + Send,
) -> Result<T, String>
where
    T: Send,
{
    let threads = threads.unwrap_or_else(rayon::current_num_threads).max(1);
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(|| f(threads)),
        Err(e) => Err(format!("cannot start {threads} threads: {e}")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scenes => {
            for (name, description) in BUILTIN_SCENES {
                println!("{name:<12} {description}");
            }
            Ok(())
        }
        Command::Run {
            scene,
            frames,
            out,
            seed,
            threads,
            dump_state,
        } => with_threads(threads, |threads| {
            run::run(&scene, frames, out, seed, dump_state, threads)
        }),
        Command::Bench {
            json,
            sizes,
            threads,
            steps,
            solver,
            no_convergence,
        } => with_threads(threads, |_| {
            bench::bench(&sizes, steps, solver.into(), json, !no_convergence)
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cleave: {e}");
            ExitCode::from(2)
        }
    }
}
