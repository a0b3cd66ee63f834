//! The dense particles in *blocks* for the tool tests: runs of consecutive dense
//! particles, each culled by one ball around it ([`crate::cut::detection`],
//! [`crate::cut::culling`]). A block's ball is only as good as the block is compact.
//!
//! Fixed runs of [`BLOCK`] particles are compact only while the runs line up with the
//! Morton order's aligned cubes of 4×4×4 cells. They do in an intact body; once a body
//! has lost particles or gained split halves and is laid out again, the runs straddle
//! cubes, and a run that straddles a jump of the Z-curve spans the body: every tool then
//! reaches it. So the layout's particles are cut into blocks where their cube changes
//! ([`Blocks::by_key`] with [`crate::body::lattice::Lattice::morton_cube`]), and a cube
//! that holds more than [`BLOCK`] particles (split halves) into runs of at most that.

use glam::{Vec3, Vec3A};
use std::ops::Range;

/// The most particles in one block (a full cube of 4×4×4 cells).
pub const BLOCK: usize = 64;

/// A partition of the dense particles `0..n` into consecutive blocks.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Blocks {
    /// Block `b` is `starts[b]..starts[b + 1]`; `starts[0] = 0`, the last is `n`.
    starts: Vec<u32>,
}

impl Blocks {
    /// Runs of [`BLOCK`] particles (the last one shorter).
    pub fn uniform(n: usize) -> Self {
        let mut starts: Vec<u32> = (0..n).step_by(BLOCK).map(|s| s as u32).collect();
        starts.push(n as u32);
        Self { starts }
    }

    /// A new block wherever `key(i)` differs from `key(i − 1)`, and after every
    /// [`BLOCK`] particles of one key (`key` is called once per particle, in order).
    pub fn by_key<K: PartialEq>(n: usize, mut key: impl FnMut(usize) -> K) -> Self {
        let mut starts = vec![0];
        let mut last = None;
        for i in 0..n {
            let k = key(i);
            let start = *starts.last().expect("starts with 0") as usize;
            if i > 0 && (last.as_ref() != Some(&k) || i - start == BLOCK) {
                starts.push(i as u32);
            }
            last = Some(k);
        }
        if n > 0 {
            starts.push(n as u32);
        }
        Self { starts }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of particles partitioned.
    pub fn particles(&self) -> usize {
        self.starts.last().map_or(0, |&n| n as usize)
    }

    /// The particles of block `b`.
    #[inline]
    pub fn range(&self, b: usize) -> Range<usize> {
        self.starts[b] as usize..self.starts[b + 1] as usize
    }

    /// The block of particle `i` (`i` < [`Self::particles`]).
    #[inline]
    pub fn of(&self, i: usize) -> usize {
        self.starts.partition_point(|&s| s as usize <= i) - 1
    }

    /// The blocks that hold some particle of `range` (`range.end` ≤
    /// [`Self::particles`]).
    pub fn overlapping(&self, range: Range<usize>) -> Range<usize> {
        if range.is_empty() {
            return 0..0;
        }
        self.of(range.start)..self.of(range.end - 1) + 1
    }
}

/// The dense particles the tool tests read: positions, whether each is live, and
/// their blocks.
#[derive(Clone, Copy, Debug)]
pub struct DenseParticles<'a> {
    /// Positions.
    pub positions: &'a [Vec3A],
    /// One flag per position.
    pub live: &'a [bool],
    /// The blocks the tests cull by (partitioning `positions`).
    pub blocks: &'a Blocks,
}

impl DenseParticles<'_> {
    /// The positions and live flags of block `b`.
    #[inline]
    pub fn block(&self, b: usize) -> (&[Vec3A], &[bool]) {
        let range = self.blocks.range(b);
        (&self.positions[range.clone()], &self.live[range])
    }
}

/// The ball around the live, finite `positions` (see [`ball_around`]).
pub fn bounding_ball(positions: &[Vec3A], live: &[bool]) -> Option<(Vec3, f32)> {
    ball_around(
        positions
            .iter()
            .zip(live)
            .filter(|(_, l)| **l)
            .map(|(x, _)| *x),
    )
}

/// The ball around the finite `points` (their box's centre and half diagonal), or
/// `None` when there is none (see [`box_around`]).
pub fn ball_around(points: impl Iterator<Item = Vec3A>) -> Option<(Vec3, f32)> {
    box_around(points).map(|(lo, hi)| {
        let centre = (lo + hi) * 0.5;
        (Vec3::from(centre), (hi - centre).length())
    })
}

/// The box `(lo, hi)` around the finite `points`, or `None` when there is none. (A
/// non-finite position fails every tool's box test, so leaving it out culls nothing a
/// full test would find.)
pub fn box_around(points: impl Iterator<Item = Vec3A>) -> Option<(Vec3A, Vec3A)> {
    let (lo, hi) = points.filter(|x| x.is_finite()).fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), x| (lo.min(x), hi.max(x)),
    );
    lo.cmple(hi).all().then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_by_key_break_where_the_key_changes_and_every_block_particles() {
        // keys: 3 × a, 150 × b, 1 × c, 64 × d
        let keys: Vec<char> = std::iter::repeat_n('a', 3)
            .chain(std::iter::repeat_n('b', 150))
            .chain(std::iter::once('c'))
            .chain(std::iter::repeat_n('d', 64))
            .collect();
        let blocks = Blocks::by_key(keys.len(), |i| keys[i]);
        let ranges: Vec<Range<usize>> = (0..blocks.len()).map(|b| blocks.range(b)).collect();
        assert_eq!(ranges, [0..3, 3..67, 67..131, 131..153, 153..154, 154..218]);
        assert_eq!(blocks.particles(), keys.len());
        for (b, r) in ranges.iter().enumerate() {
            for i in r.clone() {
                assert_eq!(blocks.of(i), b);
            }
        }
        assert_eq!(blocks.overlapping(60..132), 1..4);
        assert_eq!(blocks.overlapping(5..5), 0..0);
        assert!(Blocks::by_key(0, |_| 0).is_empty());
        let uniform = Blocks::uniform(130);
        assert_eq!(uniform.len(), 3);
        assert_eq!(uniform.range(2), 128..130);
        assert_eq!(uniform, Blocks::by_key(130, |_| ()));
    }
}
