//! The solver: each substep, one implicit Euler step of a body's energy, a sum of terms
//! (see [`term`], where the seam and the compliance convention are documented).
//!
//! - [`particles`]: the particles' dense state within a frame (prediction, velocities).
//! - [`clusters`]: cluster shape matching, the dense SIMD core.
//! - [`term`] and [`registry`]: what a term is, and the registered ones in order.
//! - [`terms`]: attachments, surface patches, centroid holds, edge distances, contacts,
//!   colliders.
//! - [`schemes`]: Jacobi, coloured Gauss–Seidel and projective dynamics, which differ in
//!   how the clusters move the particles and how the other terms join in.
//! - [`solve`]: the iteration that runs them, timed per term.
//! - [`residual`]: how far a solve is from its solution (the net force on each particle).
//! - [`yielding`]: plastic flow of a rest shape, for the clusters and the oriented groups.
//!
//! Every scheme is deterministic for any number of threads: every sum runs in a fixed
//! order.

pub mod clusters;
pub(crate) mod disjoint;
pub mod particles;
pub mod registry;
pub mod residual;
pub mod schemes;
pub mod solve;
pub mod term;
pub mod terms;
#[cfg(test)]
mod testing;
pub mod yielding;
