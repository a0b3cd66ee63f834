//! Keyframed handle targets: where a handle goes over time, as a scene file gives it.
//! A key places a handle's rest centroid at `position`, turned by `rotation` and
//! scaled by `scale` about it (a region handle's affine map); a point handle's key is
//! its particle's position (its rotation and scale must be the identity).

use super::handles::{Handle, HandleTarget};
use crate::error::{CleaveError, Result, SCALE, check_vec_within};
use glam::{Affine3A, Quat, Vec3};

/// One key of a handle's path. A scene file writes it `(position: …, rotation: …,
/// scale: …)`, the rotation and the scale optional.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandleKey {
    /// Where the handle's rest centroid (a point handle's particle) goes.
    pub position: Vec3,
    /// The rotation about it.
    #[serde(default)]
    pub rotation: Quat,
    /// The scale along the body's axes about it, before the rotation.
    #[serde(default = "unit_scale")]
    pub scale: Vec3,
}

fn unit_scale() -> Vec3 {
    Vec3::ONE
}

impl HandleKey {
    /// The key that puts the centroid at `position`, unturned and unscaled.
    pub fn at(position: Vec3) -> Self {
        Self {
            position,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
        }
    }

    /// The affine map this key gives a region resting with its centroid at `centroid`.
    pub fn map(&self, centroid: Vec3) -> Affine3A {
        Affine3A::from_scale_rotation_translation(self.scale, self.rotation, self.position)
            * Affine3A::from_translation(-centroid)
    }

    /// Whether the key turns or scales.
    pub fn is_rigid_translation(&self) -> bool {
        self.rotation == Quat::IDENTITY && self.scale == Vec3::ONE
    }
}

/// A handle's keyframes `(time in seconds, key)`, times strictly ascending; before the
/// first key the handle is at the first, after the last at the last.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HandlePath {
    /// The keys.
    pub keys: Vec<(f32, HandleKey)>,
}

impl HandlePath {
    /// Checks the keys: times finite and strictly ascending, positions within the
    /// world, rotations finite and non-zero (they are normalised), scales within
    /// [`SCALE`] on every axis; a point handle's keys neither turn nor scale. Errors name
    /// `{owner}.path[i]`.
    pub fn validate(&mut self, owner: &str, point: bool) -> Result<()> {
        self.validate_keys(&format!("{owner}.path"), point)
    }

    /// [`HandlePath::validate`], the errors naming the key as `{field}[i]` (a scene
    /// file's reader gives an empty `field`).
    pub fn validate_keys(&mut self, field: &str, point: bool) -> Result<()> {
        let path = field;
        let mut last = f32::NEG_INFINITY;
        for (i, (t, key)) in self.keys.iter_mut().enumerate() {
            let field = |what: &str| format!("{path}[{i}].{what}");
            let bad = |what: &str, value: String, allowed: &'static str| {
                Err(CleaveError::OutOfRange {
                    field: field(what),
                    value,
                    allowed: allowed.into(),
                })
            };
            if !(t.is_finite() && *t > last) {
                return bad("time", t.to_string(), "finite, after the previous key's");
            }
            last = *t;
            check_vec_within(&field("position"), key.position, &crate::error::POSITION)?;
            let length = key.rotation.length();
            if !(length.is_finite() && length > 0.0) {
                return bad(
                    "rotation",
                    format!("{:?}", key.rotation),
                    crate::error::ROTATION,
                );
            }
            key.rotation /= length;
            SCALE.check_each(&field("scale"), key.scale)?;
            if point && !key.is_rigid_translation() {
                return bad(
                    "rotation",
                    format!("{:?} (scale {})", key.rotation, key.scale),
                    "a point handle's keys neither turn nor scale",
                );
            }
        }
        Ok(())
    }

    /// The key at time `t`: positions and scales interpolated linearly, rotations by
    /// slerp; `None` for an empty path.
    pub fn sample(&self, t: f32) -> Option<HandleKey> {
        crate::util::keyframes::sample(&self.keys, t, |a, b, s| HandleKey {
            position: a.position.lerp(b.position, s),
            rotation: a.rotation.slerp(b.rotation, s),
            scale: a.scale.lerp(b.scale, s),
        })
    }

    /// The target of `handle` (resting with its centroid at `centroid`) at time `t`;
    /// an empty path leaves it at rest.
    pub fn target(&self, handle: &Handle, centroid: Vec3, t: f32) -> HandleTarget {
        let key = self.sample(t).unwrap_or(HandleKey::at(centroid));
        match handle {
            Handle::Point(_) => HandleTarget::Point(key.position),
            Handle::Region(_) => HandleTarget::Affine(key.map(centroid)),
        }
    }
}
