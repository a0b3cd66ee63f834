//! The three schemes that solve a substep's implicit step; they share the clusters' fit
//! and differ in how they move the particles:
//! - **Jacobi** ([`jacobi`]): every cluster is fitted to the same positions and adds its
//!   pulls to its members; each particle then moves to the inertia-weighted average of
//!   its goals and its prediction.
//! - **Coloured Gauss–Seidel** ([`gauss_seidel`]): colour after colour, each cluster is
//!   fitted and moves its members at once by their XPBD step.
//! - **Projective dynamics** ([`projective`]): Jacobi's cluster pass and the terms'
//!   projections as the local step, then one sparse linear solve for every particle.

pub mod gauss_seidel;
pub mod jacobi;
pub mod projective;
