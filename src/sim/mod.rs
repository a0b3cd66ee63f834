//! The headless facade ([`simulation::Simulation`]) and the Bevy plugin.

#[cfg(feature = "bevy_diagnostic")]
pub mod diagnostics;
pub mod interact;
#[cfg(feature = "bevy_mesh")]
pub mod meshes;
#[cfg(feature = "bevy_app")]
pub mod plugin;
pub mod relax;
pub mod relax_report;
#[cfg(feature = "bevy_app")]
pub mod sets;
pub mod simulation;
