//! The plugin's measurements in Bevy's `DiagnosticsStore` (cargo feature
//! `bevy_diagnostic`): each frame's wall time and the counts a game watches — live
//! particles, clusters, pieces, cut events — recorded in [`CleaveSystems::Writeback`]
//! by [`CleavePlugin`](super::plugin::CleavePlugin), readable like Bevy's own
//! (`LogDiagnosticsPlugin` prints them).

use super::sets::{CleaveSystems, LastFrame};
use crate::ecs::components::{BodyLattice, ClusterMembers};
use crate::ecs::resources::CutReport;
use bevy_app::App;
use bevy_diagnostic::{Diagnostic, DiagnosticPath, Diagnostics, RegisterDiagnostic};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;

/// Wall time of the last simulation frame (ms).
pub const STEP_TIME: DiagnosticPath = DiagnosticPath::const_new("cleave/step_time");
/// Live particles of every body.
pub const PARTICLES: DiagnosticPath = DiagnosticPath::const_new("cleave/particles");
/// Clusters of every body.
pub const CLUSTERS: DiagnosticPath = DiagnosticPath::const_new("cleave/clusters");
/// Pieces of every body.
pub const PIECES: DiagnosticPath = DiagnosticPath::const_new("cleave/pieces");
/// Bodies cut in the last frame (one cut event each).
pub const CUT_EVENTS: DiagnosticPath = DiagnosticPath::const_new("cleave/cut_events");

/// Registers the diagnostics and records them after each frame in `schedule`.
pub(super) fn install(app: &mut App, schedule: impl ScheduleLabel) {
    app.register_diagnostic(Diagnostic::new(STEP_TIME).with_suffix(" ms"))
        .register_diagnostic(Diagnostic::new(PARTICLES))
        .register_diagnostic(Diagnostic::new(CLUSTERS))
        .register_diagnostic(Diagnostic::new(PIECES))
        .register_diagnostic(Diagnostic::new(CUT_EVENTS));
    app.add_systems(schedule, record.in_set(CleaveSystems::Writeback));
}

/// Adds this frame's measurements.
fn record(
    mut diagnostics: Diagnostics,
    frame: Option<Res<LastFrame>>,
    bodies: Query<&BodyLattice>,
    clusters: Query<(), With<ClusterMembers>>,
    cut: Res<CutReport>,
) {
    if let Some(frame) = frame {
        diagnostics.add_measurement(&STEP_TIME, || frame.wall.as_secs_f64() * 1e3);
    }
    let (particles, pieces) = bodies.iter().fold((0, 0), |(n, p), b| {
        (n + b.lattice.live_count(), p + b.pieces)
    });
    diagnostics.add_measurement(&PARTICLES, || particles as f64);
    diagnostics.add_measurement(&PIECES, || pieces as f64);
    diagnostics.add_measurement(&CLUSTERS, || clusters.iter().count() as f64);
    diagnostics.add_measurement(&CUT_EVENTS, || cut.bodies.len() as f64);
}
