//! The allowed values of the number fields of [`super::Material`] and [`super::SimConfig`], declared
//! once (see [`Allowed`]): checked by [`super::Material::validate`] and
//! [`super::SimConfig::validate`], and by the scene file's reader.

use crate::error::allowed::Allowed;

/// [`super::Material::compliance`].
pub const COMPLIANCE: Allowed = Allowed::closed("compliance", 0.0, 1.0, "1/Pa");
/// [`super::Material::density`].
pub const DENSITY: Allowed = Allowed::closed("density", 1e-3, 1e6, "kg/m³");
/// [`super::Material::particle_mass`].
pub const PARTICLE_MASS: Allowed = Allowed::closed("particle_mass", 1e-9, 1e9, "kg");
/// [`super::Material::cluster_radius`].
pub const CLUSTER_RADIUS: Allowed = Allowed::count("cluster_radius", 1, 8);
/// [`super::Material::max_cluster_size`].
pub const MAX_CLUSTER_SIZE: Allowed = Allowed::count("max_cluster_size", 2, 100_000);
/// [`super::Material::expand_count`].
pub const EXPAND_COUNT: Allowed = Allowed::count("expand_count", 0, 1000);
/// [`super::Material::contact_radius`].
pub const CONTACT_RADIUS: Allowed = Allowed::closed("contact_radius", 1e-6, 1e6, "metres");
/// [`super::Material::static_friction`].
pub const STATIC_FRICTION: Allowed = Allowed::closed("static_friction", 0.0, 100.0, "");
/// [`super::Material::dynamic_friction`].
pub const DYNAMIC_FRICTION: Allowed = Allowed::closed("dynamic_friction", 0.0, 100.0, "");
/// [`super::Material::tear_stretch`].
pub const TEAR_STRETCH: Allowed = Allowed::above("tear_stretch", 1.0, 1000.0, "");
/// [`super::Material::tear_budget`].
pub const TEAR_BUDGET: Allowed = Allowed::count("tear_budget", 1, 10_000_000);
/// [`super::Material::tear_min_piece`].
pub const TEAR_MIN_PIECE: Allowed = Allowed::count("tear_min_piece", 1, 10_000_000);
/// [`super::Material::edge_compliance`].
pub const EDGE_COMPLIANCE: Allowed = Allowed::closed("edge_compliance", 0.0, 1.0, "1/Pa");
/// [`super::Material::patch_rings`].
pub const PATCH_RINGS: Allowed = Allowed::count("patch_rings", 1, crate::body::patches::MAX_RINGS);
/// [`super::Material::patch_normal_compliance`].
pub const PATCH_NORMAL_COMPLIANCE: Allowed =
    Allowed::closed("patch_normal_compliance", 0.0, 1.0, "1/Pa");
/// [`super::Material::patch_tangent_compliance`].
pub const PATCH_TANGENT_COMPLIANCE: Allowed =
    Allowed::closed("patch_tangent_compliance", 0.0, 1.0, "1/Pa");
/// [`super::Material::patch_threshold`].
pub const PATCH_THRESHOLD: Allowed =
    Allowed::above("patch_threshold", 0.0, 1000.0, "lattice spacings");
/// [`super::Material::yield_strain`].
pub const YIELD_STRAIN: Allowed = Allowed::closed("yield_strain", 0.0, 1000.0, "0: elastic");
/// [`super::Material::creep`].
pub const CREEP: Allowed = Allowed::closed("creep", 0.0, 1.0, "per second");
/// [`super::Material::max_plastic_strain`].
pub const MAX_PLASTIC_STRAIN: Allowed = Allowed::closed("max_plastic_strain", 0.0, 1000.0, "");

/// [`super::SimConfig::dt`].
pub const DT: Allowed = Allowed::closed("dt", 1e-6, 1.0, "seconds");
/// [`super::SimConfig::substeps`].
pub const SUBSTEPS: Allowed = Allowed::count("substeps", 1, 1000);
/// [`super::SimConfig::iterations`].
pub const ITERATIONS: Allowed = Allowed::count("iterations", 1, 10_000);
/// [`super::SimConfig::damping`].
pub const DAMPING: Allowed = Allowed::closed("damping", 0.0, 1000.0, "per second");
/// [`super::SimConfig::memory_budget_gb`].
pub const MEMORY_BUDGET_GB: Allowed = Allowed::closed("memory_budget_gb", 1e-3, 1024.0, "");
/// [`super::GroundPlane::height`].
pub const GROUND_HEIGHT: Allowed = Allowed::closed("height", -1e6, 1e6, "metres");
/// A body's lattice spacing.
pub const SPACING: Allowed = Allowed::closed("spacing", 1e-4, 100.0, "metres");
/// How far a body's particles are jittered from the lattice.
pub const JITTER: Allowed = Allowed::closed("jitter", 0.0, 0.5, "lattice spacings");
/// An attachment's (a handle's, a centroid hold's) spring.
pub const ATTACHMENT_COMPLIANCE: Allowed = Allowed::closed("compliance", 0.0, 1e6, "m/N; 0: hard");
/// The friction of the ground, of static boxes and of colliders.
pub const FRICTION: Allowed = Allowed::closed("friction", 0.0, 100.0, "");
