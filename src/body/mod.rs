//! A body's particles: the lattice (coordinates, live flags, edges as data, cuts on
//! it), the shapes voxelised into it, and graph algorithms over its edges (pieces,
//! connectivity).

pub mod crossings;
pub mod edits;
pub mod graph;
pub mod groups;
pub mod lattice;
mod morton;
pub mod patches;
pub mod pieces;
pub mod shape;
