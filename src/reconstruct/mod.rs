//! Cluster reconstruction after a cut (SPEC §3–4), as pure functions over a
//! [`ClusterStore`](crate::cluster_store::ClusterStore):
//! [`regroup`] (pieces and merge, §3.1–3.2), [`split`] (§3.3 and §4), [`expand`] (§3.4).

pub mod expand;
pub mod pca;
pub mod regroup;
pub mod split;

pub use expand::expand_clusters;
pub use regroup::regroup;
pub use split::{split_cluster, split_oversized};
