//! Checked readers for the scene-file schema (`deserialize_with`): each one rejects an
//! out-of-range value with a message that states the allowed range, and the RON reader
//! adds the file position and the field path.

use super::{BodyFile, ColliderShapeFile, PoseFile};
use crate::config::allowed::{CheckedField, whole_number};
use crate::config::{GroundPlane, StaticBox, ranges};
use crate::cut::tool::ToolShape;
use crate::ecs::desc::{PinRegion, Region};
use crate::error::VecBound;
use glam::{Quat, UVec3, Vec3};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

fn range<'de, D: Deserializer<'de>>(v: f32, ok: bool, allowed: &str) -> Result<f32, D::Error> {
    if ok && v.is_finite() {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "{v} is out of range (allowed: {allowed})"
        )))
    }
}
pub fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    let v = f32::deserialize(d)?;
    range::<D>(v, v > 0.0, "> 0")
}
pub fn finite<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    let v = f32::deserialize(d)?;
    range::<D>(v, true, "a finite number")
}
pub fn dt<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::DT)
}
pub fn damping<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::DAMPING)
}
pub fn vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    let v = Vec3::deserialize(d)?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "{v} is out of range (allowed: finite x, y, z)"
        )))
    }
}
/// A vector within `bound`.
fn bounded<'de, D: Deserializer<'de>>(d: D, bound: &VecBound) -> Result<Vec3, D::Error> {
    let v = Vec3::deserialize(d)?;
    if bound.allows(v) {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "{v} is out of range (allowed: {})",
            bound.text()
        )))
    }
}
pub fn coordinates<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    bounded(d, &crate::error::POSITION)
}
pub fn velocity<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    bounded(d, &crate::error::VELOCITY)
}
pub fn angular_velocity<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    bounded(d, &crate::error::ANGULAR_VELOCITY)
}
pub fn gravity<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    bounded(d, &crate::error::GRAVITY)
}
pub fn spacing<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::SPACING)
}
/// A material compliance (a region's, a group's).
pub fn compliance<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::COMPLIANCE)
}
pub fn relax<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<crate::config::RelaxOptions>, D::Error> {
    let v = Option::<crate::config::RelaxOptions>::deserialize(d)?;
    if let Some(options) = &v {
        options.validate().map_err(D::Error::custom)?;
    }
    Ok(v)
}
pub fn jitter<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::JITTER)
}
pub fn attachment_compliance<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    let v = f32::deserialize(d)?;
    range::<D>(v, v >= 0.0, "finite and ≥ 0 (m/N; 0: hard)")
}
pub fn region<'de, D: Deserializer<'de>>(d: D) -> Result<Region, D::Error> {
    let r = Region::deserialize(d)?;
    if !(r.min.is_finite() && r.max.is_finite()) {
        return Err(D::Error::custom(format!(
            "({}, {}) is out of range (allowed: finite corners)",
            r.min, r.max
        )));
    }
    Ok(r)
}
pub fn rotation<'de, D: Deserializer<'de>>(d: D) -> Result<Quat, D::Error> {
    let q = Quat::deserialize(d)?;
    match crate::math::rotation::unit_quaternion(q) {
        // keep unit quaternions bit-exact (files round-trip); normalise the rest
        Some(unit) => Ok(if (q.length() - 1.0).abs() < 1e-5 {
            q
        } else {
            unit
        }),
        None => Err(D::Error::custom(format!(
            "({}, {}, {}, {}) is out of range (allowed: a finite, non-zero quaternion (x, y, z, w))",
            q.x, q.y, q.z, q.w
        ))),
    }
}
pub fn memory_budget_gb<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::MEMORY_BUDGET_GB)
}
/// A whole number within `lo..=hi` (errors name `name` and the range).
fn count<'de, D: Deserializer<'de>>(d: D, lo: u32, hi: u32, name: &str) -> Result<u32, D::Error> {
    whole(d, lo as u64, hi as u64, name).map(|v| v as u32)
}

/// A whole number within `lo..=hi`, read from any number the file holds, so that a
/// fraction, a negative number or one out of range is refused with the field's range
/// rather than a parser's complaint.
fn whole<'de, D: Deserializer<'de>>(d: D, lo: u64, hi: u64, name: &str) -> Result<u64, D::Error> {
    let range = format!("allowed: a whole number, {lo} ≤ {name} ≤ {hi}");
    match whole_number(d)? {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v),
        Ok(v) => Err(D::Error::custom(format!("{v} is out of range ({range})"))),
        Err(v) => Err(D::Error::custom(format!("{v} is out of range ({range})"))),
    }
}

/// The random seed: any whole number a `u64` holds.
pub fn seed<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    whole(d, 0, u64::MAX, "seed")
}

/// A mesh's sampling resolution.
pub fn mesh_resolution<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    count(d, 4, 256, "resolution")
}
pub fn substeps<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    u32::read(d, &ranges::SUBSTEPS)
}
pub fn iterations<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    u32::read(d, &ranges::ITERATIONS)
}
pub fn frames<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    count(d, 0, crate::ecs::desc::MAX_FRAMES, "frames")
}
pub fn cells<'de, D: Deserializer<'de>>(d: D) -> Result<UVec3, D::Error> {
    let v = UVec3::deserialize(d)?;
    if v.min_element() >= 1 {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "{v} is out of range (allowed: at least 1 cell per axis)"
        )))
    }
}
pub fn ground<'de, D: Deserializer<'de>>(d: D) -> Result<Option<GroundPlane>, D::Error> {
    let ground = Option::<GroundPlane>::deserialize(d)?;
    if let Some(g) = &ground {
        if !ranges::GROUND_HEIGHT.allows(g.height as f64) {
            return Err(ranges::GROUND_HEIGHT.refuse(g.height));
        }
        if !ranges::FRICTION.allows(g.friction as f64) {
            return Err(ranges::FRICTION.refuse(g.friction));
        }
    }
    Ok(ground)
}
pub fn boxes<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<StaticBox>, D::Error> {
    let boxes = Vec::<StaticBox>::deserialize(d)?;
    for (i, b) in boxes.iter().enumerate() {
        if !(b.min.is_finite() && b.max.is_finite() && b.min.cmple(b.max).all()) {
            return Err(D::Error::custom(format!(
                "box {i}: ({}, {}) is out of range (allowed: finite corners, min ≤ max)",
                b.min, b.max
            )));
        }
        if !ranges::FRICTION.allows(b.friction as f64) {
            return Err(ranges::FRICTION.refuse(b.friction));
        }
    }
    Ok(boxes)
}
pub fn pins<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<PinRegion>, D::Error> {
    let pins = Vec::<PinRegion>::deserialize(d)?;
    for (i, p) in pins.iter().enumerate() {
        if !(p.min.is_finite() && p.max.is_finite()) {
            return Err(D::Error::custom(format!(
                "pin {i}: ({}, {}) is out of range (allowed: finite corners)",
                p.min, p.max
            )));
        }
        if p.velocity.is_nan() || p.velocity.abs().max_element() > 1e4 {
            return Err(D::Error::custom(format!(
                "pin {i}: velocity {} is out of range (allowed: |vx|, |vy|, |vz| ≤ 1e4 m/s)",
                p.velocity
            )));
        }
    }
    Ok(pins)
}
pub fn collider_shape<'de, D: Deserializer<'de>>(d: D) -> Result<ColliderShapeFile, D::Error> {
    let shape = ColliderShapeFile::deserialize(d)?;
    let (value, ok, allowed) = match &shape {
        ColliderShapeFile::Box { half_extents: h } => (
            format!("{h}"),
            h.is_finite() && h.cmpgt(Vec3::ZERO).all(),
            "half_extents finite and > 0",
        ),
        ColliderShapeFile::Sphere { radius } => (
            format!("{radius}"),
            radius.is_finite() && *radius > 0.0,
            "radius finite and > 0",
        ),
        ColliderShapeFile::Capsule {
            radius,
            half_length,
        } => (
            format!("({radius}, {half_length})"),
            radius.is_finite() && *radius > 0.0 && half_length.is_finite() && *half_length >= 0.0,
            "radius finite and > 0, half_length finite and ≥ 0",
        ),
        ColliderShapeFile::Mesh { resolution, .. } => (
            format!("{resolution}"),
            (4..=256).contains(resolution),
            "4 ≤ resolution ≤ 256",
        ),
    };
    if ok {
        Ok(shape)
    } else {
        Err(D::Error::custom(format!(
            "{value} is out of range (allowed: {allowed})"
        )))
    }
}
pub fn tool_shape<'de, D: Deserializer<'de>>(d: D) -> Result<ToolShape, D::Error> {
    let shape = ToolShape::deserialize(d)?;
    shape.validate().map_err(D::Error::custom)?;
    Ok(shape)
}
pub fn bodies<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<BodyFile>, D::Error> {
    let v = Vec::<BodyFile>::deserialize(d)?;
    if v.is_empty() {
        Err(D::Error::custom(
            "the body list is empty (allowed: at least one body)",
        ))
    } else {
        Ok(v)
    }
}
pub fn keys<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(f32, PoseFile)>, D::Error> {
    let keys = Vec::<(f32, PoseFile)>::deserialize(d)?;
    for (i, (t, _)) in keys.iter().enumerate() {
        if !t.is_finite() {
            return Err(D::Error::custom(format!(
                "key {i}: time {t} is out of range (allowed: a finite number)"
            )));
        }
        if i > 0 && *t <= keys[i - 1].0 {
            return Err(D::Error::custom(format!(
                "key {i}: time {t} is not after the previous key (allowed: strictly ascending times)"
            )));
        }
    }
    Ok(keys)
}
pub fn handle_keys<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Vec<(f32, super::schema::HandleKeyFile)>, D::Error> {
    let keys = Vec::<(f32, super::schema::HandleKeyFile)>::deserialize(d)?;
    for (i, (t, _)) in keys.iter().enumerate() {
        if !t.is_finite() || (i > 0 && *t <= keys[i - 1].0) {
            return Err(D::Error::custom(format!(
                "key {i}: time {t} is out of range (allowed: finite, strictly ascending times)"
            )));
        }
    }
    Ok(keys)
}
pub fn scale<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    let v = Vec3::deserialize(d)?;
    if v.is_finite() && v.min_element() > 0.0 {
        Ok(v)
    } else {
        Err(D::Error::custom(format!(
            "{v} is out of range (allowed: each component finite and > 0)"
        )))
    }
}
pub fn friction<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::FRICTION)
}
