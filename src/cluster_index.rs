//! The particle → clusters index of one body: for each particle the clusters that hold
//! it, as ascending `u32` keys.
//!
//! Eight keys are stored in place per particle, 32 bytes aligned to 32, so two
//! particles share a cache line and the usual edit (a key in, a key out) is a few
//! branch-free operations on eight slots. A particle in more clusters keeps its whole
//! list in a side table, which the bulk edits leave to a sequential pass.

use crate::cluster_edits::IndexChange;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Keys stored in place per particle.
pub const INLINE_KEYS: usize = 8;

/// The largest key the index holds (the two values above it mark slots).
pub const MAX_KEY: u32 = u32::MAX - 2;

/// An unused slot; sorts after every key.
const EMPTY: u32 = u32::MAX;

/// Slot 0 of a particle whose list lives in the side table.
const SPILLED: u32 = u32::MAX - 1;

/// Particles per block that one task edits in [`ClusterIndex::apply`].
const BLOCK: usize = 4096;

/// Below this many changes, [`ClusterIndex::apply`] edits in one pass, in order.
const PARALLEL_CHANGES: usize = 8192;

/// One particle's keys in place: ascending, then [`EMPTY`] slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(32))]
struct Slots([u32; INLINE_KEYS]);

/// What an in-place insertion did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Inserted {
    Yes,
    AlreadyThere,
    Full,
}

impl Slots {
    const NONE: Slots = Slots([EMPTY; INLINE_KEYS]);

    #[inline]
    fn spilled(&self) -> bool {
        self.0[0] == SPILLED
    }

    /// Number of keys in place.
    #[inline]
    fn len(&self) -> usize {
        self.0.iter().map(|x| usize::from(*x != EMPTY)).sum()
    }

    #[inline]
    fn keys(&self) -> &[u32] {
        &self.0[..self.len()]
    }

    #[inline]
    fn contains(&self, k: u32) -> bool {
        self.0.iter().fold(false, |found, x| found | (*x == k))
    }

    /// Inserts `k`, keeping the keys ascending: slot `i` becomes
    /// `max(s[i−1], min(s[i], k))` (with `s[−1] = 0`), which is `s[i]` below `k`'s place,
    /// `k` at it and `s[i−1]` above — lane-wise, without finding the place first.
    #[inline]
    fn insert(&mut self, k: u32) -> Inserted {
        if self.contains(k) {
            return Inserted::AlreadyThere;
        }
        if self.0[INLINE_KEYS - 1] != EMPTY {
            return Inserted::Full;
        }
        let s = self.0;
        let mut below = [0; INLINE_KEYS];
        below[1..].copy_from_slice(&s[..INLINE_KEYS - 1]);
        for i in 0..INLINE_KEYS {
            self.0[i] = below[i].max(s[i].min(k));
        }
        Inserted::Yes
    }

    /// Removes `k`: every slot from `k`'s place on takes the next slot's key.
    #[inline]
    fn remove(&mut self, k: u32) -> bool {
        if !self.contains(k) {
            return false;
        }
        let s = self.0;
        let mut above = [EMPTY; INLINE_KEYS];
        above[..INLINE_KEYS - 1].copy_from_slice(&s[1..]);
        for i in 0..INLINE_KEYS {
            self.0[i] = if s[i] < k { s[i] } else { above[i] };
        }
        true
    }
}

/// The particle → clusters index (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ClusterIndex {
    slots: Vec<Slots>,
    spill: FxHashMap<u32, Vec<u32>>,
}

impl ClusterIndex {
    /// An index of `particles` particles, each in no cluster.
    pub fn new(particles: usize) -> Self {
        Self {
            slots: vec![Slots::NONE; particles],
            spill: FxHashMap::default(),
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// True for an index of no particles.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// The clusters that hold particle `p`, ascending (none for a particle out of range).
    #[inline]
    pub fn clusters_of(&self, p: u32) -> &[u32] {
        match self.slots.get(p as usize) {
            Some(s) if s.spilled() => self.spill.get(&p).map_or(&[], Vec::as_slice),
            Some(s) => s.keys(),
            None => &[],
        }
    }

    /// Every particle's clusters, by particle.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &[u32]> {
        (0..self.slots.len() as u32).map(|p| self.clusters_of(p))
    }

    /// Adds cluster `k` (at most [`MAX_KEY`]) to particle `p`; false if it was there.
    ///
    /// # Panics
    /// If `p` is out of range.
    pub fn add(&mut self, p: u32, k: u32) -> bool {
        debug_assert!(k <= MAX_KEY, "key {k} is a slot marker");
        let s = &mut self.slots[p as usize];
        if !s.spilled() {
            match s.insert(k) {
                Inserted::Yes => return true,
                Inserted::AlreadyThere => return false,
                Inserted::Full => {
                    let mut list = s.0.to_vec();
                    *s = Slots::NONE;
                    s.0[0] = SPILLED;
                    self.spill.insert(p, std::mem::take(&mut list));
                }
            }
        }
        let list = self.spill.entry(p).or_default();
        match list.binary_search(&k) {
            Ok(_) => false,
            Err(at) => {
                list.insert(at, k);
                true
            }
        }
    }

    /// Removes cluster `k` from particle `p`; false if it was not there.
    ///
    /// # Panics
    /// If `p` is out of range.
    pub fn remove(&mut self, p: u32, k: u32) -> bool {
        let s = &mut self.slots[p as usize];
        if !s.spilled() {
            return s.remove(k);
        }
        let Some(list) = self.spill.get_mut(&p) else {
            return false;
        };
        let Ok(at) = list.binary_search(&k) else {
            return false;
        };
        list.remove(at);
        if list.len() <= INLINE_KEYS {
            // back in place
            let mut inline = Slots::NONE;
            inline.0[..list.len()].copy_from_slice(list);
            *s = inline;
            self.spill.remove(&p);
        }
        true
    }

    /// Applies one change; returns whether it changed the index.
    pub fn change(&mut self, c: &IndexChange) -> bool {
        if c.add {
            self.add(c.particle, c.key)
        } else {
            self.remove(c.particle, c.key)
        }
    }

    /// Applies a batch of changes. A batch never both adds and removes one key at one
    /// particle, so its changes commute and the result does not depend on their order:
    /// large batches are sorted by block of particles (a counting sort) and the blocks
    /// edited in parallel, each in cache; the rare changes that need the side table
    /// follow in one sequential pass.
    pub fn apply(&mut self, changes: &[IndexChange]) {
        if changes.len() < PARALLEL_CHANGES {
            for c in changes {
                self.change(c);
            }
            return;
        }
        let blocks = self.slots.len().div_ceil(BLOCK);
        let mut start = vec![0u32; blocks + 1];
        for c in changes {
            start[c.particle as usize / BLOCK + 1] += 1;
        }
        for b in 0..blocks {
            start[b + 1] += start[b];
        }
        let mut next = start.clone();
        let mut by_block = vec![changes[0]; changes.len()];
        for c in changes {
            let slot = &mut next[c.particle as usize / BLOCK];
            by_block[*slot as usize] = *c;
            *slot += 1;
        }
        let deferred: Vec<IndexChange> = self
            .slots
            .par_chunks_mut(BLOCK)
            .enumerate()
            .flat_map_iter(|(b, slots)| {
                let base = b * BLOCK;
                let mut deferred = Vec::new();
                for c in &by_block[start[b] as usize..start[b + 1] as usize] {
                    let s = &mut slots[c.particle as usize - base];
                    let done = !s.spilled()
                        && if c.add {
                            s.insert(c.key) != Inserted::Full
                        } else {
                            s.remove(c.key);
                            true
                        };
                    if !done {
                        deferred.push(*c);
                    }
                }
                deferred
            })
            .collect();
        for c in &deferred {
            self.change(c);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn change(particle: u32, key: u32, add: bool) -> IndexChange {
        IndexChange { particle, key, add }
    }

    #[test]
    fn lists_stay_ascending_in_place_and_past_eight_keys() {
        let mut index = ClusterIndex::new(3);
        let mut model: Vec<Vec<u32>> = vec![Vec::new(); 3];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for step in 0..4000 {
            let (p, k) = (rng.random_range(0..3u32), rng.random_range(0..14u32));
            let list = &mut model[p as usize];
            if rng.random_bool(0.55) {
                let new = !list.contains(&k);
                if new {
                    list.push(k);
                    list.sort_unstable();
                }
                assert_eq!(index.add(p, k), new, "step {step}");
            } else {
                let there = list.contains(&k);
                list.retain(|x| *x != k);
                assert_eq!(index.remove(p, k), there, "step {step}");
            }
            for q in 0..3u32 {
                assert_eq!(index.clusters_of(q), model[q as usize], "step {step}");
            }
        }
        assert!(model.iter().any(|l| l.len() > INLINE_KEYS), "lists spilled");
        assert_eq!(index.clusters_of(3), &[] as &[u32], "out of range");
    }

    #[test]
    fn batches_large_and_small_agree_with_one_change_at_a_time() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for changes in [50, 30_000] {
            let particles = 3 * BLOCK + 17;
            // a random index (some lists past eight keys), then random changes that
            // never add and remove one pair
            let mut index = ClusterIndex::new(particles);
            for p in 0..particles as u32 {
                for _ in 0..rng.random_range(0..11) {
                    index.add(p, rng.random_range(0..40));
                }
            }
            let batch: Vec<IndexChange> = (0..changes)
                .map(|_| {
                    let key = rng.random_range(0..40);
                    change(rng.random_range(0..particles as u32), key, key % 2 == 0)
                })
                .collect();
            let mut expected = index.clone();
            for c in &batch {
                expected.change(c);
            }
            index.apply(&batch);
            for p in 0..particles as u32 {
                assert_eq!(index.clusters_of(p), expected.clusters_of(p), "{changes}");
            }
        }
    }
}
