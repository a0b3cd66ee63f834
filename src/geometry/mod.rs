//! Shapes in space, independent of bodies: convex distance queries, triangle meshes
//! and their signed distance, and the shapes of colliders.

pub mod collider;
pub mod convex;
pub mod mesh;
pub mod mesh_sdf;
