//! The command line's own value parsers: each refuses what is out of range with the
//! range allowed (clap names the flag), so that a bad number reads the same on every
//! flag.

/// A viewer token: 8 to 128 letters, digits, `-` or `_` (it goes into a URL as is).
#[cfg(feature = "viewer")]
pub fn token(text: &str) -> Result<String, String> {
    let fits = (8..=128).contains(&text.len())
        && text
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    match fits {
        true => Ok(text.to_string()),
        false => Err("allowed: 8 to 128 letters, digits, `-` or `_`".into()),
    }
}

/// A wall-clock budget in seconds: above 0, at most a day.
pub fn budget_seconds(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(s) if s > 0.0 && s <= 86_400.0 => Ok(s),
        _ => Err(format!(
            "{text} is out of range (allowed: seconds, 0 < budget ≤ 86400)"
        )),
    }
}

/// A count of frames: a whole number no larger than a scene file's `frames` may be.
pub fn frame_count(text: &str) -> Result<u32, String> {
    use cleave::ecs::desc::FRAMES;
    match whole::<u32>(text) {
        Ok(n) if FRAMES.allows(n as f64) => Ok(n),
        _ => Err(format!(
            "{text} is out of range (allowed: {})",
            FRAMES.text()
        )),
    }
}

/// A whole number of type `T` from a flag's text; refuses a fraction, a negative number
/// or one too large with the range allowed (clap names the flag).
pub fn whole<T: TryFrom<u64>>(text: &str) -> Result<T, String> {
    let range = || {
        let max = (0..=u64::MAX.count_ones())
            .rev()
            .map(|bits| u64::MAX >> (64 - bits.max(1)))
            .find(|m| T::try_from(*m).is_ok())
            .unwrap_or(0);
        format!("allowed: a whole number, 0 to {max}")
    };
    let value: u64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{text} is out of range ({})", range()))?;
    T::try_from(value).map_err(|_| format!("{text} is out of range ({})", range()))
}
