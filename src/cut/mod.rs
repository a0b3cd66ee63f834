//! Cutting: tools and their swept motion, detection of what they reach (read-only),
//! and the edits a cut makes to a lattice — carving, tearing, splitting particles.

pub mod blocks;
pub mod carve;
pub mod crossings;
pub mod culling;
pub mod detection;
pub mod particle_split;
pub mod stroke;
pub mod tear;
pub mod tool;
pub mod tool_sweep;
