//! The bounds of the values a user gives, declared once: the vector bounds (positions,
//! velocities, gravity) and the sizes of shapes and tools, read by the API's checks and
//! by the scene file's readers alike.

use super::allowed::Allowed;
use super::cleave_error::{Result, check_finite_vec, out_of_range};

/// Largest coordinate (metres) of any position a user gives: far beyond any scene, and
/// far below where single precision loses the lattice spacing.
pub const MAX_COORDINATE: f32 = 1e6;

/// Largest speed (m/s) a body, a pin or a keyframed path may be given: each component of
/// a velocity, and a path's mean speed between two keys.
pub const MAX_SPEED: f32 = 1e4;

/// The bound of a vector field, declared once: every component finite and within
/// `±max`. The API's checks ([`check_vec_within`]) and the scene file's reader state it
/// with the same text.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VecBound {
    /// How the text names the components, e.g. `|vx|, |vy|, |vz|`.
    pub components: &'static str,
    /// The largest magnitude of a component.
    pub max: f32,
    /// The unit.
    pub unit: &'static str,
}

impl VecBound {
    /// Whether `v` is within the bound.
    pub fn allows(&self, v: glam::Vec3) -> bool {
        v.is_finite() && v.abs().max_element() <= self.max
    }

    /// The bound as errors state it, e.g. `|x|, |y|, |z| ≤ 1e6 (metres)`.
    pub fn text(&self) -> String {
        format!("{} ≤ {:e} ({})", self.components, self.max, self.unit)
    }
}

/// A position anywhere in a scene.
pub const POSITION: VecBound = VecBound {
    components: "|x|, |y|, |z|",
    max: MAX_COORDINATE,
    unit: "metres",
};
/// A velocity.
pub const VELOCITY: VecBound = VecBound {
    components: "|vx|, |vy|, |vz|",
    max: MAX_SPEED,
    unit: "m/s",
};
/// An angular velocity.
pub const ANGULAR_VELOCITY: VecBound = VecBound {
    components: "|ωx|, |ωy|, |ωz|",
    max: MAX_SPEED,
    unit: "rad/s",
};
/// Gravity.
pub const GRAVITY: VecBound = VecBound {
    components: "|gx|, |gy|, |gz|",
    max: 1e4,
    unit: "m/s²",
};

/// Checks `value` of the field at `field` against `bound`.
pub fn check_vec_within(field: &str, value: glam::Vec3, bound: &VecBound) -> Result<()> {
    if bound.allows(value) {
        Ok(())
    } else {
        Err(out_of_range(field, value, bound.text()))
    }
}

/// A size a user gives (a radius, a half extent, a tool's width): finite, above 0 and at
/// most [`MAX_COORDINATE`], as every position is.
pub const SIZE: Allowed = Allowed::above("size", 0.0, MAX_COORDINATE as f64, "metres");
/// A size that may be 0 (a capsule's shaft).
pub const SIZE_OR_ZERO: Allowed = Allowed::closed("size", 0.0, MAX_COORDINATE as f64, "metres");
/// The particles along each axis of a block given in lattice cells.
pub const CELLS: Allowed = Allowed::count("cells", 1, 1_000_000);
/// A handle key's scale along each axis. A scale moves particles by itself times their
/// distance from the centroid: past a thousandfold they leave any scene, and no finite
/// body survives it.
pub const SCALE: Allowed = Allowed::closed("scale", 1e-3, 1e3, "");
/// A rotation's bound, as every check states it (the quaternion is normalised).
pub const ROTATION: &str = "a finite, non-zero quaternion (x, y, z, w)";

/// Checks that the corners `min`, `max` of the region at `field` are finite.
pub fn check_corners(field: &str, min: glam::Vec3, max: glam::Vec3) -> Result<()> {
    check_finite_vec(&format!("{field}.min"), min)?;
    check_finite_vec(&format!("{field}.max"), max)
}
