//! Bit arrays packed in 64-bit words: the one reading of their set bits, ascending, for
//! every bit array in the crate (live particles, cell sets, marked edges), and [`Bits`],
//! a reusable set of small integers.

/// The indices of the set bits of `words` (bit `i % 64` of word `i / 64`), ascending.
#[inline]
pub fn set_bits(words: &[u64]) -> impl Iterator<Item = usize> + '_ {
    words.iter().enumerate().flat_map(|(k, &word)| {
        let mut w = word;
        std::iter::from_fn(move || {
            (w != 0).then(|| {
                let i = k * 64 + w.trailing_zeros() as usize;
                w &= w - 1;
                i
            })
        })
    })
}

/// A set of small integers as bits; the buffer is reused from use to use.
#[derive(Clone, Debug, Default)]
pub struct Bits(Vec<u64>);

impl Bits {
    /// Empties the set and makes room for the integers `0..n`.
    pub fn reset(&mut self, n: usize) {
        self.0.clear();
        self.0.resize(n.div_ceil(64), 0);
    }

    /// Adds `i`.
    #[inline]
    pub fn insert(&mut self, i: usize) {
        self.0[i >> 6] |= 1 << (i & 63);
    }

    /// Removes `i`.
    #[inline]
    pub fn remove(&mut self, i: usize) {
        self.0[i >> 6] &= !(1 << (i & 63));
    }

    /// Whether `i` is in the set.
    #[inline]
    pub fn contains(&self, i: usize) -> bool {
        self.0[i >> 6] >> (i & 63) & 1 != 0
    }

    /// Adds `i` to this set and, if it was not here, to `other` too (without a branch
    /// on whether it was: discovery loops meet both cases unpredictably).
    #[inline]
    pub fn insert_new_into(&mut self, i: usize, other: &mut Bits) {
        let (word, bit) = (i >> 6, 1u64 << (i & 63));
        other.0[word] |= bit & !self.0[word];
        self.0[word] |= bit;
    }

    /// The smallest integer in both this set and `other` (of the same size).
    #[inline]
    pub fn lowest_common(&self, other: &Bits) -> Option<usize> {
        self.0
            .iter()
            .zip(&other.0)
            .position(|(a, b)| a & b != 0)
            .map(|k| k * 64 + (self.0[k] & other.0[k]).trailing_zeros() as usize)
    }

    /// The member `i` with the smallest `keys[i]` (`None` for the empty set).
    #[inline]
    pub fn min_by_key(&self, keys: &[u64]) -> Option<usize> {
        let mut best = u64::MAX;
        let mut found = None;
        for i in self.ones() {
            // (a select, not a branch: which member wins is data)
            let smaller = keys[i] < best;
            best = if smaller { keys[i] } else { best };
            found = if smaller { Some(i) } else { found };
        }
        found
    }

    /// The smallest member.
    #[inline]
    pub fn lowest(&self) -> Option<usize> {
        self.0
            .iter()
            .position(|w| *w != 0)
            .map(|k| k * 64 + self.0[k].trailing_zeros() as usize)
    }

    /// The members, ascending.
    #[inline]
    pub fn ones(&self) -> impl Iterator<Item = usize> + '_ {
        set_bits(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_insert_remove_and_find_the_lowest() {
        let mut a = Bits::default();
        a.reset(130);
        assert_eq!(a.lowest(), None);
        for i in [129, 64, 3] {
            a.insert(i);
        }
        assert_eq!(a.lowest(), Some(3));
        a.remove(3);
        assert_eq!(a.lowest(), Some(64));
        assert!(a.contains(129) && !a.contains(128));
        let mut fresh = Bits::default();
        fresh.reset(130);
        a.insert_new_into(64, &mut fresh);
        a.insert_new_into(100, &mut fresh);
        assert!(a.contains(100) && fresh.contains(100) && !fresh.contains(64));
        a.reset(10);
        assert_eq!(a.lowest(), None);
    }

    #[test]
    fn every_set_bit_once_in_order() {
        let words = [0b1010u64, 0, 1 << 63 | 1];
        assert_eq!(set_bits(&words).collect::<Vec<_>>(), [1, 3, 128, 191]);
    }
}
