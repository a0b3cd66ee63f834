//! Simulation settings, with validation of every field; a body's material is [`Material`].

use crate::error::{Result, check_vec_within, out_of_range};
use glam::Vec3;
use serde::{Deserialize, Serialize};

mod material;
pub mod ranges;
mod relax;
pub use material::{Material, Model, Yield};
pub use relax::RelaxOptions;

/// Which scheme solves each substep's constraints. All three solve the same problem —
/// one implicit Euler step of the clusters' elastic energy (see [`Material::compliance`])
/// with the other constraint kinds projected after each iteration — and differ in how
/// fast they converge. In files, on the command line and in JSON they are spelled
/// `"jacobi"`, `"gauss-seidel"` and `"projective"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SolverMode {
    /// Every cluster computes its goals from the same positions; each particle moves to
    /// the mass-weighted average of its clusters' goals and its inertial prediction.
    /// Parallel and deterministic.
    #[default]
    Jacobi,
    /// Clusters are coloured so that clusters of one colour share no particle; colour
    /// after colour, each cluster moves its members toward its goals (XPBD, with each
    /// membership's accumulated correction). Converges in fewer iterations; parallel
    /// inside a colour and deterministic.
    GaussSeidel,
    /// Projective dynamics (Bouaziz et al. 2014): the clusters' rotation fits are the
    /// local step; the global step solves the whole body's linear system with a sparse
    /// Cholesky factor, computed once per topology. Converges across the whole body in
    /// each iteration.
    Projective,
}

crate::util::named_enum::named_enum!(SolverMode, "solver", [
    Jacobi => "jacobi",
    GaussSeidel => "gauss-seidel",
    Projective => "projective",
]);

/// A horizontal ground plane `y = height` with Coulomb friction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundPlane {
    /// Height of the plane.
    pub height: f32,
    /// Friction coefficient (≥ 0); tangential motion below `friction × penetration` is cancelled.
    pub friction: f32,
}

/// A static axis-aligned box that particles cannot enter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StaticBox {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
    /// Friction coefficient (≥ 0).
    pub friction: f32,
}

/// Global simulation settings (a resource).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    /// Frame time step in seconds.
    pub dt: f32,
    /// Substeps per frame: each runs predict and shape-match with `dt / substeps`.
    pub substeps: u32,
    /// Shape-matching iterations per substep.
    pub iterations: u32,
    /// Gravity acceleration.
    pub gravity: Vec3,
    /// Velocity damping per second, in [0, 1000]: `v *= exp(-damping·dt)`.
    pub damping: f32,
    /// Optional ground plane.
    pub ground: Option<GroundPlane>,
    /// Static box colliders.
    pub boxes: Vec<StaticBox>,
    /// Solver scheme.
    pub solver: SolverMode,
    /// Whether particles collide with each other (see [`Material::contact_radius`]).
    pub contacts: bool,
    /// Conservative culling (SPEC §6.2): contact pairs are kept across substeps while no
    /// particle has moved half a skin, and tool detection skips blocks of particles the
    /// tool cannot have reached since the last test. Exact: a run is bit for bit the same
    /// with culling on and off; off only for checking that.
    pub culling: bool,
    /// Relax every body of a scene before its first frame
    /// ([`crate::sim::simulation::Simulation::from_scene`]; see [`crate::sim::relax`]); `None` (the
    /// default): the bodies start as spawned.
    pub relax: Option<RelaxOptions>,
    /// Seed for every random choice (clustering offsets, merges, splits, expansion).
    pub seed: u64,
    /// Run `check_invariants` after every frame and panic on a violation (tests, debugging).
    pub check_invariants_every_frame: bool,
    /// Memory one body may take, in GB (0.001–1024): a body whose lattice could hold
    /// more particles than this allows, at [`crate::body::shape::BYTES_PER_PARTICLE`] each, is
    /// refused before anything is allocated.
    pub memory_budget_gb: f32,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            dt: 1.0 / 60.0,
            substeps: 2,
            iterations: 10,
            gravity: Vec3::new(0.0, -9.81, 0.0),
            damping: 1.0,
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.5,
            }),
            boxes: Vec::new(),
            solver: SolverMode::Jacobi,
            contacts: true,
            culling: true,
            relax: None,
            seed: 0,
            check_invariants_every_frame: false,
            memory_budget_gb: crate::body::shape::DEFAULT_MEMORY_BUDGET_GB,
        }
    }
}

impl SimConfig {
    /// [`SimConfig::memory_budget_gb`] in bytes.
    pub fn memory_budget_bytes(&self) -> u64 {
        (self.memory_budget_gb as f64 * 1e9) as u64
    }

    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        for (allowed, value) in [
            (ranges::DT, self.dt),
            (ranges::MEMORY_BUDGET_GB, self.memory_budget_gb),
            (ranges::DAMPING, self.damping),
        ] {
            allowed.check(&format!("config.{}", allowed.field), value)?;
        }
        for (allowed, value) in [
            (ranges::SUBSTEPS, self.substeps),
            (ranges::ITERATIONS, self.iterations),
        ] {
            allowed.check(&format!("config.{}", allowed.field), value)?;
        }
        check_vec_within("config.gravity", self.gravity, &crate::error::GRAVITY)?;
        if let Some(relax) = &self.relax {
            relax.validate()?;
        }
        if let Some(g) = &self.ground {
            g.validate("config.ground")?;
        }
        for (i, b) in self.boxes.iter().enumerate() {
            b.validate(&format!("config.boxes[{i}]"))?;
        }
        Ok(())
    }
}

impl GroundPlane {
    /// Checks the height and the friction; errors name `{field}.height` and so on.
    pub fn validate(&self, field: &str) -> Result<()> {
        ranges::GROUND_HEIGHT.check(&format!("{field}.height"), self.height)?;
        ranges::FRICTION.check(&format!("{field}.friction"), self.friction)
    }
}

impl StaticBox {
    /// Checks the corners (positions, `min ≤ max`) and the friction; errors name
    /// `{field}.min` and so on.
    pub fn validate(&self, field: &str) -> Result<()> {
        for (corner, v) in [("min", self.min), ("max", self.max)] {
            check_vec_within(&format!("{field}.{corner}"), v, &crate::error::POSITION)?;
        }
        if !self.min.cmple(self.max).all() {
            return Err(out_of_range(
                field,
                (self.min, self.max),
                "min ≤ max on every axis",
            ));
        }
        ranges::FRICTION.check(&format!("{field}.friction"), self.friction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        SimConfig::default().validate().unwrap();
    }

    #[test]
    fn solver_names_round_trip_and_unknown_names_list_the_choices() {
        for mode in SolverMode::ALL {
            assert_eq!(mode.name().parse::<SolverMode>(), Ok(mode));
            let json = serde_json::to_string(&mode).unwrap();
            assert_eq!(json, format!("\"{}\"", mode.name()));
            assert_eq!(serde_json::from_str::<SolverMode>(&json).unwrap(), mode);
            let ron = ron::to_string(&mode).unwrap();
            assert_eq!(ron::from_str::<SolverMode>(&ron).unwrap(), mode);
        }
        let e = ron::from_str::<SolverMode>("GaussSeidel")
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"gauss-seidel\""), "{e}");
        let e = "gauss_seidel".parse::<SolverMode>().unwrap_err();
        assert!(e.contains("\"gauss-seidel\""), "{e}");
    }

    #[test]
    fn bad_fields_are_named() {
        let c = SimConfig {
            gravity: Vec3::new(0.0, f32::NAN, 0.0),
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("config.gravity")
        );
        let c = SimConfig {
            substeps: 0,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("config.substeps")
        );
        let c = SimConfig {
            iterations: 0,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("config.iterations")
        );
    }
}
