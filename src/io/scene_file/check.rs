//! Checked readers for the scene-file schema (`deserialize_with`): each one rejects an
//! out-of-range value with a message that states the allowed range, and the RON reader
//! adds the file position and the field path. A reader checks by the declaration the
//! API's check reads (an [`crate::error::allowed::Allowed`], a [`VecBound`]) or by
//! calling the type's own check (`validate`), so that the file and the API refuse the
//! same values with the same text.

use super::{BodyFile, ColliderShapeFile};
use crate::config::{GroundPlane, StaticBox, ranges};
use crate::cut::tool::{Path, Pose, ToolShape};
use crate::deform::keys::{HandleKey, HandlePath};
use crate::ecs::desc::{PinRegion, Region};
use crate::error::allowed::{CheckedField, read_vec_where, refusal, whole_number};
use crate::error::{CleaveError, SIZE, SIZE_OR_ZERO, VecBound};
use glam::{Quat, UVec3, Vec3};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};

/// The reader's error for what a type's own check refused, in the check's words. The
/// check was given an empty field, so the part of the value it names (`.radius`,
/// `[2].time`) continues the file's field path (see `spanned`).
fn refused<E: serde::de::Error>(e: CleaveError) -> E {
    match e {
        CleaveError::OutOfRange {
            field,
            value,
            allowed,
        } => {
            let within = if field.is_empty() {
                String::new()
            } else {
                format!("{field}: ")
            };
            refusal(format_args!("{within}{value}"), allowed)
        }
        other => E::custom(other),
    }
}
/// A size ([`SIZE`]).
pub fn size<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &SIZE)
}
/// A size that may be 0 ([`SIZE_OR_ZERO`]).
pub fn size_or_zero<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &SIZE_OR_ZERO)
}
/// A size on every axis.
pub fn sizes<'de, D: Deserializer<'de>>(d: D) -> Result<Vec3, D::Error> {
    Vec3::read(d, &SIZE)
}
pub fn dt<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::DT)
}
pub fn damping<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::DAMPING)
}
/// A vector within `bound`.
fn bounded<'de, D: Deserializer<'de>>(d: D, bound: &VecBound) -> Result<Vec3, D::Error> {
    read_vec_where(d, |v| bound.allows(v), || bound.text())
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
    f32::read(d, &ranges::ATTACHMENT_COMPLIANCE)
}
pub fn region<'de, D: Deserializer<'de>>(d: D) -> Result<Region, D::Error> {
    let r = Region::deserialize(d)?;
    r.validate("").map_err(refused)?;
    Ok(r)
}
pub fn rotation<'de, D: Deserializer<'de>>(d: D) -> Result<Quat, D::Error> {
    let q = Quat::deserialize(d)?;
    as_read(q).ok_or_else(|| refused(crate::error::out_of_range("", q, crate::error::ROTATION)))
}
/// A rotation a check has passed, as the scene holds it ([`as_read`]).
fn kept(q: Quat) -> Quat {
    as_read(q).unwrap_or(q)
}
/// A rotation as the scene holds it: a unit quaternion kept bit-exact (so that a file
/// round-trips), any other normalised; `None` if it is no rotation (not finite, or 0).
fn as_read(q: Quat) -> Option<Quat> {
    let unit = crate::math::rotation::unit_quaternion(q)?;
    Some(if (q.length() - 1.0).abs() < 1e-5 {
        q
    } else {
        unit
    })
}
pub fn memory_budget_gb<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::MEMORY_BUDGET_GB)
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
    u32::read(d, &crate::geometry::mesh_sdf::RESOLUTION)
}
pub fn substeps<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    u32::read(d, &ranges::SUBSTEPS)
}
pub fn iterations<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    u32::read(d, &ranges::ITERATIONS)
}
pub fn frames<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    u32::read(d, &crate::ecs::desc::FRAMES)
}
pub fn cells<'de, D: Deserializer<'de>>(d: D) -> Result<UVec3, D::Error> {
    let v = UVec3::deserialize(d)?;
    crate::error::CELLS
        .check_each("", v.as_vec3())
        .map_err(refused)?;
    Ok(v)
}
pub fn ground<'de, D: Deserializer<'de>>(d: D) -> Result<Option<GroundPlane>, D::Error> {
    let ground = Option::<GroundPlane>::deserialize(d)?;
    if let Some(g) = &ground {
        g.validate("").map_err(refused)?;
    }
    Ok(ground)
}
pub fn boxes<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<StaticBox>, D::Error> {
    let boxes = Vec::<StaticBox>::deserialize(d)?;
    for (i, b) in boxes.iter().enumerate() {
        b.validate(&format!("[{i}]")).map_err(refused)?;
    }
    Ok(boxes)
}
pub fn pins<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<PinRegion>, D::Error> {
    let pins = Vec::<PinRegion>::deserialize(d)?;
    for (i, p) in pins.iter().enumerate() {
        p.validate(&format!("[{i}]")).map_err(refused)?;
    }
    Ok(pins)
}
/// A collider's shape, checked by [`crate::geometry::collider::ColliderShape::validate`]
/// (a mesh's file is read, and its shape checked, when the scene is built).
pub fn collider_shape<'de, D: Deserializer<'de>>(d: D) -> Result<ColliderShapeFile, D::Error> {
    let shape = ColliderShapeFile::deserialize(d)?;
    if let Some(primitive) = shape.primitive() {
        primitive.validate("").map_err(refused)?;
    }
    Ok(shape)
}
pub fn tool_shape<'de, D: Deserializer<'de>>(d: D) -> Result<ToolShape, D::Error> {
    let shape = ToolShape::deserialize(d)?;
    shape.validate("").map_err(refused)?;
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
/// A path's keys, checked by [`Path::validate_keys`].
pub fn keys<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(f32, Pose)>, D::Error> {
    let path = Path {
        keys: Vec::deserialize(d)?,
    };
    path.validate_keys("").map_err(refused)?;
    Ok(path
        .keys
        .into_iter()
        .map(|(t, p)| {
            (
                t,
                Pose {
                    rotation: kept(p.rotation),
                    ..p
                },
            )
        })
        .collect())
}
/// A pose, checked by [`crate::ecs::spawn::checked_pose`].
pub fn pose<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Pose>, D::Error> {
    let pose = Option::<Pose>::deserialize(d)?;
    if let Some(p) = pose {
        crate::ecs::spawn::checked_pose("", p).map_err(refused)?;
    }
    Ok(pose.map(|p| Pose {
        rotation: kept(p.rotation),
        ..p
    }))
}
/// A handle's keys, checked by [`HandlePath::validate_keys`] (whether a point handle's
/// keys turn is checked when the scene is built: the reader of the keys does not see
/// the handle's `point`).
pub fn handle_keys<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(f32, HandleKey)>, D::Error> {
    let keys = Vec::<(f32, HandleKey)>::deserialize(d)?;
    // (checked on a copy: the check normalises every rotation its own way)
    let mut path = HandlePath { keys: keys.clone() };
    path.validate_keys("", false).map_err(refused)?;
    Ok(keys
        .into_iter()
        .map(|(t, k)| {
            let rotation = kept(k.rotation);
            (t, HandleKey { rotation, ..k })
        })
        .collect())
}
pub fn friction<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    f32::read(d, &ranges::FRICTION)
}
