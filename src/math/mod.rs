//! Maths under everything else: rotations (Müller 2016 extraction, quaternion
//! helpers), eight-lane vectors and matrices, the run-time choice of SIMD backend, and
//! sparse Cholesky factors that know their size before they are computed.

pub mod lanes;
pub mod rotation;
pub mod simd;
pub mod sparse_cholesky;
