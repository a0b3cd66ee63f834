//! Reconstruction step 3: the parts of a split cluster grow by a few randomly chosen adjacent
//! particles (one BFS layer), so that they overlap each other and their neighbours again.
//!
//! The notes grow "the small clusters the split produced" (小簇); growing every rebuilt
//! cluster instead, on every cut that touches it, added 4 members to each of them per cut
//! and left 1.7–1.95 times the memberships per particle of a fresh clustering once the
//! pieces of cut clusters were kept (see [`super::regroup()`]).
//!
//! The adjacent particles are drawn, not listed: a random member and a random lattice
//! direction are tried until enough of them land on distinct live non-members. A
//! particle touching `k` members is therefore `k` times as likely as one touching a single
//! member, which favours the particles that keep the cluster compact. Listing every
//! adjacent particle to sample from the list would cost a lattice pass over all members,
//! where a draw costs one lookup; a cluster with few adjacent particles (the draws keep
//! missing) is still served by the list, uniformly.

use crate::body::graph::{adjacent_particles, position_in};
use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::clusters::edits::ClusterEdits;
use crate::clusters::store::ClusterStore;
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Draws per particle wanted before [`draw_adjacent`] gives up: inside the body, a
/// compact cluster's member–direction pairs lead out of it about a third of the time.
const DRAWS_PER_PARTICLE: usize = 16;

/// Adds up to `count` random adjacent particles to each cluster in `keys`, never
/// beyond `max` members (see the module docs for how they are chosen). Returns the
/// number of memberships added.
///
/// The choices only read the clusters and the lattice, so they are made in parallel, each
/// cluster with its own generator seeded from `rng` in key order (the result does not
/// depend on the thread count); the members are then added in key order.
pub fn expand_clusters<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    keys: &[u32],
    count: usize,
    max: usize,
    rng: &mut impl Rng,
) -> usize {
    if count == 0 {
        return 0;
    }
    let growing: Vec<(u32, &[u32], u64)> = keys
        .iter()
        .map(|k| (*k, store.members(*k)))
        .filter(|(_, m)| m.len() < max)
        .map(|(k, m)| (k, m, rng.random()))
        .collect();
    let additions: Vec<(u32, Vec<u32>)> = growing
        .into_par_iter()
        .with_min_len(32)
        .map(|(k, members, seed)| {
            let take = count.min(max - members.len());
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut extra = draw_adjacent(members, lattice, take, &mut rng).unwrap_or_else(|| {
                let adjacent = adjacent_particles(members, lattice);
                sample(&mut rng, adjacent.len(), take.min(adjacent.len()))
                    .into_iter()
                    .map(|i| adjacent[i])
                    .collect()
            });
            extra.sort_unstable();
            (k, extra)
        })
        .collect();
    let mut edits = ClusterEdits::default();
    for (k, extra) in &additions {
        edits.extend(*k, extra);
    }
    store.apply(&edits);
    additions.iter().map(|(_, extra)| extra.len()).sum()
}

/// `take` distinct adjacent particles of the sorted `members`, each found by
/// drawing a member and one of its six lattice directions until the cell there holds a
/// live particle that is neither a member nor drawn before; `None` when
/// [`DRAWS_PER_PARTICLE`] draws per particle do not find them all (or there are no
/// members to draw from).
fn draw_adjacent(
    members: &[u32],
    lattice: &Lattice,
    take: usize,
    rng: &mut impl Rng,
) -> Option<Vec<u32>> {
    // (u32 draws: a usize draw costs two words of the generator)
    let pairs = (members.len() * 6) as u32;
    if pairs == 0 {
        return None;
    }
    let mut drawn = Vec::with_capacity(take);
    for _ in 0..take * DRAWS_PER_PARTICLE {
        if drawn.len() == take {
            break;
        }
        let pair = rng.random_range(0..pairs) as usize;
        let n = lattice.link(members[pair / 6], pair % 6);
        if n != NO_PARTICLE && position_in(members, n).is_none() && !drawn.contains(&n) {
            drawn.push(n);
        }
    }
    (drawn.len() == take).then_some(drawn)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::graph::is_connected;
    use crate::body::shape::Shape;
    use crate::clusters::store::ClusterTable;
    use glam::UVec3;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn expansion_adds_adjacent_particles_up_to_max() {
        let l = Shape::cuboid(UVec3::new(5, 5, 1)).voxelise(1.0).unwrap();
        let centre = l.at(glam::IVec3::new(0, 0, 0)).unwrap();
        let mut t = ClusterTable::from_clusters(l.len(), vec![vec![centre]]);
        let added = expand_clusters(&mut t, &l, &[0], 3, 10, &mut ChaCha8Rng::seed_from_u64(2));
        assert_eq!(added, 3);
        assert_eq!(t.members(0).len(), 4);
        assert!(is_connected(t.members(0), &l));
        let added = expand_clusters(&mut t, &l, &[0], 100, 6, &mut ChaCha8Rng::seed_from_u64(2));
        assert_eq!(added, 2, "stops at max");
    }

    #[test]
    fn draws_are_distinct_adjacent_particles_and_a_short_supply_falls_back_to_the_list() {
        let mut l = Shape::cuboid(UVec3::new(6, 6, 6)).voxelise(1.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // a 3×3×3 block inside, some of its surroundings cut away
        let block: Vec<u32> = l
            .live_particles()
            .filter(|p| l.coord(*p).abs().max_element() <= 1)
            .collect();
        for p in l.live_particles().collect::<Vec<_>>() {
            if !block.contains(&p) && p % 5 == 0 {
                l.remove(p);
            }
        }
        let adjacent = adjacent_particles(&block, &l);
        let mut seen = std::collections::BTreeSet::new();
        let mut short = 0;
        for _ in 0..200 {
            let Some(drawn) = draw_adjacent(&block, &l, 4, &mut rng) else {
                short += 1;
                continue;
            };
            assert_eq!(drawn.len(), 4);
            for (i, p) in drawn.iter().enumerate() {
                assert!(adjacent.contains(p), "{p} is not adjacent");
                assert!(!drawn[..i].contains(p), "{p} drawn twice");
                seen.insert(*p);
            }
        }
        assert!(short < 10, "{short} of 200 draws ran short");
        assert_eq!(
            seen.len(),
            adjacent.len(),
            "every adjacent particle gets drawn"
        );
        assert_eq!(
            draw_adjacent(&block, &l, adjacent.len() + 1, &mut rng),
            None
        );
        assert_eq!(draw_adjacent(&[], &l, 1, &mut rng), None);
        // the list serves what the draws cannot: all adjacent particles, none more
        let mut t = ClusterTable::from_clusters(l.len(), vec![block.clone()]);
        let added = expand_clusters(&mut t, &l, &[0], 1000, 1000, &mut rng);
        assert_eq!(added, adjacent.len());
        let mut expected = [block, adjacent].concat();
        expected.sort_unstable();
        assert_eq!(t.members(0), expected);
    }
}
