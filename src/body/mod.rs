//! A body's particles: the lattice (coordinates, live flags, edges as data, cuts on
//! it), the shapes voxelised into it, and graph algorithms over its edges (pieces,
//! connectivity).

pub mod graph;
pub mod lattice;
