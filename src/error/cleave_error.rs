//! The error every fallible call returns, and the checks that build it: each names the
//! field or file and the allowed range.

use std::path::PathBuf;

/// Everything that can go wrong when building a simulation from user input.
#[derive(Debug, thiserror::Error)]
pub enum CleaveError {
    /// A numeric parameter is outside its allowed range (or not finite).
    #[error("invalid `{field}`: {value} (allowed: {allowed})")]
    OutOfRange {
        /// Dotted path of the offending field, e.g. `material.compliance`.
        field: String,
        /// The value that was given, formatted.
        value: String,
        /// Human-readable allowed range, e.g. `0 ≤ x ≤ 1`.
        allowed: std::borrow::Cow<'static, str>,
    },
    /// The shape voxelised to zero particles.
    #[error("empty shape: `{field}` produced no particles at spacing {spacing}")]
    EmptyShape {
        /// Which field described the shape.
        field: String,
        /// The lattice spacing that was used.
        spacing: f32,
    },
    /// A mesh file could not be read or is not a closed triangle mesh.
    #[error("mesh `{path}`: {reason}")]
    Mesh {
        /// The file that failed.
        path: PathBuf,
        /// What was wrong with it.
        reason: String,
    },
    /// The lattice would be too large to index.
    #[error("shape too large: `{field}` spans {cells} lattice cells (at most {max})")]
    TooLarge {
        /// Which field described the shape.
        field: String,
        /// Cells of the bounding lattice.
        cells: u64,
        /// Limit.
        max: u64,
    },
    /// A shape would need more memory than the budget allows.
    #[error(
        "shape too large: `{field}` would make up to {particles} particles, about {} GB at ~{bytes_per_particle} B each (the memory budget of {budget_gigabytes} GB allows {max} particles per body)",
        significant(*gigabytes)
    )]
    OverBudget {
        /// Which field described the shape.
        field: String,
        /// Upper bound of its particle count (the lattice cells of its bounding box).
        particles: u64,
        /// Estimated memory, GB.
        gigabytes: f64,
        /// Estimated memory per particle, bytes.
        bytes_per_particle: u64,
        /// The budget, GB.
        budget_gigabytes: f32,
        /// Most particles the budget allows.
        max: u64,
    },
    /// A body's surface would take more memory than the budget leaves beside its
    /// particles.
    #[error(
        "surface too large: the body's surface would have {faces} faces, about {} GB at ~{bytes_per_face} B each, beside about {} GB of particles (the memory budget is {budget_gigabytes} GB per body)",
        significant(*gigabytes),
        significant(*particle_gigabytes)
    )]
    SurfaceOverBudget {
        /// Faces of the body's lattice surface.
        faces: u64,
        /// Estimated memory of the surface, GB.
        gigabytes: f64,
        /// Estimated memory of the body's particles, GB.
        particle_gigabytes: f64,
        /// Estimated memory per face, bytes.
        bytes_per_face: u64,
        /// The budget, GB.
        budget_gigabytes: f32,
    },
    /// The bodies of one world would hold more particles than the solver can address.
    #[error("too many particles: {particles} in the world's bodies together (at most {max})")]
    TooManyParticles {
        /// Particles of the existing bodies and the new one.
        particles: u64,
        /// Limit.
        max: u64,
    },
    /// An entity passed to the API is not what was expected.
    #[error("{0}")]
    InvalidEntity(String),
    /// A saved simulation could not be written or read (see [`crate::io::save`]).
    #[error("saved simulation: {0}")]
    Save(String),
}

impl CleaveError {
    /// `entity` is not `what` (with its article: "a body") of this world: despawned,
    /// something else, or an entity of another world (one from before a load names
    /// nothing after it).
    pub fn not_a(what: impl std::fmt::Display, entity: bevy_ecs::entity::Entity) -> Self {
        CleaveError::InvalidEntity(format!(
            "{entity} is not {what} of this simulation (despawned, or an entity from before a load: map it with Simulation::loaded_entity)"
        ))
    }
}

/// Short alias used across the crate.
pub type Result<T> = std::result::Result<T, CleaveError>;

/// Checks `lo ≤ value ≤ hi` and finiteness; `allowed` is the text shown on failure.
pub fn check_range(field: &str, value: f32, lo: f32, hi: f32, allowed: &'static str) -> Result<()> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(out_of_range(field, value, allowed))
    }
}

/// Checks `value > 0` and finiteness.
pub fn check_positive(field: &str, value: f32) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(out_of_range(field, value, "finite and > 0"))
    }
}

/// Checks that every component of a vector is finite.
pub fn check_finite_vec(field: &str, value: glam::Vec3) -> Result<()> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(out_of_range(field, value, "finite"))
    }
}

/// Builds an [`CleaveError::OutOfRange`] from any debuggable value.
pub fn out_of_range(
    field: &str,
    value: impl std::fmt::Debug,
    allowed: impl Into<std::borrow::Cow<'static, str>>,
) -> CleaveError {
    CleaveError::OutOfRange {
        field: field.to_string(),
        value: format!("{value:?}"),
        allowed: allowed.into(),
    }
}

/// `x` to three significant digits, without trailing zeros (0.0048, 4.9, 38).
fn significant(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return format!("{x}");
    }
    let decimals = (2 - x.log10().floor() as i32).max(0) as usize;
    let text = format!("{x:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_print_to_three_significant_digits() {
        for (x, text) in [
            (0.0048, "0.0048"),
            (4.9452, "4.95"),
            (38.4, "38.4"),
            (1234.6, "1235"),
            (2.0, "2"),
        ] {
            assert_eq!(significant(x), text);
        }
        let e = CleaveError::OverBudget {
            field: "shape".into(),
            particles: 8000,
            gigabytes: 0.0048,
            bytes_per_particle: 600,
            budget_gigabytes: 0.001,
            max: 1666,
        };
        assert!(e.to_string().contains("about 0.0048 GB"), "{e}");
        assert!(e.to_string().contains("memory budget of 0.001 GB"), "{e}");
    }
}
