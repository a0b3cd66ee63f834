//! [`CleavePlugin`] (cargo feature `bevy_app`): the cleave stages in a Bevy [`App`].
//!
//! The plugin installs the resources, messages and the [`CleaveSchedule`], and runs one
//! simulation frame per run of the schedule label you choose. The default is
//! [`Update`], which runs on every `app.update()`. Fixed-step labels such as
//! `FixedUpdate` only run when bevy_time drives them; without it they never run, so
//! choose them only in an app with `TimePlugin` (and set `SimConfig::dt` to the fixed
//! step). Messages (`ParticlesCut`, `ClustersRebuilt`, `BodySplit`) are registered
//! with the app's message update, so ordinary `MessageReader`s see them.
//!
//! The frame runs in the system set [`CleaveFrame`]: order a system that moves tools,
//! colliders or attachment targets for the coming frame `.before(CleaveFrame)`, and one
//! that reads the frame's positions or messages `.after(CleaveFrame)`.

use crate::config::SimConfig;
use crate::error::Result;
use crate::systems::{CleaveSchedule, install};
use bevy_app::{App, Plugin, Update};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;

/// The system set the plugin's simulation frame runs in (see the module docs).
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CleaveFrame;

/// Adds cleave to an [`App`]; see the module docs.
#[derive(Clone, Debug)]
pub struct CleavePlugin<L: ScheduleLabel + Clone = Update> {
    config: SimConfig,
    schedule: L,
}

impl CleavePlugin<Update> {
    /// A plugin that steps the simulation once per [`Update`]; the config is checked.
    pub fn new(config: SimConfig) -> Result<Self> {
        config.validate()?;
        Ok(Self {
            config,
            schedule: Update,
        })
    }
}

impl<L: ScheduleLabel + Clone> CleavePlugin<L> {
    /// The same plugin, stepping in the schedule `label` instead.
    pub fn in_schedule<M: ScheduleLabel + Clone>(self, label: M) -> CleavePlugin<M> {
        CleavePlugin {
            config: self.config,
            schedule: label,
        }
    }
}

impl<L: ScheduleLabel + Clone> Plugin for CleavePlugin<L> {
    fn build(&self, app: &mut App) {
        install(app.world_mut(), self.config.clone());
        app.add_systems(self.schedule.clone(), run_cleave_frame.in_set(CleaveFrame));
    }
}

/// Exclusive system: advances the simulation by one frame.
pub fn run_cleave_frame(world: &mut World) {
    world.run_schedule(CleaveSchedule);
}
