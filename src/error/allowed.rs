//! A number field's allowed values, declared once: the API's check
//! ([`Allowed::check`]) and the scene file's reader ([`CheckedField`], through serde's
//! `deserialize_with`) read the same declaration, so the two cannot disagree on the
//! range or on how the error states it.

use super::cleave_error::{Result as CheckResult, out_of_range};
use glam::Vec3;
use serde::{Deserialize, Deserializer};

/// The allowed values of one number field (see the module docs): finite, at least (or,
/// with `open_min`, above) `min`, at most `max`, whole when `whole`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Allowed {
    /// The field's name, as files spell it.
    pub field: &'static str,
    /// The least value (or the bound every value is above).
    pub min: f64,
    /// Whether `min` itself is refused.
    pub open_min: bool,
    /// The greatest value.
    pub max: f64,
    /// Whether only whole numbers are allowed.
    pub whole: bool,
    /// What the range's text ends with: the unit, or what a value means (may be empty).
    pub note: &'static str,
}

impl Allowed {
    /// `min ≤ field ≤ max`.
    pub const fn closed(field: &'static str, min: f64, max: f64, note: &'static str) -> Self {
        Allowed {
            field,
            min,
            open_min: false,
            max,
            whole: false,
            note,
        }
    }

    /// `min < field ≤ max`.
    pub const fn above(field: &'static str, min: f64, max: f64, note: &'static str) -> Self {
        Allowed {
            open_min: true,
            ..Self::closed(field, min, max, note)
        }
    }

    /// A whole number, `min ≤ field ≤ max`.
    pub const fn count(field: &'static str, min: u32, max: u32) -> Self {
        Allowed {
            whole: true,
            ..Self::closed(field, min as f64, max as f64, "")
        }
    }

    /// Whether `v` is allowed. The bounds are taken as the `f32` nearest them, as the
    /// fields hold them: a field set to `1e-4` holds the `f32` below the decimal, and is
    /// allowed where the bound is `1e-4`.
    pub fn allows(&self, v: f64) -> bool {
        let (min, max) = (self.min as f32 as f64, self.max as f32 as f64);
        let above = if self.open_min { v > min } else { v >= min };
        v.is_finite() && above && v <= max && (!self.whole || v.fract() == 0.0)
    }

    /// The range as errors state it, e.g. `0 ≤ compliance ≤ 1 (1/Pa)`.
    pub fn text(&self) -> String {
        let below = if self.open_min { "<" } else { "≤" };
        let whole = if self.whole { "a whole number, " } else { "" };
        let note = if self.note.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.note)
        };
        format!(
            "{whole}{} {below} {} ≤ {}{note}",
            number(self.min),
            self.field,
            number(self.max)
        )
    }

    /// Checks `value` of the field at `path` (e.g. `material.compliance`); the error
    /// names the path and states the range.
    pub fn check(
        &self,
        path: &str,
        value: impl Into<f64> + std::fmt::Debug + Copy,
    ) -> CheckResult<()> {
        if self.allows(value.into()) {
            Ok(())
        } else {
            Err(out_of_range(path, value, self.text()))
        }
    }

    /// The file reader's error for `value`.
    pub fn refuse<E: serde::de::Error>(&self, value: impl std::fmt::Display) -> E {
        refusal(value, self.text())
    }

    /// Whether every component of `v` is allowed (a size per axis, a scale).
    pub fn allows_each(&self, v: Vec3) -> bool {
        v.to_array().iter().all(|&c| self.allows(c as f64))
    }

    /// The range of a vector whose every component is checked, e.g. `0 < size ≤ 1e6
    /// (metres) on every axis`.
    pub fn text_each(&self) -> String {
        format!("{} on every axis", self.text())
    }

    /// Checks every component of `value` of the field at `path`.
    pub fn check_each(&self, path: &str, value: Vec3) -> CheckResult<()> {
        if self.allows_each(value) {
            Ok(())
        } else {
            Err(out_of_range(path, value, self.text_each()))
        }
    }
}

/// A file reader's error for a value out of range, as every reader words it: the value
/// as the file writes it, then what is allowed.
pub fn refusal<E: serde::de::Error>(
    value: impl std::fmt::Display,
    allowed: impl std::fmt::Display,
) -> E {
    E::custom(format!("{value} is out of range (allowed: {allowed})"))
}

/// A bound as the range's text writes it: `1e-6`, `0.5`, `1000`, `1e6`.
fn number(v: f64) -> String {
    if v != 0.0 && (v.abs() < 1e-2 || v.abs() >= 1e6) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// A field type a file reader checks against an [`Allowed`] (numbers, and optional
/// numbers whose `None` is always allowed).
pub trait CheckedField: Sized {
    /// Reads the value and checks it; the error states the range.
    fn read<'de, D: Deserializer<'de>>(d: D, allowed: &Allowed) -> Result<Self, D::Error>;
}

impl CheckedField for f32 {
    fn read<'de, D: Deserializer<'de>>(d: D, allowed: &Allowed) -> Result<Self, D::Error> {
        let v = f32::deserialize(d)?;
        if allowed.allows(v as f64) {
            Ok(v)
        } else {
            Err(allowed.refuse(v))
        }
    }
}

impl CheckedField for u32 {
    /// Read from any number the file holds, so that a fraction, a negative number or one
    /// out of range is refused with the field's range rather than a parser's complaint.
    /// (A binary format, which says what it holds only when asked for a type, is read
    /// as a `u32`.)
    fn read<'de, D: Deserializer<'de>>(d: D, allowed: &Allowed) -> Result<Self, D::Error> {
        let v = if d.is_human_readable() {
            whole_number(d)?
        } else {
            Ok(u32::deserialize(d)? as u64)
        };
        match v {
            Ok(v) if allowed.allows(v as f64) => Ok(v as u32),
            Ok(v) => Err(allowed.refuse(v)),
            Err(text) => Err(allowed.refuse(text)),
        }
    }
}

impl CheckedField for Vec3 {
    /// Every component checked.
    fn read<'de, D: Deserializer<'de>>(d: D, allowed: &Allowed) -> Result<Self, D::Error> {
        read_vec_where(d, |v| allowed.allows_each(v), || allowed.text_each())
    }
}

/// Reads a vector, refused (stating the bound `text` gives) unless `allows` takes it:
/// the reader of a vector under any kind of bound.
pub fn read_vec_where<'de, D: Deserializer<'de>>(
    d: D,
    allows: impl FnOnce(Vec3) -> bool,
    text: impl FnOnce() -> String,
) -> Result<Vec3, D::Error> {
    let v = Vec3::deserialize(d)?;
    if allows(v) {
        Ok(v)
    } else {
        Err(refusal(v, text()))
    }
}

impl CheckedField for Option<f32> {
    fn read<'de, D: Deserializer<'de>>(d: D, allowed: &Allowed) -> Result<Self, D::Error> {
        match Option::<f32>::deserialize(d)? {
            Some(v) if !allowed.allows(v as f64) => Err(allowed.refuse(v)),
            v => Ok(v),
        }
    }
}

/// Any number the file holds: a whole one that fits a `u64`, or the text of one that
/// is not.
pub fn whole_number<'de, D: Deserializer<'de>>(d: D) -> Result<Result<u64, String>, D::Error> {
    struct Whole;
    impl serde::de::Visitor<'_> for Whole {
        type Value = Result<u64, String>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a whole number")
        }
        fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Self::Value, E> {
            Ok(Ok(v))
        }
        fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Self::Value, E> {
            Ok(u64::try_from(v).map_err(|_| v.to_string()))
        }
        fn visit_u128<E: serde::de::Error>(self, v: u128) -> Result<Self::Value, E> {
            Ok(u64::try_from(v).map_err(|_| v.to_string()))
        }
        fn visit_i128<E: serde::de::Error>(self, v: i128) -> Result<Self::Value, E> {
            Ok(u64::try_from(v).map_err(|_| v.to_string()))
        }
        fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Self::Value, E> {
            Ok(Err(v.to_string()))
        }
    }
    d.deserialize_any(Whole)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_text_states_the_declared_range() {
        let c = Allowed::closed("compliance", 0.0, 1.0, "1/Pa");
        assert_eq!(c.text(), "0 ≤ compliance ≤ 1 (1/Pa)");
        let d = Allowed::closed("density", 1e-3, 1e6, "kg/m³");
        assert_eq!(d.text(), "1e-3 ≤ density ≤ 1e6 (kg/m³)");
        let t = Allowed::above("tear_stretch", 1.0, 1000.0, "");
        assert_eq!(t.text(), "1 < tear_stretch ≤ 1000");
        let n = Allowed::count("max_cluster_size", 2, 100_000);
        assert_eq!(n.text(), "a whole number, 2 ≤ max_cluster_size ≤ 100000");
        assert!(c.allows(0.0) && c.allows(1.0) && !c.allows(1.5) && !c.allows(f64::NAN));
        assert!(!t.allows(1.0) && t.allows(1.5));
        assert!(n.allows(2.0) && !n.allows(2.5) && !n.allows(1.0));
        // a bound met by a field set to it: the f32 nearest 1e-4 lies below 1e-4
        let s = Allowed::closed("spacing", 1e-4, 100.0, "metres");
        assert!(s.allows(1e-4f32 as f64) && !s.allows(0.99e-4f32 as f64));
        let e = c
            .check("material.compliance", 2.0f32)
            .expect_err("out of range");
        assert_eq!(
            e.to_string(),
            "invalid `material.compliance`: 2.0 (allowed: 0 ≤ compliance ≤ 1 (1/Pa))"
        );
    }
}
