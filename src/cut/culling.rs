//! Conservative culling of the tool tests across frames (SPEC §6.2; Yuksel et al.
//! 2012): per block of particles ([`crate::cut::blocks`]) and per tool, how far apart
//! the last test found them, kept until the tool or the block may have moved that far.
//!
//! **What a block is tested in.** A box around its live particles, grown over the boxes
//! of the blocks that hold its particles' edge partners (an edge is tested from its lower
//! end's block, so the box must hold the whole edge). The own boxes are one pass over the
//! positions in memory order; the neighbour blocks are a table rebuilt once per layout
//! change. The tools are measured against the block's *frame*: that box, padded a
//! little, as it was when the block last left its frame. A block whose particles only
//! jiggle keeps its frame and every measurement against it; one that leaves it gets a
//! new frame, and each measurement shrinks by how far the new frame sticks out of the
//! old one (every point of the new frame lies that close to the old).
//!
//! **Why a skip is exact.** A block and a tool are measured by a lower bound on the
//! distance from any point of the frame to what the tool reaches over its motion
//! ([`ToolSweep::clearance_to_box`]). Later, every pose of the tool's sweep lies within
//! the tool's travel since then (its own odometer: the sum of its frames' moves, a
//! translation plus the turn times the tool's lever, [`ToolSweep::travel_from`]) of a
//! pose it was measured at, and the sweeps stand for their poses within their slack;
//! the distance to a tool is 1-Lipschitz. So no particle or edge of the block can be
//! reached by the tool while `clearance − travel − 2 × slack` stays positive, and the
//! pair's full tests are skipped until then.
//!
//! **Why per tool.** Each tool has its own odometer and its own column of measurements:
//! a tool parked beside a body costs nothing while another moves through it, and a tool
//! that appears, vanishes or changes its shape forgets its own column only. A layout
//! rebuild (or edges linked again) forgets every measurement; a cut that only severs
//! keeps them (the particles keep their places and dense indices, and a block's partners
//! only become fewer).

use crate::cut::blocks::{Blocks, DenseParticles, box_around};
use crate::cut::tool::Pose;
use crate::cut::tool_sweep::ToolSweep;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use smallvec::SmallVec;

/// What the last full test of a block against a tool found.
#[derive(Clone, Copy, Debug)]
struct Measured {
    /// The lower bound on the distance from the block's frame to the tool then, less
    /// how far the frame has moved out since (`−∞`: test it).
    clearance: f32,
    /// The tool's odometer then.
    odometer: f64,
}

/// A pair not measured yet.
const UNMEASURED: Measured = Measured {
    clearance: f32::NEG_INFINITY,
    odometer: 0.0,
};

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Frame {
    lo: Vec3A,
    hi: Vec3A,
}

impl Frame {
    /// The box around the finite `points`, if there is one (see [`box_around`]).
    fn around(points: impl Iterator<Item = Vec3A>) -> Option<Self> {
        box_around(points).map(|(lo, hi)| Self { lo, hi })
    }

    fn union(self, other: Self) -> Self {
        Self {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    fn contains(&self, other: &Self) -> bool {
        self.lo.cmple(other.lo).all() && other.hi.cmple(self.hi).all()
    }

    /// Grown on every side by a 32nd of its longest side: room to jiggle in.
    fn padded(self) -> Self {
        let pad = Vec3A::splat((self.hi - self.lo).max_element() / 32.0);
        Self {
            lo: self.lo - pad,
            hi: self.hi + pad,
        }
    }

    /// How far the farthest point of `self` lies from `old`.
    fn sticks_out_of(&self, old: &Self) -> f32 {
        (self.hi - old.hi)
            .max(old.lo - self.lo)
            .max(Vec3A::ZERO)
            .length()
    }
}

/// A tool as the culling follows it from frame to frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FollowedTool {
    /// The tool's id (its entity's bits).
    pub id: u64,
    /// Whether its shape, width or mode changed since the last frame.
    pub changed: bool,
    /// Where its motion of this frame ends.
    pub current: Pose,
}

/// A followed tool's odometer.
#[derive(Clone, Debug)]
struct Odometer {
    /// The tool's id.
    id: u64,
    /// Where its last frame's motion ended.
    pose: Pose,
    /// Its total travel so far (in f64, so that a long run does not round small moves
    /// away).
    travel: f64,
}

/// Which tools may reach which blocks this frame ([`ToolCulling::near_blocks`]): one
/// bit per block and tool, the tools in the order followed.
#[derive(Clone, Debug, Default)]
pub struct NearTools {
    tools: usize,
    words: usize,
    bits: Vec<u64>,
}

impl NearTools {
    /// The tools that may reach `block`, ascending; `None` for a block the table does
    /// not know (every tool may reach it).
    pub fn near(&self, block: usize) -> Option<impl Iterator<Item = usize> + '_> {
        let row = self
            .bits
            .get(block * self.words..(block + 1) * self.words)?;
        let set = |(w, bits): (usize, &u64)| {
            let mut bits = *bits;
            std::iter::from_fn(move || {
                let bit = (bits != 0).then(|| bits.trailing_zeros() as usize)?;
                bits &= bits - 1;
                Some(64 * w + bit)
            })
        };
        Some(row.iter().enumerate().flat_map(set))
    }

    /// How many tools the table has a column for.
    pub fn tools(&self) -> usize {
        self.tools
    }
}

/// The culling state of the detect stage: per block its frame and, per tool, what its
/// last test found; the blocks' neighbours; the tools' odometers.
#[derive(Clone, Debug, Default)]
pub struct ToolCulling {
    /// The layout the neighbour table was built for (`None`: none yet).
    layout: Option<u64>,
    /// Per block, the other blocks that hold partners of its particles: block `b`'s are
    /// `neighbours[starts[b]..starts[b + 1]]`.
    neighbours: Vec<u32>,
    starts: Vec<u32>,
    /// Per block, its frame (`None`: none yet).
    frames: Vec<Option<Frame>>,
    /// Per block a row, per tool followed a column: the last full test of the pair.
    measured: Vec<Measured>,
    /// The tools followed, in their order.
    tools: Vec<Odometer>,
    /// Pairs of a block and a tool measured in the last frame.
    pairs_measured: usize,
}

impl ToolCulling {
    /// Takes the layout `version` of the dense particles in `blocks`, whose particle `i`
    /// has the edge partners `partners(i)` (dense indices, `u32::MAX` for none); rebuilds
    /// the neighbour table and forgets every measurement when the version changed.
    pub fn set_layout(
        &mut self,
        version: u64,
        blocks: &Blocks,
        partners: impl Fn(usize) -> [u32; 3] + Sync,
    ) {
        if self.layout == Some(version) && self.frames.len() == blocks.len() {
            return;
        }
        self.layout = Some(version);
        // (a block's partners lie in a few blocks, most in its own: the block last
        // found is looked at before a search)
        let lists: Vec<SmallVec<[u32; 8]>> = (0..blocks.len())
            .into_par_iter()
            .with_min_len(16)
            .map(|b| {
                let mut list = SmallVec::new();
                let mut last = blocks.range(b);
                for j in blocks.range(b).flat_map(&partners) {
                    let j = j as usize;
                    if j == u32::MAX as usize || last.contains(&j) {
                        continue;
                    }
                    let n = blocks.of(j);
                    last = blocks.range(n);
                    if n != b && !list.contains(&(n as u32)) {
                        list.push(n as u32);
                    }
                }
                list
            })
            .collect();
        self.starts.clear();
        self.neighbours.clear();
        self.starts.push(0);
        for list in lists {
            self.neighbours.extend(list);
            self.starts.push(self.neighbours.len() as u32);
        }
        self.frames = vec![None; blocks.len()];
        self.measured = vec![UNMEASURED; blocks.len() * self.tools.len()];
    }

    /// Forgets the layout: the next [`ToolCulling::set_layout`] builds the neighbour
    /// table again and measures every block.
    pub fn forget_layout(&mut self) {
        self.layout = None;
    }

    /// Follows the tools into this frame, in this order: adds each one's travel to its
    /// odometer, and gives a tool that appeared, changed or moved by a non-finite amount
    /// a fresh column (the others keep theirs).
    pub fn follow(&mut self, tools: &[(FollowedTool, &ToolSweep)]) {
        let old = std::mem::take(&mut self.tools);
        // per tool, its old column and its travel since, when it keeps that column
        let kept: Vec<Option<(usize, f64)>> = tools
            .iter()
            .map(|(t, sweep)| {
                let c = old
                    .iter()
                    .position(|o| o.id == t.id)
                    .filter(|_| !t.changed)?;
                let travel = sweep.travel_from(&old[c].pose);
                travel
                    .is_finite()
                    .then_some((c, old[c].travel + travel as f64))
            })
            .collect();
        self.tools = (tools.iter().zip(&kept))
            .map(|((t, _), kept)| Odometer {
                id: t.id,
                pose: t.current,
                travel: kept.map_or(0.0, |(_, travel)| travel),
            })
            .collect();
        let unchanged = old.len() == tools.len()
            && kept
                .iter()
                .enumerate()
                .all(|(k, c)| c.is_some_and(|(c, _)| c == k));
        if unchanged {
            return;
        }
        let rows = self.frames.len();
        let before = std::mem::take(&mut self.measured);
        self.measured = (0..rows)
            .flat_map(|b| {
                let row = before.get(b * old.len()..(b + 1) * old.len());
                let at = move |c: usize| row.and_then(|row| row.get(c)).copied();
                kept.iter()
                    .map(move |c| c.and_then(|(c, _)| at(c)).unwrap_or(UNMEASURED))
            })
            .collect();
    }

    /// How many pairs of a block and a tool were measured in the last frame (the
    /// others were skipped on what their last tests found, or had no particle).
    pub fn measured(&self) -> usize {
        self.pairs_measured
    }

    /// Per block of `dense` (the blocks of the last [`Self::set_layout`]) and tool (those
    /// of the last [`Self::follow`], in its order): whether the tool may reach the block's
    /// particles or edges this frame (`false` only where it cannot). Pairs whose last
    /// measurement still holds are not measured at all; the others are, and keep what
    /// they found.
    pub fn near_blocks(&mut self, dense: DenseParticles, tools: &[&ToolSweep]) -> NearTools {
        self.pairs_measured = 0;
        let count = tools.len();
        if count != self.tools.len() || self.measured.len() != self.frames.len() * count {
            // not the tools followed: every tool may reach every block (a table of no
            // tools knows none)
            return NearTools::default();
        }
        let words = count.div_ceil(64);
        let mut near = NearTools {
            tools: count,
            words,
            bits: vec![0; self.frames.len() * words],
        };
        if count == 0 {
            return near;
        }
        let own: Vec<Option<Frame>> = (0..dense.blocks.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|b| {
                let (x, live) = dense.block(b);
                Frame::around(x.iter().zip(live).filter(|(_, l)| **l).map(|(x, _)| *x))
            })
            .collect();
        let slack: Vec<f32> = tools.iter().map(|t| t.slack()).collect();
        let odometers: Vec<f64> = self.tools.iter().map(|t| t.travel).collect();
        let (neighbours, starts) = (&self.neighbours, &self.starts);
        self.pairs_measured = (self.frames.par_iter_mut())
            .zip(self.measured.par_chunks_mut(count))
            .zip(near.bits.par_chunks_mut(words))
            .enumerate()
            .with_min_len(16)
            .map(|(b, ((frame, row), bits))| {
                let Some(Some(mut grown)) = own.get(b).copied() else {
                    // no live, finite particle: nothing to reach from this block
                    return 0;
                };
                // the box grown over the neighbour blocks' (partners lie in them)
                for &n in &neighbours[starts[b] as usize..starts[b + 1] as usize] {
                    if let Some(Some(other)) = own.get(n as usize) {
                        grown = grown.union(*other);
                    }
                }
                let framed = match *frame {
                    Some(f) if f.contains(&grown) => f,
                    Some(f) => {
                        let new = grown.padded();
                        let out = new.sticks_out_of(&f) * (1.0 + 1e-4);
                        row.iter_mut().for_each(|m| m.clearance -= out);
                        new
                    }
                    None => {
                        row.fill(UNMEASURED);
                        grown.padded()
                    }
                };
                *frame = Some(framed);
                let mut measured = 0;
                for (k, m) in row.iter_mut().enumerate() {
                    // (the factor covers the margins' share of the moves)
                    let travel = (odometers[k] - m.odometer) as f32;
                    if m.clearance - travel * (1.0 + 1e-4) - 2.0 * slack[k] > 0.0 {
                        continue;
                    }
                    let clearance =
                        tools[k].clearance_to_box(Vec3::from(framed.lo), Vec3::from(framed.hi));
                    *m = Measured {
                        clearance,
                        odometer: odometers[k],
                    };
                    measured += 1;
                    // (a NaN clearance is near)
                    if clearance <= 0.0 || clearance.is_nan() {
                        bits[k / 64] |= 1 << (k % 64);
                    }
                }
                measured
            })
            .sum();
        near
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::detection::{Reported, edges_separated, morton_cube, particles_hit};
    use crate::cut::tool::Tool;
    use crate::cut::tool::{CutMode, ToolShape};
    use glam::Quat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn culled_tests_find_exactly_what_full_tests_find_while_skipping_far_blocks() {
        // a 16³ block in the layout's Morton order, its particles drifting and a few
        // jumping; a sphere and a turning blade wander from far away through it and out
        let (mut positions, partner_table) = morton_cube(16);
        let partners = |i: usize| partner_table[i];
        let live: Vec<bool> = (0..positions.len()).map(|i| i % 13 != 0).collect();
        let tools = [
            Tool {
                shape: ToolShape::Sphere { radius: 0.15 },
                cut_width: 0.05,
                mode: CutMode::Remove,
            },
            Tool {
                shape: ToolShape::Blade {
                    half_width: 0.4,
                    half_height: 0.2,
                },
                cut_width: 0.01,
                mode: CutMode::Sever,
            },
        ];
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut culling = ToolCulling::default();
        let blocks = Blocks::uniform(positions.len());
        culling.set_layout(1, &blocks, partners);
        let (mut hits, mut severed, mut skipped_frames) = (0, 0, 0);
        let pose = |t: f32, k: usize| Pose {
            // from 6 m away, through the block around t = 0.5, and out again
            position: Vec3::new(6.0 - 12.0 * t, 0.8 + 0.1 * k as f32, 0.8),
            rotation: Quat::from_rotation_y(2.0 * t * k as f32),
        };
        let frames = 120;
        for frame in 0..frames {
            for x in positions.iter_mut() {
                let step = if rng.random_bool(0.001) { 0.3 } else { 0.002 };
                *x += Vec3A::new(rng.random(), rng.random(), rng.random()) * step - step / 2.0;
            }
            let (t0, t1) = (
                frame as f32 / frames as f32,
                (frame + 1) as f32 / frames as f32,
            );
            let sweeps: Vec<(FollowedTool, ToolSweep)> = tools
                .iter()
                .enumerate()
                .map(|(k, tool)| {
                    let (last, current) = (pose(t0, k), pose(t1, k));
                    let followed = FollowedTool {
                        id: k as u64,
                        changed: false,
                        current,
                    };
                    (followed, ToolSweep::new(tool, &last, &current).unwrap())
                })
                .collect();
            let pairs: Vec<(FollowedTool, &ToolSweep)> =
                sweeps.iter().map(|(t, s)| (t.clone(), s)).collect();
            culling.follow(&pairs);
            let all: Vec<&ToolSweep> = sweeps.iter().map(|(_, s)| s).collect();
            let dense = DenseParticles {
                positions: &positions,
                live: &live,
                blocks: &blocks,
            };
            let near = culling.near_blocks(dense, &all);
            if culling.measured() < blocks.len() {
                skipped_frames += 1;
            }
            // each tool tested alone, by its column of the table
            let full = particles_hit(dense, &all[..1], None);
            let culled = particles_hit(dense, &all[..1], Some((&near, &[0])));
            assert_eq!(culled, full, "frame {frame}");
            let range = 0..positions.len();
            let first = Reported::FirstTool;
            let full_edges =
                edges_separated(dense, range.clone(), partners, &all[1..], None, first);
            let near = Some((&near, &[1][..]));
            let culled = edges_separated(dense, range, partners, &all[1..], near, first);
            assert_eq!(culled, full_edges, "frame {frame}");
            hits += full.len();
            severed += full_edges.len();
        }
        assert!(
            hits > 100 && severed > 100,
            "{hits} hits, {severed} severed"
        );
        assert!(
            skipped_frames > frames / 2,
            "{skipped_frames} frames skipped most blocks"
        );
    }

    #[test]
    fn a_parked_tool_is_not_measured_again_while_another_moves_or_a_third_appears() {
        // an 8³ cube jiggling in place; a sphere parked half a cell off its +x face; from
        // frame 10 a blade sliding along far from it; from frame 30 a second sphere
        let (mut positions, partner_table) = morton_cube(8);
        let partners = |i: usize| partner_table[i];
        let live = vec![true; positions.len()];
        let blocks = Blocks::uniform(positions.len());
        let tool = |shape| Tool {
            shape,
            cut_width: 0.02,
            mode: CutMode::Sever,
        };
        let sphere = tool(ToolShape::Sphere { radius: 0.2 });
        let blade = tool(ToolShape::Blade {
            half_width: 0.3,
            half_height: 0.3,
        });
        // (the cube's particles lie within ±0.35 of the origin)
        let parked = Pose::at(Vec3::new(0.35 + 0.05 + 0.2, 0.0, 0.0));
        let sliding = |frame: usize| Pose {
            position: Vec3::new(-4.0, frame as f32 * 0.05, 0.0),
            rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        };
        let far = Pose::at(Vec3::new(0.0, 6.0, 0.0));
        let mut culling = ToolCulling::default();
        culling.set_layout(1, &blocks, partners);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for frame in 0..40 {
            for x in positions.iter_mut() {
                *x += Vec3A::new(rng.random(), rng.random(), rng.random()) * 1e-4 - 0.5e-4;
            }
            let mut sweeps = vec![(parked, ToolSweep::new(&sphere, &parked, &parked))];
            if frame >= 10 {
                let (from, to) = (sliding(frame), sliding(frame + 1));
                sweeps.push((to, ToolSweep::new(&blade, &from, &to)));
            }
            if frame >= 30 {
                sweeps.push((far, ToolSweep::new(&sphere, &far, &far)));
            }
            let sweeps: Vec<(Pose, ToolSweep)> = (sweeps.into_iter())
                .map(|(pose, sweep)| (pose, sweep.expect("a valid tool")))
                .collect();
            let pairs: Vec<(FollowedTool, &ToolSweep)> = (sweeps.iter().enumerate())
                .map(|(id, (current, sweep))| {
                    let followed = FollowedTool {
                        id: id as u64,
                        changed: false,
                        current: *current,
                    };
                    (followed, sweep)
                })
                .collect();
            culling.follow(&pairs);
            let all: Vec<&ToolSweep> = pairs.iter().map(|(_, s)| *s).collect();
            let dense = DenseParticles {
                positions: &positions,
                live: &live,
                blocks: &blocks,
            };
            let near = culling.near_blocks(dense, &all);
            // every block measured against a tool when it appears, and never again
            let fresh = if [0, 10, 30].contains(&frame) {
                blocks.len()
            } else {
                0
            };
            assert_eq!(culling.measured(), fresh, "frame {frame}");
            assert!(
                (0..blocks.len()).all(|b| near.near(b).is_some_and(|mut n| n.all(|t| t != 0))),
                "frame {frame}"
            );
            // what the culled tests find is what the full tests find: nothing
            let range = 0..positions.len();
            let columns: Vec<usize> = (0..all.len()).collect();
            let near = Some((&near, &columns[..]));
            let first = Reported::FirstTool;
            let culled = edges_separated(dense, range.clone(), partners, &all, near, first);
            assert_eq!(
                culled,
                edges_separated(dense, range, partners, &all, None, first)
            );
            assert!(culled.is_empty(), "frame {frame}");
        }
        assert!(culling.tools[1].travel > 1.4 && culling.tools[0].travel == 0.0);
    }
}
