//! Measuring the engine: statistics of a state, cluster shapes, fidelity of rebuilt
//! clusters, static solves, the benchmarks behind `cleave bench`, per-stage profiles.

pub mod bench;
pub mod bench_cutting;
pub mod bench_deform;
pub mod bench_oriented;
pub mod bench_pile;
pub mod bench_surface;
pub mod cluster_shape;
pub mod fidelity;
pub mod frames;
pub mod profile;
pub mod static_solve;
pub mod stats;
