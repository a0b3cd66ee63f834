//! Simulation and material parameters, with validation of every field.

use crate::error::{MAX_COORDINATE, Result, check_range, check_vec_within, out_of_range};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Which iteration scheme the shape-matching solver uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SolverMode {
    /// Every cluster computes its goals from the same positions; each particle moves to
    /// the (mass-weighted) average of its clusters' goals. Parallel and deterministic.
    #[default]
    Jacobi,
    /// Clusters are coloured so that clusters of one colour share no particle; colour
    /// after colour, each cluster moves its members to its goals at once. Converges in
    /// fewer iterations; parallel inside a colour and deterministic.
    GaussSeidel,
}

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
    /// Seed for every random choice (clustering offsets, merges, splits, expansion).
    pub seed: u64,
    /// Run `check_invariants` after every frame and panic on a violation (tests, debugging).
    pub check_invariants_every_frame: bool,
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
            seed: 0,
            check_invariants_every_frame: false,
        }
    }
}

impl SimConfig {
    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range("config.dt", self.dt, 1e-6, 1.0, "1e-6 ≤ dt ≤ 1 (seconds)")?;
        if self.substeps == 0 || self.substeps > 1000 {
            return Err(out_of_range(
                "config.substeps",
                self.substeps,
                "1 ≤ substeps ≤ 1000",
            ));
        }
        if self.iterations == 0 || self.iterations > 10_000 {
            return Err(out_of_range(
                "config.iterations",
                self.iterations,
                "1 ≤ iterations ≤ 10000",
            ));
        }
        check_vec_within(
            "config.gravity",
            self.gravity,
            1e4,
            "|gx|, |gy|, |gz| ≤ 1e4 (m/s²)",
        )?;
        check_range(
            "config.damping",
            self.damping,
            0.0,
            1000.0,
            "0 ≤ damping ≤ 1000 (per second)",
        )?;
        if let Some(g) = &self.ground {
            check_range(
                "config.ground.height",
                g.height,
                -MAX_COORDINATE,
                MAX_COORDINATE,
                "-1e6 ≤ height ≤ 1e6 (metres)",
            )?;
            check_range(
                "config.ground.friction",
                g.friction,
                0.0,
                100.0,
                "0 ≤ friction ≤ 100",
            )?;
        }
        for (i, b) in self.boxes.iter().enumerate() {
            for (corner, v) in [("min", b.min), ("max", b.max)] {
                check_vec_within(
                    &format!("config.boxes[{i}].{corner}"),
                    v,
                    MAX_COORDINATE,
                    "|x|, |y|, |z| ≤ 1e6 (metres)",
                )?;
            }
            if !b.min.cmple(b.max).all() {
                return Err(out_of_range(
                    &format!("config.boxes[{i}]"),
                    (b.min, b.max),
                    "min ≤ max on every axis",
                ));
            }
            check_range(
                &format!("config.boxes[{i}].friction"),
                b.friction,
                0.0,
                100.0,
                "0 ≤ friction ≤ 100",
            )?;
        }
        Ok(())
    }
}

/// Material and clustering parameters of one body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Shape-matching stiffness of every cluster, in [0, 1].
    pub stiffness: f32,
    /// Mass of one particle (> 0).
    pub particle_mass: f32,
    /// Cluster radius in lattice units (Chebyshev): a cluster spans up to `2r+1` cells per axis.
    pub cluster_radius: u32,
    /// Layers shared by neighbouring clusters; cluster centres are `2r+1-overlap` cells apart.
    pub cluster_overlap: u32,
    /// Largest allowed cluster (≥ 2); regroup splits clusters above it.
    pub max_cluster_size: u32,
    /// Particles added to each rebuilt cluster by the expand stage (SPEC §3.4).
    pub expand_count: u32,
    /// Radius of each particle's contact ball; `None`: half the lattice spacing, so
    /// that neighbouring balls touch.
    pub contact_radius: Option<f32>,
    /// Static friction coefficient of particle contacts (≥ 0).
    pub static_friction: f32,
    /// Dynamic friction coefficient of particle contacts (≥ 0).
    pub dynamic_friction: f32,
    /// Whether particles of one piece collide when the piece folds onto itself
    /// (particles more than two lattice cells apart).
    pub self_contact: bool,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            stiffness: 1.0,
            particle_mass: 1.0,
            cluster_radius: 1,
            cluster_overlap: 1,
            max_cluster_size: 40,
            expand_count: 4,
            contact_radius: None,
            static_friction: 0.6,
            dynamic_friction: 0.4,
            self_contact: true,
        }
    }
}

impl Material {
    /// Distance between neighbouring cluster centres, in lattice cells.
    pub fn cluster_stride(&self) -> u32 {
        2 * self.cluster_radius + 1 - self.cluster_overlap
    }

    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "material.stiffness",
            self.stiffness,
            0.0,
            1.0,
            "0 ≤ stiffness ≤ 1",
        )?;
        check_range(
            "material.particle_mass",
            self.particle_mass,
            1e-9,
            1e9,
            "1e-9 ≤ particle_mass ≤ 1e9 (kg)",
        )?;
        if self.cluster_radius == 0 || self.cluster_radius > 8 {
            return Err(out_of_range(
                "material.cluster_radius",
                self.cluster_radius,
                "1 ≤ cluster_radius ≤ 8 (lattice units)",
            ));
        }
        if self.cluster_overlap > 2 * self.cluster_radius {
            return Err(out_of_range(
                "material.cluster_overlap",
                self.cluster_overlap,
                "0 ≤ cluster_overlap ≤ 2·cluster_radius",
            ));
        }
        if self.max_cluster_size < 2 || self.max_cluster_size > 100_000 {
            return Err(out_of_range(
                "material.max_cluster_size",
                self.max_cluster_size,
                "2 ≤ max_cluster_size ≤ 100000",
            ));
        }
        if self.expand_count > 1000 {
            return Err(out_of_range(
                "material.expand_count",
                self.expand_count,
                "0 ≤ expand_count ≤ 1000",
            ));
        }
        if let Some(r) = self.contact_radius {
            check_range(
                "material.contact_radius",
                r,
                1e-6,
                1e6,
                "1e-6 ≤ contact_radius ≤ 1e6 (metres)",
            )?;
        }
        check_range(
            "material.static_friction",
            self.static_friction,
            0.0,
            100.0,
            "0 ≤ static_friction ≤ 100",
        )?;
        check_range(
            "material.dynamic_friction",
            self.dynamic_friction,
            0.0,
            100.0,
            "0 ≤ dynamic_friction ≤ 100",
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        SimConfig::default().validate().unwrap();
        Material::default().validate().unwrap();
    }

    #[test]
    fn bad_contact_fields_are_named() {
        for (m, field) in [
            (
                Material {
                    contact_radius: Some(-0.1),
                    ..Default::default()
                },
                "material.contact_radius",
            ),
            (
                Material {
                    contact_radius: Some(f32::NAN),
                    ..Default::default()
                },
                "material.contact_radius",
            ),
            (
                Material {
                    static_friction: f32::NAN,
                    ..Default::default()
                },
                "material.static_friction",
            ),
            (
                Material {
                    dynamic_friction: -1.0,
                    ..Default::default()
                },
                "material.dynamic_friction",
            ),
        ] {
            let e = m.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
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
        let m = Material {
            stiffness: 1.5,
            ..Default::default()
        };
        let e = m.validate().unwrap_err().to_string();
        assert!(
            e.contains("material.stiffness") && e.contains("0 ≤ stiffness ≤ 1"),
            "{e}"
        );
        let m = Material {
            max_cluster_size: 1,
            ..Default::default()
        };
        assert!(
            m.validate()
                .unwrap_err()
                .to_string()
                .contains("max_cluster_size")
        );
    }
}
