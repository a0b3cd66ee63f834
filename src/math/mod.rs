//! Maths under everything else: rotations (Müller 2016 extraction, eight at once or
//! eight scalar ones in lockstep, quaternion helpers), a root-free test of a length
//! against a limit, symmetric 3×3 eigen-decomposition, eight-lane vectors and
//! matrices, the run-time choice of SIMD backend, and sparse Cholesky factors that know
//! their size before they are computed.

pub mod cone;
pub mod eigen;
pub mod lanes;
pub mod log_map;
pub mod rigid_fit;
pub mod rotation;
pub mod rotation_lockstep;
pub mod simd;
pub mod sparse_cholesky;
