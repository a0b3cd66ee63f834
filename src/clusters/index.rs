//! The particle → clusters index of one body: for each particle the clusters that hold
//! it, as ascending `u32` keys.
//!
//! Eight keys are stored in place per particle, 32 bytes aligned to 32, so two
//! particles share a cache line and the usual edit (a key in, a key out) is a few
//! branch-free operations on eight slots. A particle in more clusters keeps its whole
//! list in a side table.

use crate::clusters::edits::IndexChange;
use crate::util::prefetch::prefetch;
use rustc_hash::FxHashMap;

/// Keys stored in place per particle.
pub const INLINE_KEYS: usize = 8;

/// The largest key the index holds (the two values above it mark slots).
pub const MAX_KEY: u32 = u32::MAX - 2;

/// An unused slot; sorts after every key.
const EMPTY: u32 = u32::MAX;

/// Slot 0 of a particle whose list lives in the side table.
const SPILLED: u32 = u32::MAX - 1;

/// How many changes ahead [`ClusterIndex::apply`] starts loading a particle's slots.
const PREFETCH_AHEAD: usize = 16;

/// One particle's keys in place: ascending, then [`EMPTY`] slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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

    /// Makes room for `particles` particles (new ones in no cluster); never shrinks.
    pub fn grow(&mut self, particles: usize) {
        if self.slots.len() < particles {
            self.slots.resize(particles, Slots::NONE);
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
    #[inline]
    pub fn add(&mut self, p: u32, k: u32) -> bool {
        debug_assert!(k <= MAX_KEY, "key {k} is a slot marker");
        let s = &mut self.slots[p as usize];
        if !s.spilled() {
            match s.insert(k) {
                Inserted::Yes => return true,
                Inserted::AlreadyThere => return false,
                Inserted::Full => {}
            }
        }
        self.add_spilled(p, k)
    }

    /// [`Self::add`] for a particle whose keys do not fit in place (rare: the side table
    /// takes them, moving them there first if they were in place).
    #[cold]
    #[inline(never)]
    fn add_spilled(&mut self, p: u32, k: u32) -> bool {
        let s = &mut self.slots[p as usize];
        let list = if s.spilled() {
            self.spill.entry(p).or_default()
        } else {
            // (room for twice the keys: a particle past eight usually gains a few more)
            let mut list = Vec::with_capacity(2 * INLINE_KEYS);
            list.extend_from_slice(&s.0);
            *s = Slots::NONE;
            s.0[0] = SPILLED;
            self.spill.entry(p).insert_entry(list).into_mut()
        };
        match list.binary_search(&k) {
            Ok(_) => false,
            Err(at) => {
                list.insert(at, k);
                true
            }
        }
    }

    /// Adds cluster `k` to every particle of `members`.
    ///
    /// # Panics
    /// If a member is out of range.
    pub fn add_cluster(&mut self, k: u32, members: &[u32]) {
        for &p in members {
            self.add(p, k);
        }
    }

    /// Removes cluster `k` from particle `p`; false if it was not there.
    ///
    /// # Panics
    /// If `p` is out of range.
    #[inline]
    pub fn remove(&mut self, p: u32, k: u32) -> bool {
        let s = &mut self.slots[p as usize];
        if !s.spilled() {
            return s.remove(k);
        }
        self.remove_spilled(p, k)
    }

    /// [`Self::remove`] for a particle whose keys are in the side table; they move back
    /// in place once they fit.
    #[cold]
    #[inline(never)]
    fn remove_spilled(&mut self, p: u32, k: u32) -> bool {
        let Some(list) = self.spill.get_mut(&p) else {
            return false;
        };
        let Ok(at) = list.binary_search(&k) else {
            return false;
        };
        list.remove(at);
        if list.len() <= INLINE_KEYS {
            let mut inline = Slots::NONE;
            inline.0[..list.len()].copy_from_slice(list);
            self.slots[p as usize] = inline;
            self.spill.remove(&p);
        }
        true
    }

    /// Applies one change; returns whether it changed the index.
    #[inline]
    pub fn change(&mut self, c: &IndexChange) -> bool {
        if c.add {
            self.add(c.particle, c.key)
        } else {
            self.remove(c.particle, c.key)
        }
    }

    /// Applies a batch of changes, in order. A batch's changes touch scattered
    /// particles; each particle's slots are requested a few changes ahead, so the cache
    /// misses overlap. (Sorting the changes by block of particles and editing blocks in
    /// parallel was measured three times slower at 64³ on two threads: the sort's
    /// scattered writes cost more than the second core saves.)
    pub fn apply(&mut self, changes: &[IndexChange]) {
        for (i, c) in changes.iter().enumerate() {
            if let Some(ahead) = changes.get(i + PREFETCH_AHEAD)
                && let Some(s) = self.slots.get(ahead.particle as usize)
            {
                prefetch(s);
            }
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
    fn a_batch_gives_the_lists_of_plain_set_operations() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let particles = 500;
        let mut index = ClusterIndex::new(particles);
        let mut model: Vec<std::collections::BTreeSet<u32>> = vec![Default::default(); particles];
        for round in 0..4 {
            // lists of up to twelve keys: some spill past eight, some come back
            let batch: Vec<IndexChange> = (0..5000)
                .map(|_| {
                    let key = rng.random_range(0..14);
                    change(
                        rng.random_range(0..particles as u32),
                        key,
                        rng.random_bool(0.5),
                    )
                })
                .collect();
            for c in &batch {
                let set = &mut model[c.particle as usize];
                if c.add {
                    set.insert(c.key);
                } else {
                    set.remove(&c.key);
                }
            }
            index.apply(&batch);
            for (p, set) in model.iter().enumerate() {
                let want: Vec<u32> = set.iter().copied().collect();
                assert_eq!(index.clusters_of(p as u32), want, "round {round}");
            }
        }
        assert!(model.iter().any(|s| s.len() > INLINE_KEYS));
    }
}
