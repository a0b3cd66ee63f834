//! The simulation thread of `cleave view`: it owns the simulation, carries out the
//! pages' commands between frames, steps in real time while playing, and publishes
//! each frame as one [`Published`] snapshot. Pages read the latest snapshot whenever
//! they are ready, so a slow page misses frames and never holds the simulation back.
//!
//! A panic while carrying out a command, stepping or publishing stops the simulation
//! (it may be half updated) but not the thread: the last frame is published again with
//! the reason in its status's `stopped`, which every page shows, and a reset or another
//! scene starts afresh.

use super::protocol::{Command, cut_mode_name};
use super::refusals::Refusals;
use super::snapshot::{self, Published};
use cleave::cut::tool::CutMode;
use cleave::ecs::desc::Scene;
use cleave::sim::interact::Interaction;
use cleave::sim::simulation::Simulation;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};
use tokio::sync::watch;

/// A scene a page may choose: its name and how to build it.
pub struct Offered {
    /// Name shown on the page.
    pub name: String,
    /// The scene (with its own tools).
    pub scene: Scene,
}

/// The simulation of `scene`, with its own tools or without, its surfaces extracted.
fn build(scene: &Scene, scripted_tools: bool) -> Result<Simulation, String> {
    let mut scene = scene.clone();
    if !scripted_tools {
        scene.tools.clear();
    }
    let mut sim = Simulation::from_scene(&scene).map_err(|e| e.to_string())?;
    sim.update_surfaces()
        .map_err(|e| format!("surfaces: {e}"))?;
    Ok(sim)
}

/// What the simulation thread runs on.
pub struct Runner {
    offered: Vec<Offered>,
    current: usize,
    sim: Simulation,
    interaction: Interaction,
    playing: bool,
    cut_mode: CutMode,
    scripted_tools: bool,
    ms_per_step: f64,
    epoch: u64,
    last: Option<Arc<Published>>,
    /// Why the simulation stopped, after a panic.
    stopped: Option<String>,
    /// Whether the test-only `panic` command is carried out.
    test_panic: bool,
}

impl Runner {
    /// Starts on the offered scene `current`, playing, without the scene's own tools
    /// (the pointer is the tool); an error when the scene will not build.
    pub fn new(offered: Vec<Offered>, current: usize, test_panic: bool) -> Result<Self, String> {
        Ok(Runner {
            sim: build(&offered[current].scene, false)?,
            offered,
            current,
            interaction: Interaction::new(),
            playing: true,
            cut_mode: CutMode::Sever,
            scripted_tools: false,
            ms_per_step: 0.0,
            epoch: 1,
            last: None,
            stopped: None,
            test_panic,
        })
    }

    /// Starts the offered scene `index` afresh; a scene that will not build leaves the
    /// running one as it was.
    fn load(&mut self, index: usize) -> Result<(), String> {
        self.sim = build(&self.offered[index].scene, self.scripted_tools)?;
        self.current = index;
        self.interaction = Interaction::new();
        self.epoch += 1;
        self.stopped = None;
        Ok(())
    }

    /// Carries out one command; an error is a line for the log (the simulation goes
    /// on as it was).
    pub fn apply(&mut self, command: Command) -> Result<(), String> {
        let starts_afresh = matches!(
            command,
            Command::Reset | Command::Scene(_) | Command::ScriptedTools(_)
        );
        if let Some(why) = &self.stopped
            && !starts_afresh
        {
            return Err(format!("the simulation stopped ({why}): reset it"));
        }
        let (sim, interaction) = (&mut self.sim, &mut self.interaction);
        match command {
            Command::Play => self.playing = true,
            Command::Pause => self.playing = false,
            Command::Step => {
                self.playing = false;
                self.step();
            }
            Command::Reset => self.load(self.current)?,
            Command::Scene(name) => {
                let index = self
                    .offered
                    .iter()
                    .position(|o| o.name == name)
                    .ok_or_else(|| format!("no scene `{name}` is offered"))?;
                self.load(index)?;
            }
            Command::CutMode(mode) => self.cut_mode = mode,
            Command::ScriptedTools(on) => {
                self.scripted_tools = on;
                self.load(self.current)?;
            }
            Command::Stroke(eye, from, to) => interaction
                .stroke(sim, eye, from, to, self.cut_mode)
                .map_err(|e| e.to_string())?,
            Command::Grab(eye, dir) => {
                let grabbed = interaction.press(sim, eye, dir);
                if grabbed.map_err(|e| e.to_string())?.is_none() {
                    return Err("grab: nothing under the pointer".into());
                }
            }
            Command::Drag(eye, dir) => {
                interaction.drag(sim, eye, dir).map_err(|e| e.to_string())?
            }
            Command::Release => interaction.release(sim).map_err(|e| e.to_string())?,
            Command::Panic if self.test_panic => panic!("the test-only panic command"),
            Command::Panic => return Err("unknown command `panic`".into()),
        }
        Ok(())
    }

    fn step(&mut self) {
        let start = Instant::now();
        if let Err(e) = self.interaction.before_step(&mut self.sim) {
            eprintln!("cleave view: {e}");
        }
        self.sim.step();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        // a running mean over about a second of frames, for the overlay
        self.ms_per_step = if self.ms_per_step == 0.0 {
            ms
        } else {
            0.95 * self.ms_per_step + 0.05 * ms
        };
    }

    /// Runs `f`; a panic in it stops the simulation (see the module docs) and gives
    /// `None`.
    fn guarded<T>(&mut self, f: impl FnOnce(&mut Self) -> T) -> Option<T> {
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(self))) {
            Ok(value) => Some(value),
            Err(payload) => {
                let why = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "a panic".into());
                eprintln!("cleave view: the simulation stopped: {why}");
                self.stopped = Some(why);
                self.playing = false;
                None
            }
        }
    }

    /// The snapshot to publish now: the simulation's, or after a panic the last one
    /// with the reason.
    fn publish_guarded(&mut self) -> Arc<Published> {
        if self.stopped.is_none()
            && let Some(published) = self.guarded(Self::publish)
        {
            return published;
        }
        let last = self.last.as_deref().cloned().unwrap_or_default();
        let mut status: serde_json::Value =
            serde_json::from_str(&last.status).unwrap_or_else(|_| serde_json::json!({}));
        status["stopped"] = serde_json::json!(self.stopped);
        status["playing"] = serde_json::json!(false);
        Arc::new(Published {
            status: status.to_string(),
            ..last
        })
    }

    /// The snapshot of the simulation as it is now.
    pub fn publish(&mut self) -> Arc<Published> {
        let names: Vec<&str> = self.offered.iter().map(|o| o.name.as_str()).collect();
        let settings = snapshot::Settings {
            epoch: self.epoch,
            scene: &self.offered[self.current].name,
            scenes: &names,
            playing: self.playing,
            cut_mode: cut_mode_name(self.cut_mode),
            scripted_tools: self.scripted_tools,
            ms_per_step: self.ms_per_step,
        };
        let published = Arc::new(snapshot::take(
            &mut self.sim,
            settings,
            self.last.as_deref(),
        ));
        self.last = Some(published.clone());
        published
    }

    /// Runs until every sender of `commands` is gone: commands as they come, a frame
    /// every `dt` of wall time while playing (or as fast as the frames go, when they
    /// take longer), each frame published to `frames`.
    pub fn run(
        mut self,
        commands: Receiver<Command>,
        frames: watch::Sender<Arc<Published>>,
        refusals: &Refusals,
    ) {
        let mut next = Instant::now();
        loop {
            let dt = Duration::from_secs_f32(self.sim.config().dt);
            let wait = if self.playing {
                next.saturating_duration_since(Instant::now())
            } else {
                Duration::from_millis(100)
            };
            let mut changed = false;
            match commands.recv_timeout(wait) {
                Ok(command) => {
                    if let Some(Err(e)) = self.guarded(|r| r.apply(command)) {
                        refusals.note(&e);
                    }
                    changed = true;
                }
                Err(RecvTimeoutError::Disconnected) => return,
                Err(RecvTimeoutError::Timeout) => {}
            }
            // (a stream of commands does not hold the frames back)
            if self.playing && Instant::now() >= next {
                self.guarded(Self::step);
                // fall behind rather than catch up in a burst
                next = (next + dt).max(Instant::now());
                changed = true;
            }
            if changed {
                frames.send_replace(self.publish_guarded());
            }
        }
    }
}
