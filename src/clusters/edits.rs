//! A batch of cluster edits — member lists replaced, extended, created, removed — that a
//! reconstruction step computes from a read-only view of the clusters and a store then
//! applies at once ([`crate::clusters::store::ClusterStore::apply`]), and the particle →
//! clusters index changes such a batch implies (applied by
//! [`crate::clusters::index::ClusterIndex::apply`]).

/// A member list inside [`ClusterEdits`]: `particles[start..end]`.
type Span = [u32; 2];

/// Cluster edits to apply together. Member lists are strictly ascending body-local
/// particle indices. A cluster appears in at most one of replaced, extended and removed.
#[derive(Clone, Debug, Default)]
pub struct ClusterEdits {
    particles: Vec<u32>,
    replaced: Vec<(u32, Span)>,
    extended: Vec<(u32, Span)>,
    created: Vec<Span>,
    removed: Vec<u32>,
}

impl ClusterEdits {
    fn push(&mut self, members: &[u32]) -> Span {
        debug_assert!(members.is_sorted_by(|a, b| a < b), "{members:?}");
        let start = self.particles.len() as u32;
        self.particles.extend_from_slice(members);
        [start, self.particles.len() as u32]
    }

    fn list(&self, span: Span) -> &[u32] {
        &self.particles[span[0] as usize..span[1] as usize]
    }

    /// The members of `k` become `members`.
    pub fn replace(&mut self, k: u32, members: &[u32]) {
        let span = self.push(members);
        self.replaced.push((k, span));
    }

    /// `k` gains the particles of `extra` it does not hold yet.
    pub fn extend(&mut self, k: u32, extra: &[u32]) {
        let span = self.push(extra);
        self.extended.push((k, span));
    }

    /// A new cluster with `members`; new clusters get their keys in the order of these
    /// calls.
    pub fn create(&mut self, members: &[u32]) {
        let span = self.push(members);
        self.created.push(span);
    }

    /// `k` is deleted.
    pub fn remove(&mut self, k: u32) {
        self.removed.push(k);
    }

    /// Replacements, in the order given.
    pub fn replaced(&self) -> impl Iterator<Item = (u32, &[u32])> {
        self.replaced.iter().map(|(k, s)| (*k, self.list(*s)))
    }

    /// Extensions, in the order given.
    pub fn extended(&self) -> impl Iterator<Item = (u32, &[u32])> {
        self.extended.iter().map(|(k, s)| (*k, self.list(*s)))
    }

    /// Member lists of the new clusters, in the order given.
    pub fn created(&self) -> impl Iterator<Item = &[u32]> {
        self.created.iter().map(|s| self.list(*s))
    }

    /// Deleted clusters.
    pub fn removed(&self) -> &[u32] {
        &self.removed
    }

    /// Room for the index changes of applying these edits, given the members of the
    /// removed clusters: every listed particle, plus those of `removed_members`.
    pub fn changes_capacity(&self, removed_members: usize) -> usize {
        // (a replacement changes at most its old and new lists; the old ones are close
        // in size to the new)
        self.particles.len() + self.replaced_len() + removed_members
    }

    fn replaced_len(&self) -> usize {
        self.replaced
            .iter()
            .map(|(_, [s, e])| (e - s) as usize)
            .sum()
    }
}

/// One change of a particle → clusters index: `key` joins or leaves `particle`'s list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexChange {
    /// The particle.
    pub particle: u32,
    /// The cluster.
    pub key: u32,
    /// True to add, false to remove.
    pub add: bool,
}

/// Appends the index changes of cluster `k`'s members going from `old` to `new` (both
/// strictly ascending): removals for the particles that left, additions for those that
/// joined.
pub fn diff_into(old: &[u32], new: &[u32], k: u32, out: &mut Vec<IndexChange>) {
    let (mut i, mut j) = (0, 0);
    while i < old.len() && j < new.len() {
        let (a, b) = (old[i], new[j]);
        if a == b {
            i += 1;
            j += 1;
        } else if a < b {
            out.push(change(a, k, false));
            i += 1;
        } else {
            out.push(change(b, k, true));
            j += 1;
        }
    }
    out.extend(old[i..].iter().map(|p| change(*p, k, false)));
    out.extend(new[j..].iter().map(|p| change(*p, k, true)));
}

fn change(particle: u32, key: u32, add: bool) -> IndexChange {
    IndexChange { particle, key, add }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffs_list_the_particles_that_left_and_joined() {
        let mut out = Vec::new();
        diff_into(&[1, 3, 5, 7], &[0, 3, 4, 7, 9], 2, &mut out);
        let pairs: Vec<(u32, bool)> = out.iter().map(|c| (c.particle, c.add)).collect();
        assert_eq!(
            pairs,
            [(0, true), (1, false), (4, true), (5, false), (9, true)]
        );
        out.clear();
        diff_into(&[], &[], 2, &mut out);
        assert!(out.is_empty());
    }
}
