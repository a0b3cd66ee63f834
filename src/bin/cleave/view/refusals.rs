//! The log of what `cleave view` refused (bad messages, commands it could not carry
//! out): at most one line a second, with how many were refused and each distinct reason
//! once, so that a page flooding the server cannot flood the terminal.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Distinct reasons kept for one line.
const MAX_REASONS: usize = 16;
/// Characters kept of a reason.
const MAX_REASON_CHARS: usize = 160;
/// The shortest time between two lines.
pub const PERIOD: Duration = Duration::from_secs(1);

#[derive(Default)]
struct Pending {
    count: u64,
    reasons: Vec<String>,
    last_line: Option<Instant>,
}

/// Refusals not yet logged; shared by the server's sessions and the simulation thread.
#[derive(Default)]
pub struct Refusals(Mutex<Pending>);

impl Refusals {
    /// Notes one refusal: logged at once when no line went out in the last second,
    /// else with the next line.
    pub fn note(&self, reason: &str) {
        let mut p = self.0.lock().unwrap_or_else(|e| e.into_inner());
        p.count += 1;
        let reason: String = reason.chars().take(MAX_REASON_CHARS).collect();
        if p.reasons.len() < MAX_REASONS && !p.reasons.contains(&reason) {
            p.reasons.push(reason);
        }
        if p.last_line.is_none_or(|t| t.elapsed() >= PERIOD) {
            Self::write(&mut p);
        }
    }

    /// Logs what is pending if a second has passed since the last line (call it about
    /// once a second).
    pub fn flush(&self) {
        let mut p = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if p.count > 0 && p.last_line.is_none_or(|t| t.elapsed() >= PERIOD) {
            Self::write(&mut p);
        }
    }

    fn write(p: &mut Pending) {
        let plural = if p.count == 1 { "" } else { "s" };
        eprintln!(
            "cleave view: ignored {} message{plural}: {}",
            p.count,
            p.reasons.join(" | ")
        );
        p.count = 0;
        p.reasons.clear();
        p.last_line = Some(Instant::now());
    }
}
