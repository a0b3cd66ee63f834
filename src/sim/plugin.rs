//! [`CleavePlugin`] (cargo feature `bevy_app`): the cleave stages in a Bevy [`App`],
//! on the game's clock.
//!
//! The plugin installs the resources, messages and the
//! [`CleaveSchedule`](crate::systems::CleaveSchedule), and runs one simulation frame per
//! run of its schedule (on rayon's pool, see [`crate::systems::run_frame`]): by default
//! [`FixedPostUpdate`], which bevy_time's `TimePlugin` runs once per fixed timestep of
//! `Time<Fixed>` (after the game's `FixedUpdate`, as avian does), so the simulation
//! keeps the game's time whatever the display's frame rate. Each frame is
//! `Time<Fixed>`'s timestep long ([`StepClock::FixedTimestep`]); an app without
//! `Time<Fixed>` — a headless test, a tool — steps by the config's `dt`. Another
//! schedule is a choice ([`CleavePlugin::in_schedule`]); `Update` runs once per
//! `app.update()` without bevy_time.
//!
//! The frame runs in three system sets, chained, all inside [`CleaveFrame`]:
//! [`CleaveSystems::Prepare`] (the frame's length follows the clock), then
//! [`CleaveSystems::StepSimulation`] (the whole
//! [`CleaveSchedule`](crate::systems::CleaveSchedule): motion, cutting, the surface),
//! then [`CleaveSystems::Writeback`] (what the frame hands to the game: meshes with the
//! `bevy_mesh` feature, diagnostics with `bevy_diagnostic`). Order a system that moves
//! tools, colliders or attachment targets for the coming frame
//! `.before(CleaveFrame)` (or in `FixedUpdate`), and one that reads the frame's
//! positions or messages `.after(CleaveFrame)`. Messages (`ParticlesCut`,
//! `ClustersRebuilt`, `BodySplit`, …) are registered with the app's message update, so
//! ordinary `MessageReader`s see them.

use crate::config::SimConfig;
use crate::ecs::resources::SimSettings;
use crate::error::Result;
use crate::systems::{install, run_frame};
use bevy_app::{App, FixedPostUpdate, Plugin};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use bevy_time::{Fixed, Time};
use std::time::Duration;

pub use super::sets::{CleaveFrame, CleaveSystems, LastFrame};

/// What a frame's length follows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StepClock {
    /// `Time<Fixed>`'s timestep when the app has one (changes at run time are
    /// followed), else the config's `dt`. A timestep that is the config's `dt` as
    /// closely as the two types can say keeps the config's value: a `Duration` holds
    /// whole nanoseconds, an f32 near 1/60 s steps by 1.9 ns, so `1/60 s` is
    /// 16 666 666 or 16 666 667 ns, and the first, read back as f32, is another frame
    /// length by a unit — and another run.
    #[default]
    FixedTimestep,
    /// Always the config's `dt`.
    Config,
}

/// Adds cleave to an [`App`]; see the module docs.
#[derive(Clone, Debug)]
pub struct CleavePlugin<L: ScheduleLabel + Clone = FixedPostUpdate> {
    config: SimConfig,
    schedule: L,
    clock: StepClock,
}

impl CleavePlugin<FixedPostUpdate> {
    /// A plugin that steps the simulation once per [`FixedPostUpdate`], by
    /// `Time<Fixed>`'s timestep; the config is checked.
    pub fn new(config: SimConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            schedule: FixedPostUpdate,
            clock: StepClock::FixedTimestep,
        })
    }
}

impl<L: ScheduleLabel + Clone> CleavePlugin<L> {
    /// The same plugin, stepping in the schedule `label` instead (for example `Update`,
    /// once per `app.update()`, which needs no bevy_time).
    pub fn in_schedule<M: ScheduleLabel + Clone>(self, label: M) -> CleavePlugin<M> {
        CleavePlugin {
            config: self.config,
            schedule: label,
            clock: self.clock,
        }
    }

    /// The same plugin, with frames as long as `clock` says.
    pub fn with_clock(self, clock: StepClock) -> Self {
        Self { clock, ..self }
    }
}

impl<L: ScheduleLabel + Clone> Plugin for CleavePlugin<L> {
    fn build(&self, app: &mut App) {
        install(app.world_mut(), self.config.clone());
        let schedule = self.schedule.clone();
        app.configure_sets(
            schedule.clone(),
            (
                CleaveSystems::Prepare,
                CleaveSystems::StepSimulation,
                CleaveSystems::Writeback,
            )
                .chain()
                .in_set(CleaveFrame),
        );
        if self.clock == StepClock::FixedTimestep {
            app.add_systems(
                schedule.clone(),
                follow_fixed_timestep.in_set(CleaveSystems::Prepare),
            );
        }
        app.add_systems(
            schedule.clone(),
            run_cleave_frame.in_set(CleaveSystems::StepSimulation),
        );
        #[cfg(feature = "bevy_mesh")]
        super::meshes::install(app, schedule.clone());
        #[cfg(feature = "bevy_diagnostic")]
        super::diagnostics::install(app, schedule);
    }
}

/// Exclusive system: advances the simulation by one frame, timing it ([`LastFrame`]).
pub fn run_cleave_frame(world: &mut World) {
    let start = std::time::Instant::now();
    run_frame(world);
    world.insert_resource(LastFrame {
        wall: start.elapsed(),
    });
}

/// Sets the frame's length to `Time<Fixed>`'s timestep, if the app has one (see
/// [`StepClock::FixedTimestep`]). A timestep the config refuses (beyond 1 s) is logged
/// once per change and the frame keeps its length.
pub fn follow_fixed_timestep(
    fixed: Option<Res<Time<Fixed>>>,
    mut settings: ResMut<SimSettings>,
    mut refused: Local<Option<Duration>>,
) {
    let Some(fixed) = fixed else { return };
    let timestep = fixed.timestep();
    let Some(dt) = frame_length(timestep, settings.0.dt) else {
        return;
    };
    let mut config = settings.0.clone();
    config.dt = dt;
    match config.validate() {
        Ok(()) => settings.0.dt = dt,
        Err(e) if *refused != Some(timestep) => {
            *refused = Some(timestep);
            tracing::warn!("cleave keeps dt = {} s: {e}", settings.0.dt);
        }
        Err(_) => {}
    }
}

/// The frame length a fixed `timestep` asks for, if it is not `dt`: the same within a
/// nanosecond or two f32 units of `dt`, whichever is more (see
/// [`StepClock::FixedTimestep`]).
pub fn frame_length(timestep: Duration, dt: f32) -> Option<f32> {
    let dt = dt as f64;
    let resolution = (2.0 * f32::EPSILON as f64 * dt).max(1e-9);
    let same = (timestep.as_secs_f64() - dt).abs() <= resolution;
    (!same).then_some(timestep.as_secs_f32())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timestep_as_close_as_the_types_say_keeps_the_configs_dt() {
        let below = Duration::from_nanos(16_666_666);
        assert_ne!(below.as_secs_f32(), 1.0 / 60.0, "the case this guards");
        for sixtieth in [below, Duration::from_nanos(16_666_667)] {
            assert_eq!(frame_length(sixtieth, 1.0 / 60.0), None);
        }
        assert!(frame_length(Duration::from_nanos(16_666_660), 1.0 / 60.0).is_some());
        assert_eq!(
            frame_length(Duration::from_micros(15_625), 1.0 / 60.0),
            Some(0.015625)
        );
        assert_eq!(frame_length(Duration::from_micros(15_625), 0.015625), None);
    }
}
