//! Z-order (Morton) keys of lattice coordinates, by which particles are ordered so that
//! neighbours in space are neighbours in memory.

use glam::IVec3;

/// Interleaves the bits of a lattice coordinate (offset to non-negative) into a
/// Z-order key: bit `b` of x, y, z lands at bit `3b`, `3b + 1`, `3b + 2`.
pub(super) fn morton_code(c: IVec3) -> u64 {
    /// A coordinate offset to non-negative (21 bits), its bits spread three apart.
    fn spread(v: i32) -> u64 {
        let mut x = (v as i64 + (1 << 20)) as u64 & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    }
    spread(c.x) | (spread(c.y) << 1) | (spread(c.z) << 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_codes_interleave_the_coordinate_bits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        // the lowest coordinate offsets to 0; one step in x, y, z sets bit 0, 1, 2
        let origin = IVec3::splat(-(1 << 20));
        assert_eq!(morton_code(origin), 0);
        assert_eq!(morton_code(origin + IVec3::X), 1);
        assert_eq!(morton_code(origin + IVec3::Y), 2);
        assert_eq!(morton_code(origin + IVec3::Z), 4);
        assert_eq!(morton_code(origin + IVec3::new(2, 0, 0)), 8);
        // bit by bit
        let reference = |c: IVec3| {
            let offset = (c + IVec3::splat(1 << 20)).to_array().map(|v| v as u64);
            (0..21).fold(0u64, |code, b| {
                (0..3).fold(code, |code, axis| {
                    code | (offset[axis] >> b & 1) << (3 * b + axis)
                })
            })
        };
        for _ in 0..10_000 {
            let c = IVec3::new(
                rng.random_range(-5000..5000),
                rng.random_range(-5000..5000),
                rng.random_range(-5000..5000),
            );
            assert_eq!(morton_code(c), reference(c), "{c}");
        }
    }
}
