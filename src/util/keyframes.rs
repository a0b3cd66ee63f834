//! Sampling keyframes `(time, value)` (times ascending): a tool's or a collider's
//! path, a handle's keys.

/// The value at time `t`: the first key's before it, the last key's after it, else
/// `lerp(a, b, s)` between the two keys around `t` at fraction `s`; `None` for no keys.
pub fn sample<K: Copy>(keys: &[(f32, K)], t: f32, lerp: impl Fn(&K, &K, f32) -> K) -> Option<K> {
    let (first, last) = (keys.first()?, keys.last()?);
    if t <= first.0 {
        return Some(first.1);
    }
    if t >= last.0 {
        return Some(last.1);
    }
    let i = keys.partition_point(|(kt, _)| *kt <= t);
    let ((t0, a), (t1, b)) = (keys[i - 1], keys[i]);
    let span = t1 - t0;
    Some(if span > 0.0 {
        lerp(&a, &b, (t - t0) / span)
    } else {
        b
    })
}
