//! Frame times as a game feels them: the median, the 95th percentile and the slowest
//! frame of a run (and the slowest after the first, which pays for first touches), for
//! all frames and for a chosen subset such as the frames that cut.

use serde::Serialize;

/// Percentiles of a list of frame times, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// How many frames.
    pub frames: usize,
    /// The median frame (the upper median of an even count).
    pub median_ms: f64,
    /// The 95th percentile (nearest rank: the frame that 95 % of the frames are no
    /// slower than).
    pub p95_ms: f64,
    /// The slowest frame.
    pub max_ms: f64,
    /// The slowest frame after the first of the list.
    pub max_after_first_ms: f64,
}

impl FrameStats {
    /// The statistics of `frames` (in run order); all zero for none.
    pub fn of(frames: &[f64]) -> Self {
        if frames.is_empty() {
            return Self::default();
        }
        let mut sorted = frames.to_vec();
        sorted.sort_by(f64::total_cmp);
        let rank =
            |q: f64| sorted[((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1];
        Self {
            frames: frames.len(),
            median_ms: sorted[sorted.len() / 2],
            p95_ms: rank(0.95),
            max_ms: sorted[sorted.len() - 1],
            max_after_first_ms: frames[1..].iter().copied().fold(0.0, f64::max),
        }
    }

    /// The statistics of the frames of `frames` for which `keep` holds (by index).
    pub fn of_where(frames: &[f64], keep: impl Fn(usize) -> bool) -> Self {
        let kept: Vec<f64> = (0..frames.len())
            .filter(|&i| keep(i))
            .map(|i| frames[i])
            .collect();
        Self::of(&kept)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_are_nearest_ranks_of_the_frames() {
        // 1..=100 ms in a shuffled order, the slowest first
        let mut frames: Vec<f64> = (1..=100).map(|k| ((k * 37) % 100 + 1) as f64).collect();
        let slowest = frames.iter().position(|&f| f == 100.0).unwrap();
        frames.swap(0, slowest);
        let s = FrameStats::of(&frames);
        assert_eq!(s.frames, 100);
        assert_eq!(s.median_ms, 51.0);
        assert_eq!(s.p95_ms, 95.0);
        assert_eq!(s.max_ms, 100.0);
        assert_eq!(s.max_after_first_ms, 99.0);
        assert_eq!(FrameStats::of(&[]), FrameStats::default());
        let odd = FrameStats::of_where(&frames, |i| frames[i] as u32 % 2 == 1);
        assert_eq!((odd.frames, odd.max_ms), (50, 99.0));
    }
}
