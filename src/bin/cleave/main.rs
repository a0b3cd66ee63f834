//! The `cleave` command-line program: run scenes, list them, benchmark the engine.

mod bench;
mod bench_flags;
mod fidelity;
mod flags;
mod notices;
mod pictures;
mod run;
mod run_frames;
mod summary;
#[cfg(feature = "viewer")]
mod view;

use clap::{Parser, Subcommand};
use cleave::config::{Model, SolverMode};
use cleave::cut::tool::CutMode;
use cleave::ecs::handles::PoseMethod;
use cleave::io::render::{ColorMode, Draw};
use cleave::io::scene::BUILTIN_SCENES;
use cleave::io::scene_file::SceneFile;
#[cfg(feature = "viewer")]
use flags::token;
use flags::{frame_count, whole};
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

/// The flags of `cleave run` (and `cleave relax`).
#[derive(clap::Args)]
struct RunFlags {
    /// Built-in scene name (see `cleave scenes`) or a `.ron` scene file.
    scene: String,
    /// Frames to simulate (default: the scene's; 0 for `cleave relax`).
    #[arg(long, value_parser = frame_count, allow_negative_numbers = true)]
    frames: Option<u32>,
    /// Output directory for summary.json.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Random seed (default: the scene's; 0 for built-ins).
    #[arg(long, value_parser = whole::<u64>, allow_negative_numbers = true)]
    seed: Option<u64>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = whole::<usize>, allow_negative_numbers = true)]
    threads: Option<usize>,
    /// Write the final state (cleave-state/2 JSON) to this file.
    #[arg(long)]
    dump_state: Option<PathBuf>,
    /// Save the simulation at the end to this file (binary; `--load-state` resumes it).
    #[arg(long)]
    save_state: Option<PathBuf>,
    /// Start from a simulation saved with `--save-state` instead of the scene's start
    /// (the scene still names the run; `--frames` counts the frames run on).
    #[arg(long)]
    load_state: Option<PathBuf>,
    /// Write a PNG every N frames (0: none).
    #[arg(long, default_value_t = 30, value_parser = whole::<u32>, allow_negative_numbers = true)]
    png_every: u32,
    /// Add a frame to `run.gif` every N frames (0: no GIF).
    #[arg(long, default_value_t = 3, value_parser = whole::<u32>, allow_negative_numbers = true)]
    gif_every: u32,
    /// Colour particles by piece, by cluster, or by orientation (`orientation` draws the
    /// particles, each coloured by its turn).
    #[arg(long, value_enum, default_value = "pieces")]
    color: ColorArg,
    /// Image width in pixels.
    #[arg(long, default_value_t = 640, value_parser = whole::<u32>, allow_negative_numbers = true)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 480, value_parser = whole::<u32>, allow_negative_numbers = true)]
    height: u32,
    /// What stands for a body in the pictures: its surface, its particles, or both.
    #[arg(long, value_enum, default_value = "surfaces")]
    draw: DrawArg,
    /// Also export, comma-separated: point clouds (`ply`: DIR/ply/frame_NNNNN.ply,
    /// every `--ply-every` frames) and the surfaces with every PNG (`obj`:
    /// DIR/obj/frame_NNNNN.obj, a group per piece; `gltf`: DIR/gltf/frame_NNNNN.glb,
    /// a mesh per piece).
    #[arg(long, value_enum, value_delimiter = ',')]
    export: Vec<ExportArg>,
    /// With `--export ply`: a point cloud every N frames.
    #[arg(long, default_value_t = 10, value_parser = whole::<u32>, allow_negative_numbers = true)]
    ply_every: u32,
    /// Print milliseconds per stage (predict, shape-match, detect, cut, regroup,
    /// split, expand).
    #[arg(long)]
    profile: bool,
    /// No progress bar and no report table.
    #[arg(long)]
    quiet: bool,
    /// Solver scheme, overriding the scene's: jacobi, gauss-seidel or projective.
    #[arg(long)]
    solver: Option<SolverMode>,
    /// Substeps per frame, overriding the scene's (1–1000).
    #[arg(long, value_parser = whole::<u32>, allow_negative_numbers = true)]
    substeps: Option<u32>,
    /// Solver iterations per substep, overriding the scene's (1–10000).
    #[arg(long, value_parser = whole::<u32>, allow_negative_numbers = true)]
    iterations: Option<u32>,
    /// What every tool of the scene does where it passes: remove (particles), sever
    /// (edges; no mass is lost) or split (particles in two, by the blade's side).
    #[arg(long)]
    cut_mode: Option<CutMode>,
    /// The model of every body, overriding the scene's: clusters or oriented (oriented
    /// particles, SPEC §5).
    #[arg(long)]
    model: Option<Model>,
    /// Turn conservative culling off (contact pairs and tool tests redone in full
    /// every time): the result is the same bit for bit, only slower.
    #[arg(long)]
    no_culling: bool,
    /// After this frame (0: before the first), replace every body's clusters by a
    /// fresh clustering of its geometry, to compare a cut body with the same shape
    /// built fresh.
    #[arg(long, value_parser = whole::<u32>, allow_negative_numbers = true)]
    recluster_at: Option<u32>,
}

#[derive(Subcommand)]
enum Command {
    /// Run a built-in scene or a scene file and write a summary and pictures.
    Run(RunFlags),
    /// Relax every body of a scene into its rest shape (the scene's `settings.relax`, or
    /// the defaults), then run it as `cleave run` does (`--frames`, default 0) and write
    /// the same outputs; the summary reports each relaxation.
    Relax(RunFlags),
    /// Pose a scene's bodies by their handles instead of simulating them (each body
    /// with `handles` follows them exactly, its particles kinematic; other bodies
    /// simulate), with the pictures and summary of `cleave run`.
    Deform {
        #[command(flatten)]
        flags: RunFlags,
        /// How a posed body follows its handles: `linear` (the linear subspace `V̄ +
        /// W ΔH`), `arap` (as rigid as possible, from the subspace's pose) or `reduced`
        /// (ARAP in the subspace of the handles and 24 automatic ones). Default: linear,
        /// or with `--load-state` the method the saved run posed by.
        #[arg(long, value_enum)]
        method: Option<MethodArg>,
    },
    /// Compare cut bodies' rebuilt clusters with fresh clusterings of the same geometry:
    /// a block cut N times (cluster counts, sizes, memberships, extents) and the
    /// cantilever with 20 scoops (static tip sag).
    Fidelity {
        /// Random cuts of the block (1–1000).
        #[arg(long, default_value_t = 50, value_parser = whole::<u32>, allow_negative_numbers = true)]
        cuts: u32,
        /// Seed of the cuts and scoops.
        #[arg(long, default_value_t = 0, value_parser = whole::<u64>, allow_negative_numbers = true)]
        seed: u64,
        /// What the tools do: remove, sever or split.
        #[arg(long, default_value = "remove")]
        cut_mode: CutMode,
        /// Print the report as one JSON object.
        #[arg(long)]
        json: bool,
        /// Worker threads (default: all cores).
        #[arg(long, value_parser = whole::<usize>, allow_negative_numbers = true)]
        threads: Option<usize>,
    },
    /// List the built-in scenes, or print one as a scene file.
    Scenes {
        #[command(subcommand)]
        action: Option<ScenesAction>,
    },
    /// Benchmark boxes of n³ particles: engine vs bare kernel, memory, cut event.
    Bench(bench_flags::BenchFlags),
    /// Serve an interactive page: the simulation runs here, the browser draws it; orbit,
    /// cut with a mouse stroke, grab and drag.
    #[cfg(feature = "viewer")]
    View {
        /// Built-in scene name or a `.ron` scene file (default: slice).
        scene: Option<String>,
        /// Port to listen on (0: any free port, printed on start).
        #[arg(long, default_value_t = 7878, value_parser = whole::<u16>, allow_negative_numbers = true)]
        port: u16,
        /// Address to listen on (only this machine by default). Any other address lets
        /// the network in: a token is then required (printed in the URL).
        #[arg(long, default_value = "127.0.0.1")]
        host: String,
        /// The token `/status` and the WebSocket require (`?token=` in the URL); made
        /// up and printed when `--host` is not a loopback address.
        #[arg(long, value_parser = token)]
        token: Option<String>,
        /// Carry out the test-only `panic` command (the browser test's).
        #[arg(long, hide = true)]
        test_panic: bool,
        /// Random seed of the built-in scenes.
        #[arg(long, default_value_t = 0, value_parser = whole::<u64>, allow_negative_numbers = true)]
        seed: u64,
        /// Worker threads of the simulation (default: all cores but one, left to the
        /// browser drawing the page).
        #[arg(long, value_parser = whole::<usize>, allow_negative_numbers = true)]
        threads: Option<usize>,
    },
}

/// `cleave scenes` actions.
#[derive(Subcommand)]
enum ScenesAction {
    /// Print a built-in scene as RON, to start a scene file from.
    Show {
        /// Built-in scene name.
        name: String,
    },
}

/// How `cleave deform` poses a body.
#[derive(Clone, Copy, clap::ValueEnum)]
enum MethodArg {
    Linear,
    Arap,
    Reduced,
}

/// Particle colours on the command line.
#[derive(Clone, Copy, clap::ValueEnum)]
enum ColorArg {
    Pieces,
    Clusters,
    Orientation,
}

/// What stands for a body in the pictures.
#[derive(Clone, Copy, clap::ValueEnum)]
enum DrawArg {
    Surfaces,
    Particles,
    Both,
}

/// Export formats.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum ExportArg {
    Ply,
    Obj,
    Gltf,
}

/// Most worker threads `--threads` accepts: far more than any machine's cores, far
/// fewer than would take the process minutes to start.
const MAX_THREADS: usize = 1024;

/// Runs `f` on a rayon pool of `threads` threads (default: all cores); a count outside
/// 1..=[`MAX_THREADS`] is an error.
fn with_threads<T>(
    threads: Option<usize>,
    f: impl FnOnce(usize) -> Result<T, String> + Send,
) -> Result<T, String>
where
    T: Send,
{
    if let Some(t) = threads
        && !(1..=MAX_THREADS).contains(&t)
    {
        return Err(format!(
            "--threads: {t} is out of range (allowed 1 ≤ threads ≤ {MAX_THREADS})"
        ));
    }
    let threads = threads.unwrap_or_else(rayon::current_num_threads).max(1);
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(|| f(threads)),
        Err(e) => Err(format!("cannot start {threads} threads: {e}")),
    }
}

/// `cleave run`, or with `relax` `cleave relax`.
fn run_command(
    flags: RunFlags,
    relax: bool,
    pose: Option<PoseMethod>,
    method_given: bool,
) -> Result<(), String> {
    let RunFlags {
        scene,
        frames,
        out,
        seed,
        threads,
        dump_state,
        save_state,
        load_state,
        png_every,
        gif_every,
        color,
        draw,
        width,
        height,
        export,
        ply_every,
        profile,
        quiet,
        solver,
        substeps,
        iterations,
        cut_mode,
        model,
        no_culling,
        recluster_at,
    } = flags;
    let args = run::RunArgs {
        scene,
        relax,
        pose,
        method_given,
        recluster_at,
        overrides: run::SceneOverrides {
            solver,
            substeps,
            iterations,
            cut_mode,
            model,
            no_culling,
        },
        frames,
        out,
        seed,
        dump_state,
        save_state,
        load_state,
        pictures: pictures::PictureOptions {
            png_every,
            gif_every,
            ply_every: match (export.contains(&ExportArg::Ply), ply_every) {
                (true, 0) => {
                    return Err(
                        "--export ply with --ply-every 0 would write no point cloud: give --ply-every N"
                            .into(),
                    );
                }
                (true, every) => every,
                (false, _) => 0,
            },
            obj: export.contains(&ExportArg::Obj),
            gltf: export.contains(&ExportArg::Gltf),
            color: match color {
                ColorArg::Pieces => ColorMode::Pieces,
                ColorArg::Clusters => ColorMode::Clusters,
                ColorArg::Orientation => ColorMode::Orientation,
            },
            draw: match draw {
                // (orientations are the particles': draw them)
                DrawArg::Surfaces if matches!(color, ColorArg::Orientation) => Draw::Particles,
                DrawArg::Surfaces => Draw::Surfaces,
                DrawArg::Particles => Draw::Particles,
                DrawArg::Both => Draw::Both,
            },
            width,
            height,
            dt: 1.0 / 60.0,
        },
        profile,
        quiet,
    };
    with_threads(threads, |threads| run::run(&args, threads))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    notices::install(matches!(
        &cli.command,
        Command::Run(RunFlags { quiet: true, .. })
            | Command::Relax(RunFlags { quiet: true, .. })
            | Command::Deform {
                flags: RunFlags { quiet: true, .. },
                ..
            }
    ));
    let result = match cli.command {
        Command::Scenes { action: None } => {
            for b in BUILTIN_SCENES {
                println!("{:<12} {}", b.name, b.description);
            }
            Ok(())
        }
        Command::Scenes {
            action: Some(ScenesAction::Show { name }),
        } => run::builtin_scene(&name, 0).and_then(|scene| {
            let file = SceneFile::from_scene(&scene).ok_or("scene has no file form")?;
            print!("{}", file.to_ron());
            Ok(())
        }),
        Command::Run(flags) => run_command(flags, false, None, false),
        Command::Relax(flags) => run_command(flags, true, None, false),
        Command::Deform { flags, method } => {
            let given = method.is_some();
            let method = match method.unwrap_or(MethodArg::Linear) {
                MethodArg::Linear => PoseMethod::Linear,
                MethodArg::Arap => PoseMethod::Arap(Default::default()),
                MethodArg::Reduced => PoseMethod::reduced(),
            };
            run_command(flags, false, Some(method), given)
        }
        Command::Fidelity {
            cuts,
            seed,
            cut_mode,
            json,
            threads,
        } => with_threads(threads, |_| {
            let options = cleave::analysis::fidelity::FidelityOptions {
                cuts,
                seed,
                cut_mode,
                ..Default::default()
            };
            fidelity::fidelity(options, json)
        }),
        Command::Bench(flags) => with_threads(flags.threads, |_| bench_flags::bench(flags)),
        #[cfg(feature = "viewer")]
        Command::View {
            scene,
            port,
            host,
            token,
            test_panic,
            seed,
            threads,
        } => with_threads(
            Some(threads.unwrap_or_else(|| rayon::current_num_threads().saturating_sub(1).max(1))),
            |threads| {
                view::view(view::ViewArgs {
                    scene,
                    port,
                    host,
                    seed,
                    threads,
                    token,
                    test_panic,
                })
            },
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("cleave: {e}");
            ExitCode::from(2)
        }
    }
}
