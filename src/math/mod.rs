//! Maths under everything else: rotations (Müller 2016 extraction, quaternion
//! helpers), eight-lane vectors and matrices, and the run-time choice of SIMD backend.

pub mod lanes;
pub mod rotation;
pub mod simd;
