//! The clusters of one body as seen by the algorithms: a small trait for reading and
//! editing member lists with a particle → clusters index, and [`ClusterTable`], its
//! plain-data implementation (initial clustering, tests, benchmarks).

use smallvec::SmallVec;
use std::fmt::Debug;
use std::hash::Hash;

/// Cluster lists per particle; most particles are in at most 8 clusters.
pub type ClusterList<K> = SmallVec<[K; 8]>;

/// Read and edit access to one body's clusters. Member lists are kept sorted and
/// hold body-local particle indices; implementations keep the particle index in sync.
pub trait ClusterStore {
    /// Cluster handle (an entity in the ECS, a slot number in [`ClusterTable`]).
    type Key: Copy + Eq + Ord + Hash + Debug + Send + Sync;
    /// The particle → clusters index: entry `p` lists the clusters that contain particle
    /// `p`, ascending. Plain data, so parallel readers can share it.
    fn particle_index(&self) -> &[ClusterList<Self::Key>];
    /// Clusters that contain particle `p` (none for a particle out of range).
    fn clusters_of(&self, p: u32) -> &[Self::Key] {
        self.particle_index()
            .get(p as usize)
            .map(|l| l.as_slice())
            .unwrap_or(&[])
    }
    /// Members of cluster `k` (sorted); empty if `k` does not exist.
    fn members(&self, k: Self::Key) -> &[u32];
    /// Replaces the members of `k` (the list is sorted and deduplicated here).
    fn set_members(&mut self, k: Self::Key, members: Vec<u32>);
    /// Adds `extra` (strictly ascending) to the members of `k`; only new particles touch
    /// the index.
    fn add_members(&mut self, k: Self::Key, extra: &[u32]);
    /// Creates a cluster with the given members.
    fn create(&mut self, members: Vec<u32>) -> Self::Key;
    /// Deletes cluster `k`.
    fn remove(&mut self, k: Self::Key);
}

/// Sorts and deduplicates a member list (a strictly ascending list is returned as is).
pub fn normalise(mut members: Vec<u32>) -> Vec<u32> {
    if !members.is_sorted_by(|a, b| a < b) {
        members.sort_unstable();
        members.dedup();
    }
    members
}

/// Merges strictly ascending `extra` into strictly ascending `members` in place, in
/// linear time and without a temporary list; returns how many particles were new.
///
/// The merge runs from the back into room for all of `extra`, then closes the gap the
/// shared particles left. Its loop is branch-free (each step takes the larger head, from
/// both lists on a tie): which list a step takes from is data, and a branch on it would
/// mispredict about once per particle of `extra`.
pub fn merge_sorted(members: &mut Vec<u32>, extra: &[u32]) -> usize {
    let (old_len, added) = (members.len(), extra.len());
    if added == 0 {
        return 0;
    }
    members.resize(old_len + added, 0);
    // the write position never overtakes an unread member
    let (mut i, mut j, mut w) = (old_len, added, old_len + added);
    while i > 0 && j > 0 {
        let (a, e) = (members[i - 1], extra[j - 1]);
        w -= 1;
        members[w] = a.max(e);
        i -= usize::from(a >= e);
        j -= usize::from(e >= a);
    }
    // Either the members left are in place, or the particles left of `extra` (all new)
    // go right below the merged tail; the gap below the tail has one slot per shared
    // particle.
    let gap = if j == 0 {
        i..w
    } else {
        members[w - j..w].copy_from_slice(&extra[..j]);
        0..w - j
    };
    let shared = gap.len();
    if shared > 0 {
        members.copy_within(gap.end.., gap.start);
        members.truncate(old_len + added - shared);
    }
    added - shared
}

/// Moves the index entries of cluster `k` from the sorted member list `old` to the
/// sorted list `new`, touching only the particles that left or joined.
pub fn index_replace<K: Copy + Ord>(index: &mut [ClusterList<K>], old: &[u32], new: &[u32], k: K) {
    let (mut i, mut j) = (0, 0);
    while i < old.len() || j < new.len() {
        match (old.get(i), new.get(j)) {
            (Some(a), Some(b)) if a == b => {
                i += 1;
                j += 1;
            }
            (Some(&a), Some(&b)) if a < b => {
                index_remove(index, &[a], k);
                i += 1;
            }
            (Some(&a), None) => {
                index_remove(index, &[a], k);
                i += 1;
            }
            (_, Some(&b)) => {
                index_add(index, &[b], k);
                j += 1;
            }
            (None, None) => break,
        }
    }
}

/// Helpers that keep a particle → clusters index in step with member edits.
pub fn index_remove<K: Eq>(index: &mut [ClusterList<K>], members: &[u32], k: K) {
    for &m in members {
        if let Some(list) = index.get_mut(m as usize)
            && let Some(pos) = list.iter().position(|x| *x == k)
        {
            list.remove(pos);
        }
    }
}

/// Adds `k` to the index entry of every particle in `members` (inserted in order;
/// entries that already hold `k` are left as they are).
pub fn index_add<K: Copy + Ord>(index: &mut [ClusterList<K>], members: &[u32], k: K) {
    for &m in members {
        let list = &mut index[m as usize];
        if let Err(pos) = list.binary_search(&k) {
            list.insert(pos, k);
        }
    }
}

/// Plain-data clusters of one body: slots of member lists plus the particle index.
#[derive(Clone, Debug, Default)]
pub struct ClusterTable {
    slots: Vec<Option<Vec<u32>>>,
    of_particle: Vec<ClusterList<u32>>,
}

impl ClusterTable {
    /// An empty table for a body with `particles` particle indices.
    pub fn new(particles: usize) -> Self {
        Self {
            slots: Vec::new(),
            of_particle: vec![ClusterList::new(); particles],
        }
    }

    /// Builds a table from member lists.
    pub fn from_clusters(particles: usize, clusters: Vec<Vec<u32>>) -> Self {
        let mut t = Self::new(particles);
        for c in clusters {
            t.create(c);
        }
        t
    }

    /// Live clusters as `(slot, members)`, ascending by slot.
    pub fn iter(&self) -> impl Iterator<Item = (u32, &[u32])> {
        self.slots
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.as_deref().map(|m| (i as u32, m)))
    }

    /// Number of live clusters.
    pub fn len(&self) -> usize {
        self.iter().count()
    }

    /// True when there is no live cluster.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Member lists of the live clusters, in slot order.
    pub fn into_clusters(self) -> Vec<Vec<u32>> {
        self.slots.into_iter().flatten().collect()
    }
}

impl ClusterStore for ClusterTable {
    type Key = u32;

    fn particle_index(&self) -> &[ClusterList<u32>] {
        &self.of_particle
    }

    fn members(&self, k: u32) -> &[u32] {
        self.slots
            .get(k as usize)
            .and_then(|s| s.as_deref())
            .unwrap_or(&[])
    }

    fn set_members(&mut self, k: u32, members: Vec<u32>) {
        let members = normalise(members);
        let old = self.slots[k as usize].take().unwrap_or_default();
        index_replace(&mut self.of_particle, &old, &members, k);
        self.slots[k as usize] = Some(members);
    }

    fn add_members(&mut self, k: u32, extra: &[u32]) {
        if let Some(Some(members)) = self.slots.get_mut(k as usize)
            && merge_sorted(members, extra) > 0
        {
            index_add(&mut self.of_particle, extra, k);
        }
    }

    fn create(&mut self, members: Vec<u32>) -> u32 {
        let k = self.slots.len() as u32;
        self.slots.push(None);
        self.set_members(k, members);
        k
    }

    fn remove(&mut self, k: u32) {
        if let Some(old) = self.slots.get_mut(k as usize).and_then(Option::take) {
            index_remove(&mut self.of_particle, &old, k);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_sorted_is_a_set_union() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for _ in 0..2000 {
            // strictly ascending lists of up to 40 particles out of 60
            let mut list = || {
                let n = rng.random_range(0..40);
                let mut v: Vec<u32> = (0..n).map(|_| rng.random_range(0..60)).collect();
                v.sort_unstable();
                v.dedup();
                v
            };
            let (before, extra) = (list(), list());
            let mut union = [before.clone(), extra.clone()].concat();
            union.sort_unstable();
            union.dedup();
            let mut members = before.clone();
            let new = merge_sorted(&mut members, &extra);
            assert_eq!(members, union, "{before:?} + {extra:?}");
            assert_eq!(new, union.len() - before.len());
        }
    }

    #[test]
    fn merge_sorted_keeps_order_and_reports_new_particles() {
        let mut index: Vec<ClusterList<u32>> = vec![ClusterList::new(); 6];
        index_add(&mut index, &[0, 2, 3], 7);
        index_add(&mut index, &[2], 1);
        index_replace(&mut index, &[0, 2, 3], &[2, 4, 5], 7);
        let lists: Vec<Vec<u32>> = index.iter().map(|l| l.to_vec()).collect();
        assert_eq!(
            lists,
            [vec![], vec![], vec![1, 7], vec![], vec![7], vec![7]]
        );
        let mut m = vec![2, 5, 9];
        assert_eq!(merge_sorted(&mut m, &[1, 5, 7, 12]), 3);
        assert_eq!(m, vec![1, 2, 5, 7, 9, 12]);
        assert_eq!(merge_sorted(&mut m, &[2, 12]), 0);
        assert_eq!(m, vec![1, 2, 5, 7, 9, 12]);
        let mut empty = vec![];
        assert_eq!(merge_sorted(&mut empty, &[4]), 1);
        assert_eq!(empty, vec![4]);
        let mut m = vec![3, 4];
        assert_eq!(merge_sorted(&mut m, &[0, 1, 4, 8]), 3);
        assert_eq!(m, vec![0, 1, 3, 4, 8]);
    }
}
