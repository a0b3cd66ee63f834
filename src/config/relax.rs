//! How relaxation settles a body into its rest shape ([`crate::sim::relax`]), with
//! validation of every field.

use crate::error::{Result, check_range, out_of_range};
use serde::{Deserialize, Serialize};

/// Options of [`crate::sim::simulation::Simulation::relax`] (scene files: `settings.relax`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RelaxOptions {
    /// The body is relaxed once its particles' rms speed is below this many lattice
    /// spacings per second (> 0; default 1e-3): its kinetic energy is then below
    /// `½ M (tolerance · h)²`, M its mass.
    pub tolerance: f32,
    /// Most frames to relax for (1–1,000,000; default 3000); the report says whether
    /// the tolerance was met.
    pub max_frames: u32,
    /// Mass-proportional damping while relaxing, per second (0–1000; default 10): each
    /// particle's velocity decays as `exp(−damping · t)`.
    pub damping: f32,
    /// Hold the centroid of every boundary set (the surface in blocks of
    /// `boundary_cells³` cells) hard where it starts (default true).
    pub centroids: bool,
    /// Hold the surface patches (default true), with the material's patch compliances,
    /// or its compliance when it sets none (see
    /// [`crate::config::Material::patch_normal_compliance`]); false: no patches while
    /// relaxing, not even the material's own.
    pub patches: bool,
    /// Side of the boundary sets' blocks, in lattice cells (1–1024; default 4).
    pub boundary_cells: u32,
}

impl Default for RelaxOptions {
    fn default() -> Self {
        Self {
            tolerance: 0.02,
            max_frames: 3000,
            damping: 10.0,
            centroids: true,
            patches: true,
            boundary_cells: 6,
        }
    }
}

impl RelaxOptions {
    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        if !(self.tolerance > 0.0 && self.tolerance <= 1e6) {
            return Err(out_of_range(
                "relax.tolerance",
                self.tolerance,
                "0 < tolerance ≤ 1e6 (lattice spacings per second)",
            ));
        }
        if !(1..=1_000_000).contains(&self.max_frames) {
            return Err(out_of_range(
                "relax.max_frames",
                self.max_frames,
                "1 ≤ max_frames ≤ 1000000",
            ));
        }
        check_range(
            "relax.damping",
            self.damping,
            0.0,
            1000.0,
            "0 ≤ damping ≤ 1000 (per second)",
        )?;
        if !(1..=1024).contains(&self.boundary_cells) {
            return Err(out_of_range(
                "relax.boundary_cells",
                self.boundary_cells,
                "1 ≤ boundary_cells ≤ 1024",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_fields_are_named() {
        RelaxOptions::default().validate().unwrap();
        for (options, field) in [
            (
                RelaxOptions {
                    tolerance: 0.0,
                    ..Default::default()
                },
                "relax.tolerance",
            ),
            (
                RelaxOptions {
                    tolerance: f32::NAN,
                    ..Default::default()
                },
                "relax.tolerance",
            ),
            (
                RelaxOptions {
                    max_frames: 0,
                    ..Default::default()
                },
                "relax.max_frames",
            ),
            (
                RelaxOptions {
                    damping: -1.0,
                    ..Default::default()
                },
                "relax.damping",
            ),
            (
                RelaxOptions {
                    boundary_cells: 0,
                    ..Default::default()
                },
                "relax.boundary_cells",
            ),
        ] {
            let e = options.validate().unwrap_err().to_string();
            assert!(e.contains(field) && e.contains("allowed"), "{e}");
        }
    }
}
