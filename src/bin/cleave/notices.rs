//! What the library tells its user through `tracing` — a solver falling back, a long
//! factorisation — printed on standard error as `cleave: warning: …` (always) and
//! `cleave: …` (notes, unless `--quiet`). Without this the library's warnings would
//! reach nobody: the program installs no other subscriber.

use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, Layer};
use tracing_subscriber::prelude::*;

/// Prints events at or above `quietest` (warnings, or also notes).
struct Notices {
    quietest: Level,
}

/// An event's `message` field.
struct Message(String);

impl Visit for Message {
    fn record_str(&mut self, field: &Field, value: &str) {
        if field.name() == "message" {
            self.0 = value.to_string();
        }
    }
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

impl<S: Subscriber> Layer<S> for Notices {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let level = *event.metadata().level();
        if level > self.quietest {
            return;
        }
        let mut message = Message(String::new());
        event.record(&mut message);
        if level <= Level::WARN {
            eprintln!("cleave: warning: {}", message.0);
        } else {
            eprintln!("cleave: {}", message.0);
        }
    }
}

/// Installs the printer for the whole program: warnings always, notes unless `quiet`.
pub fn install(quiet: bool) {
    let quietest = if quiet { Level::WARN } else { Level::INFO };
    // (a second install, or one after another subscriber, changes nothing)
    let _ = tracing::subscriber::set_global_default(
        tracing_subscriber::registry().with(Notices { quietest }),
    );
}
