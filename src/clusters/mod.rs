//! Clusters over a body's particles: the initial clustering, the particle → clusters
//! index, the store that edits clusters in batches, the rule that no cluster lies inside
//! another, and the invariants every body keeps.

pub mod clustering;
pub mod contained;
pub mod edits;
pub mod index;
pub mod invariants;
pub mod store;
