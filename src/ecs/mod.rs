//! The ECS data of a simulation: components, resources and messages, descriptions of
//! what can be spawned and the spawning itself, poses set from game code, the map between the particle table and
//! the solver's dense arrays, the drawable surfaces, and the invariant check over a world.

pub mod attach;
pub mod budget;
pub mod check;
pub mod commands;
pub mod components;
pub mod desc;
pub mod ecs_term;
pub mod groups;
pub mod handles;
pub mod layout;
pub mod poses;
pub mod resources;
pub mod spawn;
pub mod spawn_body;
pub mod surface_mesh;
pub mod terms;
