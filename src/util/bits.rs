//! The set bits of a bit array packed in 64-bit words, ascending: one reading for every
//! bit set in the crate (live particles, cell sets, marked edges).

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_set_bit_once_in_order() {
        let words = [0b1010u64, 0, 1 << 63 | 1];
        assert_eq!(set_bits(&words).collect::<Vec<_>>(), [1, 3, 128, 191]);
    }
}
