//! Simulation and material parameters, with validation of every field.

use crate::error::{MAX_COORDINATE, Result, check_range, check_vec_within, out_of_range};
use glam::Vec3;
use serde::{Deserialize, Serialize};

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
            seed: 0,
            check_invariants_every_frame: false,
            memory_budget_gb: crate::body::shape::DEFAULT_MEMORY_BUDGET_GB,
        }
    }
}

impl SimConfig {
    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range("config.dt", self.dt, 1e-6, 1.0, "1e-6 ≤ dt ≤ 1 (seconds)")?;
        check_range(
            "config.memory_budget_gb",
            self.memory_budget_gb,
            1e-3,
            1024.0,
            "0.001 ≤ memory_budget_gb ≤ 1024",
        )?;
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
    /// Compliance of the material, `1/E` in 1/Pa (E: Young's modulus, Poisson's ratio
    /// 0); 0 makes every cluster rigid; default 1e-6 (rubber, see [`Material::rubber`]). Each cluster stores the elastic energy
    /// `(κ/2) Σᵢ wᵢ |xᵢ − gᵢ|²` of its members' distances to their goals (weights
    /// `wᵢ = 1/nᵢ`, nᵢ the particle's cluster count), with `κ = E·V/σ²` (V a particle's
    /// volume, σ² a full cluster's per-axis spread of rest offsets), which approximates
    /// the as-rigid-as-possible energy density `(E/2)·|F − R|²`. The solvers take it
    /// into one implicit step the way XPBD does (Macklin et al. 2016), so the stiffness
    /// does not depend on the time step or the iteration count.
    pub compliance: f32,
    /// Density in kg/m³ (default 1100): a particle's mass is `density · spacing³`
    /// unless [`Material::particle_mass`] overrides it.
    pub density: f32,
    /// Mass of one particle in kg, overriding the density (`None`: from the density).
    pub particle_mass: Option<f32>,
    /// Cluster radius in lattice units (Chebyshev): a cluster spans up to `2r+1` cells per axis.
    pub cluster_radius: u32,
    /// Layers shared by neighbouring clusters; cluster centres are `2r+1-overlap` cells apart.
    pub cluster_overlap: u32,
    /// Largest allowed cluster (≥ 2): the initial clustering truncates its balls here,
    /// and no cut makes a cluster larger (see [`Material::split_size`]).
    pub max_cluster_size: u32,
    /// Particles added to each part of a split cluster by the expand stage.
    pub expand_count: u32,
    /// Radius of each particle's contact ball, with which it meets other particles, the
    /// ground and colliders; `None`: half the lattice spacing, so that neighbouring balls
    /// touch and a body rests on the ground with its lowest particle centres half a
    /// spacing above it.
    pub contact_radius: Option<f32>,
    /// Static friction coefficient of particle contacts (≥ 0).
    pub static_friction: f32,
    /// Dynamic friction coefficient of particle contacts (≥ 0).
    pub dynamic_friction: f32,
    /// Whether particles of one piece collide when the piece folds onto itself
    /// (particles more than two lattice cells apart).
    pub self_contact: bool,
    /// The largest principal stretch a voxel (the 8 particles around one lattice cell)
    /// bears before it tears; `None`: the body never tears (see [`crate::cut::tear`]).
    pub tear_stretch: Option<f32>,
    /// Most voxels of one body that tear in one frame (≥ 1): the strongest stretches
    /// go first, the rest wait for the next frame, so a crack grows over frames instead
    /// of shattering the body at once.
    pub tear_budget: u32,
    /// Smallest piece, in particles, that tearing may cut off (≥ 1): a tear that would
    /// leave a smaller piece is taken back.
    pub tear_min_piece: u32,
    /// Compliance of the lattice edges' distance constraints, `1/E` of the edges in 1/Pa
    /// (each edge a bar of the material, h² in section and h long, of stiffness `E h`);
    /// `None` (the default): no edge constraints. With soft clusters (a large
    /// [`Material::compliance`]) and stiff edges a body bends easily but barely
    /// stretches; 0 makes every edge hard.
    pub edge_compliance: Option<f32>,
}

/// Rubber ([`Material::rubber`]): a body a newcomer spawns deforms where it lands.
impl Default for Material {
    fn default() -> Self {
        Self {
            compliance: 1e-6,
            density: 1100.0,
            particle_mass: None,
            cluster_radius: 1,
            cluster_overlap: 1,
            max_cluster_size: 40,
            expand_count: 4,
            contact_radius: None,
            static_friction: 0.6,
            dynamic_friction: 0.4,
            self_contact: true,
            tear_stretch: None,
            tear_budget: 64,
            tear_min_piece: 8,
            edge_compliance: None,
        }
    }
}

impl Material {
    /// Rigid: every cluster keeps its rest shape (compliance 0), density 1000 kg/m³ —
    /// pieces that move as stones do.
    pub fn rigid() -> Self {
        Self {
            compliance: 0.0,
            density: 1000.0,
            ..Self::default()
        }
    }

    /// Rubber: Young's modulus 1 MPa (compliance 1e-6 1/Pa), density 1100 kg/m³ — a
    /// block squashes as it lands and springs back. The default.
    pub fn rubber() -> Self {
        Self::default()
    }

    /// Gel: Young's modulus 30 kPa (compliance 3.3e-5 1/Pa), density 1000 kg/m³ — it
    /// wobbles and sags under its own weight.
    pub fn gel() -> Self {
        Self {
            compliance: 3.3e-5,
            density: 1000.0,
            ..Self::default()
        }
    }

    /// The contact radius of a particle of a lattice with this spacing (see
    /// [`Material::contact_radius`]).
    pub fn contact_radius_at(&self, spacing: f32) -> f32 {
        self.contact_radius.unwrap_or(0.5 * spacing)
    }

    /// The mass of one particle of a lattice with this spacing (metres).
    pub fn mass_at_spacing(&self, spacing: f32) -> f32 {
        self.particle_mass
            .unwrap_or(self.density * spacing * spacing * spacing)
    }

    /// Each cluster's compliance `1/κ` in m/N on a lattice with this spacing (see
    /// [`Material::compliance`]): `σ²/(E·V)` with `V = spacing³` and
    /// `σ² = spacing²·r(r+1)/3`, the per-axis spread of a full `(2r+1)³` cluster.
    pub fn cluster_compliance(&self, spacing: f32) -> f32 {
        let r = self.cluster_radius as f32;
        self.compliance * r * (r + 1.0) / (3.0 * spacing)
    }

    /// Members of the largest cluster the initial clustering builds: a full `(2r+1)³`
    /// ball, or [`Material::max_cluster_size`] if that is smaller. After a cut, a
    /// cluster larger than this is too big and is split, so the rebuilt
    /// clusters stay the size a fresh clustering would make.
    pub fn split_size(&self) -> u32 {
        (2 * self.cluster_radius + 1)
            .saturating_pow(3)
            .min(self.max_cluster_size)
    }

    /// Distance between neighbouring cluster centres, in lattice cells.
    pub fn cluster_stride(&self) -> u32 {
        2 * self.cluster_radius + 1 - self.cluster_overlap
    }

    /// Checks every field; the error names the field and its allowed range.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "material.compliance",
            self.compliance,
            0.0,
            1.0,
            "0 ≤ compliance ≤ 1 (1/Pa)",
        )?;
        check_range(
            "material.density",
            self.density,
            1e-3,
            1e6,
            "1e-3 ≤ density ≤ 1e6 (kg/m³)",
        )?;
        if let Some(mass) = self.particle_mass {
            check_range(
                "material.particle_mass",
                mass,
                1e-9,
                1e9,
                "1e-9 ≤ particle_mass ≤ 1e9 (kg)",
            )?;
        }
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
        if let Some(stretch) = self.tear_stretch
            && !(stretch > 1.0 && stretch <= 1000.0)
        {
            return Err(out_of_range(
                "material.tear_stretch",
                stretch,
                "1 < tear_stretch ≤ 1000",
            ));
        }
        if let Some(c) = self.edge_compliance {
            check_range(
                "material.edge_compliance",
                c,
                0.0,
                1.0,
                "0 ≤ edge_compliance ≤ 1 (1/Pa)",
            )?;
        }
        for (field, value) in [
            ("material.tear_budget", self.tear_budget),
            ("material.tear_min_piece", self.tear_min_piece),
        ] {
            if !(1..=10_000_000).contains(&value) {
                return Err(out_of_range(field, value, "1 ≤ value ≤ 10000000"));
            }
        }
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
        for (m, field) in [
            (
                Material {
                    compliance: -1e-6,
                    ..Default::default()
                },
                "material.compliance",
            ),
            (
                Material {
                    compliance: f32::INFINITY,
                    ..Default::default()
                },
                "material.compliance",
            ),
            (
                Material {
                    density: f32::NAN,
                    ..Default::default()
                },
                "material.density",
            ),
            (
                Material {
                    particle_mass: Some(0.0),
                    ..Default::default()
                },
                "material.particle_mass",
            ),
        ] {
            let e = m.validate().unwrap_err().to_string();
            assert!(e.contains(field) && e.contains("allowed"), "{e}");
        }
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
