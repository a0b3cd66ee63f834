//! A length compared with a limit from the length's square, without its square root,
//! where the answer is certain: the colliders' friction cone skips a root for each
//! particle that sticks.

/// The share of the limit's square below which a square is surely below it, whatever
/// the rounding of the limit's square (a few units in the last place of `f32` below 1).
const ROUNDING_MARGIN: f32 = 1.0 - 1.0 / (1 << 20) as f32;

/// The smallest limit whose square is a normal `f32`, so rounds by no more than
/// [`ROUNDING_MARGIN`] allows for (a subnormal square can round by far more).
const SMALLEST_LIMIT: f32 = 1e-18;

/// Whether `squared.sqrt() <= limit` surely holds, judged without the root: true only
/// when it holds, for every `f32` pair, infinities and NaN included. False, so that the
/// caller takes the root, also when the square is within a few units in the last place
/// of the limit's, when the limit is at most 1e-18 (some way above the limits whose
/// squares are subnormal), or NaN.
#[inline]
pub fn surely_within(squared: f32, limit: f32) -> bool {
    limit > SMALLEST_LIMIT && squared < limit * limit * ROUNDING_MARGIN
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Never true where the root says otherwise: squares a few ulps either side of a
    /// limit's square, random ones, limits from subnormal squares to overflowing ones,
    /// zero, negative, infinite and NaN. And true for nearly every square below the
    /// limit's by more than rounding, so that it spares roots.
    #[test]
    fn it_is_true_only_where_the_root_is_within_the_limit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(64);
        let special = [0.0, -0.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut spared = 0;
        for case in 0..400_000 {
            let limit = match case % 50 {
                0..6 => special[case % 6],
                _ => 10f32.powf(rng.random_range(-25.0..25.0)),
            };
            let square = match case % 3 {
                0 => limit * limit * (1.0 + rng.random_range(-8..=8) as f32 * f32::EPSILON),
                1 => f32::from_bits(
                    ((limit * limit).to_bits() as i64 + rng.random_range(-8..=8)) as u32,
                ),
                _ => limit * limit * rng.random_range(0.0..2.0),
            };
            let within = square.sqrt() <= limit;
            if surely_within(square, limit) {
                assert!(within, "case {case}: √{square:e} > {limit:e}");
            }
            let clearly_below = square < 0.999 * limit * limit;
            spared += usize::from(surely_within(square, limit) && clearly_below);
        }
        // a third of the cases are random squares up to twice the limit's, half of them
        // below it; of those, the limits in 1e-18..1.8e19 (three in four): about 50,000
        assert!(spared > 40_000, "only {spared} roots spared");
    }
}
