//! The ECS side of the built-in terms that take data from the ECS ([`crate::ecs::ecs_term`]):
//! one module per kind, beside its kernel in [`crate::solver::terms`]. Their syncs are
//! registered in [`crate::systems::build_sync_schedule`].

pub mod attachments;
pub mod colliders;
pub mod contacts;
