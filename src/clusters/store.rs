//! The clusters of one body as seen by the algorithms: a small trait for reading member
//! lists and applying batches of edits ([`ClusterEdits`]) with the particle → clusters
//! index ([`ClusterIndex`]) kept in step, and [`ClusterTable`], its plain-data
//! implementation (initial clustering, tests, benchmarks). Clusters are named by `u32`
//! keys: a slot number in [`ClusterTable`], an entity index in the ECS.

use crate::clusters::edits::{ClusterEdits, IndexChange, diff_into};
use crate::clusters::index::ClusterIndex;

/// Read access to one body's clusters, and edits in batches. Member lists are ascending
/// body-local particle indices; implementations keep the particle index in step.
pub trait ClusterStore {
    /// The particle → clusters index. Plain data, so parallel readers can share it.
    fn index(&self) -> &ClusterIndex;
    /// Members of cluster `k`, ascending; empty if `k` does not exist.
    fn members(&self, k: u32) -> &[u32];
    /// Applies a batch of edits and brings the index up to date in one pass; returns
    /// the keys of the created clusters, in order.
    fn apply(&mut self, edits: &ClusterEdits) -> Vec<u32>;

    /// Adds `extra` (strictly ascending) to the members of `k`: one edit, applied at once
    /// (many edits are cheaper as one batch, [`Self::apply`]).
    fn add_members(&mut self, k: u32, extra: &[u32]);
    /// Creates a cluster with the given members (sorted and deduplicated here): one edit,
    /// applied at once.
    fn create(&mut self, members: Vec<u32>) -> u32;

    /// Clusters that contain particle `p`, ascending (none for a particle out of range).
    fn clusters_of(&self, p: u32) -> &[u32] {
        self.index().clusters_of(p)
    }
}

/// Spare room of a member list a store makes: the expansion adds a few
/// particles to a new cluster next, which would otherwise reallocate the list.
const LIST_HEADROOM: usize = 8;

/// A store's own copy of a member list, with room to grow.
pub fn owned_list(members: &[u32]) -> Vec<u32> {
    let mut list = Vec::with_capacity(members.len() + LIST_HEADROOM);
    list.extend_from_slice(members);
    list
}

/// Adds `extra` (strictly ascending) to the sorted `members` of cluster `k`, and `k` to
/// the index entries of the particles that are new to it.
pub fn extend_indexed(members: &mut Vec<u32>, extra: &[u32], k: u32, index: &mut ClusterIndex) {
    extend_with(members, extra, |p| {
        index.add(p, k);
    });
}

/// Writes `extra` (strictly ascending) into the sorted `members` and appends the index
/// additions of the particles that are new to cluster `k`.
pub fn extend_members(
    members: &mut Vec<u32>,
    extra: &[u32],
    k: u32,
    changes: &mut Vec<IndexChange>,
) {
    extend_with(members, extra, |p| {
        changes.push(IndexChange {
            particle: p,
            key: k,
            add: true,
        })
    });
}

/// Merges strictly ascending `extra` into the sorted `members`, calling `joined` for each
/// particle that was not a member yet (the list is rewritten only if there is one).
fn extend_with(members: &mut Vec<u32>, extra: &[u32], mut joined: impl FnMut(u32)) {
    let mut new = false;
    let mut i = 0;
    for &p in extra {
        while i < members.len() && members[i] < p {
            i += 1;
        }
        if members.get(i) != Some(&p) {
            joined(p);
            new = true;
        }
    }
    if new {
        merge_sorted(members, extra);
    }
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

/// Plain-data clusters of one body: slots of member lists plus the particle index.
#[derive(Clone, Debug, Default)]
pub struct ClusterTable {
    slots: Vec<Option<Vec<u32>>>,
    index: ClusterIndex,
}

impl ClusterTable {
    /// An empty table for a body with `particles` particle indices.
    pub fn new(particles: usize) -> Self {
        Self {
            slots: Vec::new(),
            index: ClusterIndex::new(particles),
        }
    }

    /// Builds a table from member lists.
    pub fn from_clusters(particles: usize, clusters: Vec<Vec<u32>>) -> Self {
        let mut t = Self::new(particles);
        let mut edits = ClusterEdits::default();
        for c in clusters {
            edits.create(&normalise(c));
        }
        t.apply(&edits);
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
    fn index(&self) -> &ClusterIndex {
        &self.index
    }

    fn members(&self, k: u32) -> &[u32] {
        self.slots
            .get(k as usize)
            .and_then(|s| s.as_deref())
            .unwrap_or(&[])
    }

    fn apply(&mut self, edits: &ClusterEdits) -> Vec<u32> {
        let removed: usize = edits.removed().iter().map(|k| self.members(*k).len()).sum();
        let mut changes = Vec::with_capacity(edits.changes_capacity(removed));
        for (k, members) in edits.replaced() {
            if let Some(Some(old)) = self.slots.get_mut(k as usize) {
                diff_into(old, members, k, &mut changes);
                old.clear();
                old.extend_from_slice(members);
            }
        }
        for (k, extra) in edits.extended() {
            if let Some(Some(old)) = self.slots.get_mut(k as usize) {
                extend_members(old, extra, k, &mut changes);
            }
        }
        for &k in edits.removed() {
            if let Some(old) = self.slots.get_mut(k as usize).and_then(Option::take) {
                diff_into(&old, &[], k, &mut changes);
            }
        }
        let created: Vec<u32> = edits
            .created()
            .map(|members| {
                let k = self.slots.len() as u32;
                diff_into(&[], members, k, &mut changes);
                self.slots.push(Some(owned_list(members)));
                k
            })
            .collect();
        self.index.apply(&changes);
        created
    }

    fn add_members(&mut self, k: u32, extra: &[u32]) {
        if let Some(Some(members)) = self.slots.get_mut(k as usize) {
            extend_indexed(members, extra, k, &mut self.index);
        }
    }

    fn create(&mut self, members: Vec<u32>) -> u32 {
        let members = normalise(members);
        let k = self.slots.len() as u32;
        self.index.add_cluster(k, &members);
        self.slots.push(Some(members));
        k
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
    fn a_batch_of_edits_keeps_the_index_in_step() {
        let mut t = ClusterTable::from_clusters(6, vec![vec![0, 2, 3], vec![2]]);
        let mut edits = ClusterEdits::default();
        edits.replace(0, &[2, 4, 5]);
        edits.extend(1, &[1, 2]);
        edits.create(&[0, 5]);
        assert_eq!(t.apply(&edits), [2]);
        let lists: Vec<&[u32]> = t.index().iter().collect();
        assert_eq!(lists, [&[2][..], &[1], &[0, 1], &[], &[0], &[0, 2]]);
        let mut edits = ClusterEdits::default();
        edits.remove(0);
        t.apply(&edits);
        let lists: Vec<&[u32]> = t.index().iter().collect();
        assert_eq!(lists, [&[2][..], &[1], &[1], &[], &[], &[2]]);
        assert_eq!(t.members(0), &[] as &[u32]);
    }

    #[test]
    fn merge_sorted_keeps_order_and_reports_new_particles() {
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
