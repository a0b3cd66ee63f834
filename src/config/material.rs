//! A body's material: its elasticity, mass, clustering, contacts, tearing and shape
//! keeping, with validation of every field.

use crate::error::allowed::{Allowed, CheckedField};
use crate::error::{Result, out_of_range};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// How a body's elasticity is modelled; spelled `"clusters"` and `"oriented"` in files,
/// on the command line and in JSON.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Model {
    /// Overlapping clusters of particles, each a shape-matching constraint (SPEC §2).
    #[default]
    Clusters,
    /// Oriented particles (SPEC §5): one implicit shape-matching group per particle —
    /// the particle and its live lattice neighbours — with generalised shape matching,
    /// so that bodies one particle thick hold their shape; explicit groups make rigid
    /// parts. See [`crate::solver::terms::oriented`].
    Oriented,
}

crate::util::named_enum::named_enum!(Model, "model", [
    Clusters => "clusters",
    Oriented => "oriented",
]);

/// Material and clustering parameters of one body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Material {
    /// Compliance of the material, `1/E` in 1/Pa (E: Young's modulus, Poisson's ratio
    /// 0); 0 makes every cluster rigid; default 1e-6 (rubber, see [`Material::rubber`]). Each cluster stores the elastic energy
    /// `(κ/2) Σᵢ wᵢ |xᵢ − gᵢ|²` of its members' distances to their goals (weights
    /// `wᵢ = 1/nᵢ`, nᵢ the particle's cluster count), with `κ = E·V/σ²` (V a particle's
    /// volume, σ² a full cluster's per-axis spread of rest offsets), which approximates
    /// the as-rigid-as-possible energy density `(E/2)·|F − R|²`. The solvers take it
    /// into one implicit step the way XPBD does (Macklin et al. 2016), so the stiffness
    /// does not depend on the time step or the iteration count.
    #[serde(deserialize_with = "checked::compliance")]
    pub compliance: f32,
    /// Density in kg/m³ (default 1100): a particle's mass is `density · spacing³`
    /// unless [`Material::particle_mass`] overrides it.
    #[serde(deserialize_with = "checked::density")]
    pub density: f32,
    /// Mass of one particle in kg, overriding the density (`None`: from the density).
    #[serde(deserialize_with = "checked::particle_mass")]
    pub particle_mass: Option<f32>,
    /// Cluster radius in lattice units (Chebyshev): a cluster spans up to `2r+1` cells per axis.
    #[serde(deserialize_with = "checked::cluster_radius")]
    pub cluster_radius: u32,
    /// Layers shared by neighbouring clusters; cluster centres are `2r+1-overlap` cells apart.
    pub cluster_overlap: u32,
    /// Largest allowed cluster (≥ 2): the initial clustering truncates its balls here,
    /// and no cut makes a cluster larger (see [`Material::split_size`]).
    #[serde(deserialize_with = "checked::max_cluster_size")]
    pub max_cluster_size: u32,
    /// Particles added to each part of a split cluster by the expand stage.
    #[serde(deserialize_with = "checked::expand_count")]
    pub expand_count: u32,
    /// Radius of each particle's contact ball, with which it meets other particles, the
    /// ground and colliders; `None`: half the lattice spacing, so that neighbouring balls
    /// touch and a body rests on the ground with its lowest particle centres half a
    /// spacing above it.
    #[serde(deserialize_with = "checked::contact_radius")]
    pub contact_radius: Option<f32>,
    /// Static friction coefficient of particle contacts (≥ 0).
    #[serde(deserialize_with = "checked::static_friction")]
    pub static_friction: f32,
    /// Dynamic friction coefficient of particle contacts (≥ 0).
    #[serde(deserialize_with = "checked::dynamic_friction")]
    pub dynamic_friction: f32,
    /// Whether particles of one piece collide when the piece folds onto itself
    /// (particles more than two lattice cells apart).
    pub self_contact: bool,
    /// The largest principal stretch a voxel (the 8 particles around one lattice cell)
    /// bears before it tears; `None`: the body never tears (see [`crate::cut::tear`]).
    #[serde(deserialize_with = "checked::tear_stretch")]
    pub tear_stretch: Option<f32>,
    /// Most voxels of one body that tear in one frame (≥ 1): the strongest stretches
    /// go first, the rest wait for the next frame, so a crack grows over frames instead
    /// of shattering the body at once.
    #[serde(deserialize_with = "checked::tear_budget")]
    pub tear_budget: u32,
    /// Smallest piece, in particles, that tearing may cut off (≥ 1): a tear that would
    /// leave a smaller piece is taken back.
    #[serde(deserialize_with = "checked::tear_min_piece")]
    pub tear_min_piece: u32,
    /// Compliance of the lattice edges' distance constraints, `1/E` of the edges in 1/Pa
    /// (each edge a bar of the material, h² in section and h long, of stiffness `E h`);
    /// `None` (the default): no edge constraints. With soft clusters (a large
    /// [`Material::compliance`]) and stiff edges a body bends easily but barely
    /// stretches; 0 makes every edge hard.
    #[serde(deserialize_with = "checked::edge_compliance")]
    pub edge_compliance: Option<f32>,
    /// Rings of the surface patches that shape keeping holds (1–8, default 2): each
    /// surface particle centres a patch of the surface particles within this many rings
    /// (see [`crate::solver::terms::patches`]).
    #[serde(deserialize_with = "checked::patch_rings")]
    pub patch_rings: u32,
    /// Compliance of each patch's mean displacement along its rest normal, `1/E` in
    /// 1/Pa as [`Material::compliance`] (a patch of the material, h² in section and h
    /// deep: `α = patch_normal_compliance / h` m/N); 0 holds it hard. `None` (the
    /// default): no patch constraints while the body simulates; relaxation
    /// ([`crate::sim::relax`]) then holds the patches with the material's compliance.
    #[serde(deserialize_with = "checked::patch_normal_compliance")]
    pub patch_normal_compliance: Option<f32>,
    /// Compliance of each patch's mean displacement across its rest normal, 1/Pa;
    /// `None`: 100 times the normal compliance, so the surface keeps its place far more
    /// firmly than it may slide along itself.
    #[serde(deserialize_with = "checked::patch_tangent_compliance")]
    pub patch_tangent_compliance: Option<f32>,
    /// The normal displacement, in lattice spacings (> 0, default 0.1), past which a
    /// patch's normal stiffness grows, as the square of the displacement over it.
    #[serde(deserialize_with = "checked::patch_threshold")]
    pub patch_threshold: f32,
    /// How the body's elasticity is modelled (default: clusters).
    pub model: Model,
    /// Radii of each particle's ellipsoid along its own axes, in metres (> 0), whose
    /// moment matrix generalised shape matching adds (oriented model); `None`: a sphere
    /// of half the lattice spacing.
    #[serde(deserialize_with = "checked::particle_radii")]
    pub particle_radii: Option<Vec3>,
    /// Plasticity (both models): the strain of a cluster's or a group's shape past which
    /// its rest shape creeps toward its deformed shape (≥ 0; 0, the default: elastic).
    /// The strain is the shape's RMS deviation from its fitted rigid motion over its RMS
    /// rest offset. See [`crate::solver::yielding`].
    #[serde(deserialize_with = "checked::yield_strain")]
    pub yield_strain: f32,
    /// How fast a yielded rest shape creeps, as the share of its excess strain taken per
    /// second (0–1).
    #[serde(deserialize_with = "checked::creep")]
    pub creep: f32,
    /// The most a cluster's or a group's rest shape may drift from its lattice shape, as
    /// strain (≥ 0).
    #[serde(deserialize_with = "checked::max_plastic_strain")]
    pub max_plastic_strain: f32,
}

/// A material's plasticity, as the solver's terms take it ([`Material::yielding`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Yield {
    /// [`Material::yield_strain`] (> 0).
    pub strain: f32,
    /// [`Material::creep`].
    pub creep: f32,
    /// [`Material::max_plastic_strain`].
    pub max_strain: f32,
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
            patch_rings: 2,
            patch_normal_compliance: None,
            patch_tangent_compliance: None,
            patch_threshold: 0.1,
            model: Model::Clusters,
            particle_radii: None,
            yield_strain: 0.0,
            creep: 0.5,
            max_plastic_strain: 0.5,
        }
    }
}

impl Material {
    /// The material's plasticity, `None` when it is elastic (yield strain 0).
    pub fn yielding(&self) -> Option<Yield> {
        (self.yield_strain > 0.0).then_some(Yield {
            strain: self.yield_strain,
            creep: self.creep,
            max_strain: self.max_plastic_strain,
        })
    }

    /// Rigid: every cluster keeps its rest shape (compliance 0), density 1000 kg/m³ —
    /// pieces that move as stones do. Without self-contact: a stone does not fold onto
    /// itself (at rest, particles more than two cells apart are three cells apart, more
    /// than twice as far as their balls reach), so it needs no pairs of its own; its
    /// pieces still meet each other and every other body. Only a solve too short to
    /// hold a large piece's shape through a hard impact brings such particles close,
    /// and self-contact would then hide that rather than cure it.
    pub fn rigid() -> Self {
        Self {
            compliance: 0.0,
            density: 1000.0,
            self_contact: false,
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
        self.cluster_compliance_of(self.compliance, spacing)
    }

    /// [`Material::cluster_compliance`] of a cluster of material compliance
    /// `compliance` (1/Pa) instead of the material's (a stiffness region's).
    pub fn cluster_compliance_of(&self, compliance: f32, spacing: f32) -> f32 {
        let r = self.cluster_radius as f32;
        compliance * r * (r + 1.0) / (3.0 * spacing)
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

    /// The radii of a particle's ellipsoid on a lattice with this spacing (see
    /// [`Material::particle_radii`]).
    pub fn particle_radii_at(&self, spacing: f32) -> Vec3 {
        self.particle_radii.unwrap_or(Vec3::splat(0.5 * spacing))
    }

    /// The patch constraints' compliances `(normal, tangent)` in 1/Pa, or `None` when
    /// the material holds no patches (see [`Material::patch_normal_compliance`]).
    pub fn patch_compliances(&self) -> Option<(f32, f32)> {
        let normal = self.patch_normal_compliance?;
        let tangent = self.patch_tangent_compliance.unwrap_or(100.0 * normal);
        Some((normal, tangent))
    }

    /// Checks every field; the error names the field and its allowed range (the ranges
    /// of [`crate::config::ranges`], which the scene file's reader checks too).
    pub fn validate(&self) -> Result<()> {
        use super::ranges::*;
        let path = |a: &Allowed| format!("material.{}", a.field);
        for (allowed, value) in [
            (COMPLIANCE, Some(self.compliance)),
            (DENSITY, Some(self.density)),
            (PARTICLE_MASS, self.particle_mass),
            (CONTACT_RADIUS, self.contact_radius),
            (STATIC_FRICTION, Some(self.static_friction)),
            (DYNAMIC_FRICTION, Some(self.dynamic_friction)),
            (TEAR_STRETCH, self.tear_stretch),
            (EDGE_COMPLIANCE, self.edge_compliance),
            (PATCH_NORMAL_COMPLIANCE, self.patch_normal_compliance),
            (PATCH_TANGENT_COMPLIANCE, self.patch_tangent_compliance),
            (PATCH_THRESHOLD, Some(self.patch_threshold)),
            (YIELD_STRAIN, Some(self.yield_strain)),
            (CREEP, Some(self.creep)),
            (MAX_PLASTIC_STRAIN, Some(self.max_plastic_strain)),
        ] {
            if let Some(v) = value {
                allowed.check(&path(&allowed), v)?;
            }
        }
        for (allowed, value) in [
            (CLUSTER_RADIUS, self.cluster_radius),
            (MAX_CLUSTER_SIZE, self.max_cluster_size),
            (EXPAND_COUNT, self.expand_count),
            (TEAR_BUDGET, self.tear_budget),
            (TEAR_MIN_PIECE, self.tear_min_piece),
            (PATCH_RINGS, self.patch_rings),
        ] {
            allowed.check(&path(&allowed), value)?;
        }
        if self.cluster_overlap > 2 * self.cluster_radius {
            return Err(out_of_range(
                "material.cluster_overlap",
                self.cluster_overlap,
                "0 ≤ cluster_overlap ≤ 2·cluster_radius",
            ));
        }
        if let Some(r) = self.particle_radii
            && !radii_allowed(r)
        {
            return Err(out_of_range("material.particle_radii", r, RADII));
        }
        Ok(())
    }
}

/// What [`Material::particle_radii`] allows.
const RADII: &str = "each radius finite and > 0 (metres)";

fn radii_allowed(r: Vec3) -> bool {
    r.is_finite() && r.cmpgt(Vec3::ZERO).all()
}

/// The scene file's readers of the checked fields (serde's `deserialize_with`): each
/// checks its field against [`crate::config::ranges`], the error stating the range.
mod checked {
    use super::{CheckedField, RADII, radii_allowed};
    use crate::config::ranges::*;
    use glam::Vec3;
    use serde::{Deserialize, Deserializer};

    macro_rules! readers {
        ($($field:ident: $ty:ty = $allowed:ident;)*) => {$(
            pub(super) fn $field<'de, D: Deserializer<'de>>(d: D) -> Result<$ty, D::Error> {
                <$ty>::read(d, &$allowed)
            }
        )*};
    }

    readers! {
        compliance: f32 = COMPLIANCE;
        density: f32 = DENSITY;
        particle_mass: Option<f32> = PARTICLE_MASS;
        cluster_radius: u32 = CLUSTER_RADIUS;
        max_cluster_size: u32 = MAX_CLUSTER_SIZE;
        expand_count: u32 = EXPAND_COUNT;
        contact_radius: Option<f32> = CONTACT_RADIUS;
        static_friction: f32 = STATIC_FRICTION;
        dynamic_friction: f32 = DYNAMIC_FRICTION;
        tear_stretch: Option<f32> = TEAR_STRETCH;
        tear_budget: u32 = TEAR_BUDGET;
        tear_min_piece: u32 = TEAR_MIN_PIECE;
        edge_compliance: Option<f32> = EDGE_COMPLIANCE;
        patch_rings: u32 = PATCH_RINGS;
        patch_normal_compliance: Option<f32> = PATCH_NORMAL_COMPLIANCE;
        patch_tangent_compliance: Option<f32> = PATCH_TANGENT_COMPLIANCE;
        patch_threshold: f32 = PATCH_THRESHOLD;
        yield_strain: f32 = YIELD_STRAIN;
        creep: f32 = CREEP;
        max_plastic_strain: f32 = MAX_PLASTIC_STRAIN;
    }

    pub(super) fn particle_radii<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Vec3>, D::Error> {
        let v = Option::<Vec3>::deserialize(d)?;
        match v {
            Some(r) if !radii_allowed(r) => Err(crate::error::allowed::refusal(r, RADII)),
            _ => Ok(v),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_is_valid() {
        Material::default().validate().unwrap();
    }

    #[test]
    fn bad_fields_are_named() {
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
            (
                Material {
                    patch_rings: 0,
                    ..Default::default()
                },
                "material.patch_rings",
            ),
            (
                Material {
                    patch_rings: 9,
                    ..Default::default()
                },
                "material.patch_rings",
            ),
            (
                Material {
                    patch_threshold: 0.0,
                    ..Default::default()
                },
                "material.patch_threshold",
            ),
            (
                Material {
                    patch_threshold: f32::NAN,
                    ..Default::default()
                },
                "material.patch_threshold",
            ),
            (
                Material {
                    patch_normal_compliance: Some(-1e-6),
                    ..Default::default()
                },
                "material.patch_normal_compliance",
            ),
            (
                Material {
                    patch_tangent_compliance: Some(f32::NAN),
                    ..Default::default()
                },
                "material.patch_tangent_compliance",
            ),
            (
                Material {
                    max_cluster_size: 1,
                    ..Default::default()
                },
                "material.max_cluster_size",
            ),
            (
                Material {
                    yield_strain: -0.1,
                    ..Default::default()
                },
                "material.yield_strain",
            ),
            (
                Material {
                    creep: 1.5,
                    ..Default::default()
                },
                "material.creep",
            ),
            (
                Material {
                    particle_radii: Some(Vec3::new(0.1, 0.0, 0.1)),
                    ..Default::default()
                },
                "material.particle_radii",
            ),
            (
                Material {
                    particle_radii: Some(Vec3::new(0.1, f32::NAN, 0.1)),
                    ..Default::default()
                },
                "material.particle_radii",
            ),
        ] {
            let e = m.validate().unwrap_err().to_string();
            assert!(e.contains(field) && e.contains("allowed"), "{e}");
        }
    }
}
