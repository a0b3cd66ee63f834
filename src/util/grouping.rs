//! Values grouped by a small integer key into one flat list (a counting sort): no vector
//! per key, and each key's values in the order they were given.

/// Groups the `(key, value)` pairs that `pairs` yields (every key below `keys`): key
/// `k`'s values are `values[start[k]..start[k + 1]]`, in the order given. `pairs` is
/// walked twice, to count and to fill.
pub fn group_by_key<I>(keys: usize, pairs: impl Fn() -> I) -> (Vec<u32>, Vec<u32>)
where
    I: Iterator<Item = (u32, u32)>,
{
    let mut start = vec![0u32; keys + 1];
    for (k, _) in pairs() {
        start[k as usize + 1] += 1;
    }
    for k in 0..keys {
        start[k + 1] += start[k];
    }
    let mut filled = start.clone();
    let mut values = vec![0u32; start[keys] as usize];
    for (k, v) in pairs() {
        values[filled[k as usize] as usize] = v;
        filled[k as usize] += 1;
    }
    (start, values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_key_holds_its_values_in_the_order_given() {
        let pairs = [(2, 10), (0, 11), (2, 12), (3, 13), (0, 14)];
        let (start, values) = group_by_key(5, || pairs.iter().copied());
        assert_eq!(start, [0, 2, 2, 4, 5, 5]);
        assert_eq!(values, [11, 14, 10, 12, 13]);
    }
}
