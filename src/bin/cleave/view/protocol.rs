//! What a page may ask of `cleave view`, as JSON text messages over the WebSocket:
//! `{"cmd": "play"}`, `{"cmd": "stroke", "eye": [x, y, z], "from": [...], "to": [...]}`…
//! Everything is checked here (finite numbers, known names, a bounded size) so that
//! the simulation thread only sees commands it can carry out; anything else is
//! refused with a reason that goes to the log.

use cleave::cut::tool::CutMode;
use glam::Vec3;
use serde::Deserialize;

/// Largest WebSocket message accepted from a page, bytes.
pub const MAX_MESSAGE_BYTES: usize = 16 * 1024;

/// A page's command.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Run in real time.
    Play,
    /// Stop stepping.
    Pause,
    /// One frame, then pause.
    Step,
    /// Start the scene again.
    Reset,
    /// Switch to the scene offered under this name (checked by the caller against
    /// the offered names: a page never names a path).
    Scene(String),
    /// Cut mode of the strokes from now on.
    CutMode(CutMode),
    /// Whether scenes run with their own keyframed tools.
    ScriptedTools(bool),
    /// Cut along a stroke: eye, first ray, last ray.
    Stroke(Vec3, Vec3, Vec3),
    /// Grab what is under the pointer: eye, ray.
    Grab(Vec3, Vec3),
    /// Move the grab along: eye, ray.
    Drag(Vec3, Vec3),
    /// Let go.
    Release,
    /// Panic in the simulation thread: only a server started with `--test-panic`
    /// carries it out (the browser test checks what a page sees when the simulation
    /// stops); every other refuses it.
    Panic,
}

// (commands without fields are empty structs: serde refuses unknown fields only in
// those, not in unit variants)
#[derive(Deserialize)]
#[serde(tag = "cmd", rename_all = "snake_case", deny_unknown_fields)]
enum Wire {
    Play {},
    Pause {},
    Step {},
    Reset {},
    Scene {
        name: String,
    },
    CutMode {
        mode: String,
    },
    ScriptedTools {
        on: bool,
    },
    Stroke {
        eye: [f32; 3],
        from: [f32; 3],
        to: [f32; 3],
    },
    Grab {
        eye: [f32; 3],
        dir: [f32; 3],
    },
    Drag {
        eye: [f32; 3],
        dir: [f32; 3],
    },
    Release {},
    Panic {},
}

/// Reads a page's message; an error says why it is refused.
pub fn parse(text: &str) -> Result<Command, String> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(format!(
            "{} bytes (at most {MAX_MESSAGE_BYTES})",
            text.len()
        ));
    }
    let wire: Wire = serde_json::from_str(text).map_err(|e| e.to_string())?;
    let vector = |name: &str, v: [f32; 3]| {
        let v = Vec3::from_array(v);
        if v.is_finite() && v.abs().max_element() <= 1e6 {
            Ok(v)
        } else {
            Err(format!("{name}: {v} is not finite or beyond ±1e6"))
        }
    };
    Ok(match wire {
        Wire::Play {} => Command::Play,
        Wire::Pause {} => Command::Pause,
        Wire::Step {} => Command::Step,
        Wire::Reset {} => Command::Reset,
        Wire::Scene { name } => Command::Scene(name),
        Wire::CutMode { mode } => Command::CutMode(match mode.as_str() {
            "remove" => CutMode::Remove,
            "sever" => CutMode::Sever,
            "split" => CutMode::Split,
            other => return Err(format!("unknown cut mode `{other}`")),
        }),
        Wire::ScriptedTools { on } => Command::ScriptedTools(on),
        Wire::Stroke { eye, from, to } => Command::Stroke(
            vector("eye", eye)?,
            vector("from", from)?,
            vector("to", to)?,
        ),
        Wire::Grab { eye, dir } => Command::Grab(vector("eye", eye)?, vector("dir", dir)?),
        Wire::Drag { eye, dir } => Command::Drag(vector("eye", eye)?, vector("dir", dir)?),
        Wire::Release {} => Command::Release,
        Wire::Panic {} => Command::Panic,
    })
}

/// The name a page uses for a cut mode.
pub fn cut_mode_name(mode: CutMode) -> &'static str {
    match mode {
        CutMode::Remove => "remove",
        CutMode::Sever => "sever",
        CutMode::Split => "split",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_are_read_and_bad_ones_refused() {
        assert_eq!(parse(r#"{"cmd":"play"}"#), Ok(Command::Play));
        assert_eq!(
            parse(r#"{"cmd":"cut_mode","mode":"split"}"#),
            Ok(Command::CutMode(CutMode::Split))
        );
        assert_eq!(
            parse(r#"{"cmd":"grab","eye":[0,1,2],"dir":[0,0,-1]}"#),
            Ok(Command::Grab(Vec3::new(0.0, 1.0, 2.0), Vec3::NEG_Z))
        );
        for bad in [
            "",
            "not json",
            r#"{"cmd":"explode"}"#,
            r#"{"cmd":"play","extra":1}"#,
            r#"{"cmd":"cut_mode","mode":"shred"}"#,
            r#"{"cmd":"grab","eye":[0,1],"dir":[0,0,-1]}"#,
            r#"{"cmd":"grab","eye":[0,1,2],"dir":[0,0,1e39]}"#,
            r#"{"cmd":"stroke","eye":[0,1,2],"from":[0,0,-1],"to":"x"}"#,
            r#"{"cmd":"scene"}"#,
        ] {
            assert!(parse(bad).is_err(), "{bad}");
        }
        let huge = format!(
            r#"{{"cmd":"scene","name":"{}"}}"#,
            "a".repeat(MAX_MESSAGE_BYTES)
        );
        assert!(parse(&huge).unwrap_err().contains("bytes"));
    }
}
