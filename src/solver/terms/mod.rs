//! The terms besides the clusters, one module each; each is registered by one line in
//! [`super::registry::Terms::builtin`].

pub mod attachments;
pub mod centroids;
pub mod colliders;
mod contact_grid;
pub mod contact_list;
pub mod contact_pairs;
pub mod contacts;
pub mod edges;
pub mod oriented;
pub mod patches;
