//! Per-stage wall time from the `system` spans that bevy_ecs opens around every system
//! run (its `trace` feature): a tracing layer adds up the time between entering and
//! leaving each span, keyed by the system's name. Install it with
//! [`StageProfile::install`]; read the table with [`StageProfile::rows`].

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tracing::field::{Field, Visit};
use tracing::span::{Attributes, Id};
use tracing::subscriber::Subscriber;
use tracing_subscriber::layer::{Context, Layer};
use tracing_subscriber::prelude::*;
use tracing_subscriber::registry::LookupSpan;

/// Accumulated time per system.
#[derive(Clone, Default)]
pub struct StageProfile {
    totals: Arc<Mutex<BTreeMap<String, (Duration, u64)>>>,
}

/// The system name recorded on a span.
struct SystemName(String);
/// When the span was last entered.
struct Entered(Instant);

struct NameVisitor(Option<String>);
impl Visit for NameVisitor {
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "name" {
            self.0 = Some(value.to_string());
        }
    }
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "name" {
            self.0 = Some(format!("{value:?}").trim_matches('"').to_string());
        }
    }
}

impl<S: Subscriber + for<'a> LookupSpan<'a>> Layer<S> for StageProfile {
    fn on_new_span(&self, attrs: &Attributes<'_>, id: &Id, ctx: Context<'_, S>) {
        if attrs.metadata().name() != "system" {
            return;
        }
        let mut visitor = NameVisitor(None);
        attrs.record(&mut visitor);
        if let (Some(name), Some(span)) = (visitor.0, ctx.span(id)) {
            span.extensions_mut().insert(SystemName(name));
        }
    }

    fn on_enter(&self, id: &Id, ctx: Context<'_, S>) {
        if let Some(span) = ctx.span(id) {
            let mut ext = span.extensions_mut();
            if ext.get_mut::<SystemName>().is_some() {
                ext.replace(Entered(Instant::now()));
            }
        }
    }

    fn on_exit(&self, id: &Id, ctx: Context<'_, S>) {
        let Some(span) = ctx.span(id) else {
            return;
        };
        let ext = span.extensions();
        if let (Some(SystemName(name)), Some(Entered(at))) =
            (ext.get::<SystemName>(), ext.get::<Entered>())
            && let Ok(mut totals) = self.totals.lock()
        {
            let entry = totals.entry(name.clone()).or_default();
            entry.0 += at.elapsed();
            entry.1 += 1;
        }
    }
}

impl StageProfile {
    /// Installs the profile as this thread's tracing subscriber for as long as the
    /// returned guard lives.
    pub fn install(&self) -> tracing::subscriber::DefaultGuard {
        tracing::dispatcher::set_default(&self.dispatch())
    }

    /// The profile as a tracing dispatcher, to be made the default where its stages
    /// should be timed (a span reports to the dispatcher it was made under).
    pub fn dispatch(&self) -> tracing::Dispatch {
        tracing::Dispatch::new(tracing_subscriber::registry().with(self.clone()))
    }

    /// `(system, total ms, runs)`, slowest first; names shortened to the last path
    /// segment.
    pub fn rows(&self) -> Vec<(String, f64, u64)> {
        let totals = self.totals.lock().map(|t| t.clone()).unwrap_or_default();
        let mut rows: Vec<(String, f64, u64)> = totals
            .into_iter()
            .map(|(name, (d, n))| {
                let short = name.rsplit("::").next().unwrap_or(&name).to_string();
                (short, d.as_secs_f64() * 1e3, n)
            })
            .collect();
        rows.sort_by(|a, b| b.1.total_cmp(&a.1));
        rows
    }

    /// Total milliseconds so far per system, by the short names of [`Self::rows`]:
    /// two readings a frame apart give that frame's time per stage.
    pub fn totals_ms(&self) -> BTreeMap<String, f64> {
        self.rows()
            .into_iter()
            .map(|(name, ms, _)| (name, ms))
            .collect()
    }

    /// The rows as a text table with ms per frame over `frames` frames.
    pub fn table(&self, frames: u32) -> String {
        let mut out = format!(
            "{:<26} {:>10} {:>12} {:>8}\n",
            "stage", "total ms", "ms / frame", "runs"
        );
        for (name, ms, runs) in self.rows() {
            let _ = writeln!(
                out,
                "{name:<26} {ms:>10.2} {:>12.4} {runs:>8}",
                ms / frames.max(1) as f64
            );
        }
        out
    }
}

/// The parts of the solver's time (seconds each, as
/// [`crate::solver::solve::Solver::seconds`] gives them) as rows of the profile table:
/// `shape-match: NAME`, total ms and ms per frame over `frames` frames.
pub fn solver_table(parts: &[(&'static str, f64)], frames: u32) -> String {
    let mut out = String::new();
    for (name, seconds) in parts {
        let ms = seconds * 1e3;
        let _ = writeln!(
            out,
            "{:<26} {ms:>10.2} {:>12.4}",
            format!("  shape-match: {name}"),
            ms / frames.max(1) as f64
        );
    }
    out
}
