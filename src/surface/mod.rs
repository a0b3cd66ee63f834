//! A drawable surface for every body: the closed triangle mesh of the boundary of the
//! solid its particles own, opened along every cut ([`mod@extract`]), and carried by the
//! particles each frame ([`deform`]). Pure functions on the lattice and on arrays of
//! positions; the `Surface` stage keeps one per body ([`crate::ecs::surface_mesh`]).

pub mod carry;
pub mod cells;
pub mod clip;
pub mod deform;
pub mod embed;
pub mod extract;
pub mod fans;
pub mod placement;
pub mod smooth;
mod trilinear;
pub mod update;

pub use carry::{CarryLayout, SpareLists};
pub use extract::{Binding, SurfaceTopology, extract};
