//! A stable radix sort of `(key, value)` pairs by their 64-bit key: the lattice orders
//! its particles with it, the contact grid its particles by cell, and the surface its
//! cut vertices by corner.

/// Sorts `(key, value)` pairs by key; pairs with equal keys keep their order (so a list
/// ordered by value comes out ordered by key, then value, as `sort_unstable` orders it).
/// A least-significant-digit radix sort over 11-bit digits of the key (skipping digits
/// that every key shares) for long lists, a comparison sort for short ones.
pub fn sort_by_key_radix(items: &mut Vec<(u64, u32)>) {
    const BITS: u32 = 11;
    const DIGITS: usize = 64_u32.div_ceil(BITS) as usize;
    const BUCKETS: usize = 1 << BITS;
    if items.len() < 4 * BUCKETS {
        items.sort_by_key(|(key, _)| *key);
        return;
    }
    let digit = |key: u64, d: usize| ((key >> (d as u32 * BITS)) as usize) & (BUCKETS - 1);
    let mut counts = vec![[0u32; BUCKETS]; DIGITS];
    for (key, _) in items.iter() {
        for (d, count) in counts.iter_mut().enumerate() {
            count[digit(*key, d)] += 1;
        }
    }
    let mut spare = vec![(0, 0); items.len()];
    for (d, count) in counts.iter_mut().enumerate() {
        if count.iter().any(|c| *c as usize == items.len()) {
            continue; // every key has this digit: the pass would change nothing
        }
        let mut start = 0;
        for c in count.iter_mut() {
            (*c, start) = (start, start + *c);
        }
        for &(key, value) in items.iter() {
            let slot = &mut count[digit(key, d)];
            spare[*slot as usize] = (key, value);
            *slot += 1;
        }
        std::mem::swap(items, &mut spare);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radix_sort_agrees_with_a_comparison_sort() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        for len in [0, 5, 9000, 40_000] {
            // keys in a narrow band (few digits differ) and over all 64 bits
            for spread in [1u64 << 20, u64::MAX] {
                let base: u64 = rng.random();
                let mut items: Vec<(u64, u32)> = (0..len)
                    .map(|i| (base.wrapping_add(rng.random_range(0..=spread / 2)), i))
                    .collect();
                let mut expected = items.clone();
                expected.sort_unstable();
                sort_by_key_radix(&mut items);
                assert_eq!(items, expected, "{len} keys, spread {spread}");
            }
        }
    }
}
