//! After a split cut: the clusters around the split particles grown again from the
//! body's seed grid, as a fresh clustering grows them.
//!
//! A split leaves two particles in each cell it passes (the twins), and a fresh
//! clustering seeds a ball at each twin on a seed point, one on each side of the cut.
//! The pieces of the cut clusters are not those balls: a blade that crosses a layer
//! over several frames, or at a slant, leaves pieces that each cover some edges alone,
//! so none can be dropped, and the clusters grow smaller and more numerous with every
//! split. So the clusters a split's reconstruction produced are replaced by the balls of
//! the seed points among their particles, every particle and edge among them covered
//! again, and the clusters inside others removed.

use crate::body::lattice::Lattice;
use crate::clusters::clustering::{ball_cluster, cover_particles};
use crate::clusters::contained::remove_contained;
use crate::clusters::edits::ClusterEdits;
use crate::clusters::store::ClusterStore;
use crate::config::Material;
use glam::IVec3;

/// Replaces the clusters `keys` by the balls of the seed points (the grid of stride
/// [`Material::cluster_stride`] placed at `offset`) among their particles; returns the
/// clusters it created that remain, ascending.
pub fn reseed<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    material: &Material,
    offset: IVec3,
    keys: &[u32],
) -> Vec<u32> {
    let stride = IVec3::splat(material.cluster_stride() as i32);
    let max = material.max_cluster_size as usize;
    let mut region: Vec<u32> = keys
        .iter()
        .flat_map(|k| store.members(*k).iter().copied())
        .filter(|p| lattice.is_live(*p))
        .collect();
    region.sort_unstable();
    region.dedup();
    let mut edits = ClusterEdits::default();
    for &k in keys {
        edits.remove(k);
    }
    store.apply(&edits);
    let mut created: Vec<u32> = region
        .iter()
        .filter(|p| (lattice.coord(**p) - offset).rem_euclid(stride) == IVec3::ZERO)
        .map(|&seed| store.create(ball_cluster(lattice, seed, material.cluster_radius, max)))
        .collect();
    created.extend(cover_particles(store, lattice, &region, max));
    created.sort_unstable();
    created.dedup();
    let removed = remove_contained(store, lattice.len(), &created);
    created.retain(|k| removed.binary_search(k).is_err());
    created
}
