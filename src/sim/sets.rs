//! The system sets the plugin's frame runs in, and what it records of the last frame:
//! named apart from the plugin so that the parts that hang on the frame (meshes,
//! diagnostics) can name them without it.

use bevy_ecs::prelude::*;
use std::time::Duration;

/// The whole of the plugin's simulation frame (the three [`CleaveSystems`]).
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CleaveFrame;

/// The parts of the plugin's frame, in the order they run (see [`super::plugin`]).
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CleaveSystems {
    /// The frame's length follows the clock ([`StepClock`](super::plugin::StepClock)); nothing moves yet.
    Prepare,
    /// One simulation frame: the [`CleaveSchedule`](crate::systems::CleaveSchedule).
    StepSimulation,
    /// The frame's results handed to the game (meshes, diagnostics, and the game's own
    /// systems placed here).
    Writeback,
}

/// How long the last simulation frame took (wall time of the [`CleaveSchedule`](crate::systems::CleaveSchedule)).
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct LastFrame {
    /// Wall time of the frame.
    pub wall: Duration,
}
