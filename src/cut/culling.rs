//! Conservative culling of the tool tests across frames (SPEC §6.2; Yuksel et al.
//! 2012): per block of particles ([`crate::cut::blocks`]), the distance the last test
//! found between the block and every tool, kept until the tools or the block may have
//! moved that far.
//!
//! **What a block is tested in.** A ball around its live particles, grown to take in
//! the balls of the blocks that hold its particles' edge partners (an edge is tested
//! from its lower end's block, so the ball must cover the whole edge). The own balls
//! are one pass over the positions in memory order; the neighbour blocks are a table
//! rebuilt once per layout change.
//!
//! **Why a skip is exact.** When a block is tested, its *gap* is the least over the
//! tools of the swept distance from its ball's centre to what the tool reaches
//! ([`ToolSweep::gap`]). Later, every pose of a tool's sweep lies within the tool's
//! travel since then (the sum of its frames' moves, a translation plus the turn times
//! the tool's lever, [`ToolSweep::travel_from`]) of a pose it was tested at, and the
//! sweeps stand for their poses within their slack; the distance to a tool is
//! 1-Lipschitz. So no particle or edge of the block can be reached while
//! `gap − |centre moved| − radius − travel − 2 × slack` stays positive, and the block's
//! full tests are skipped until then. A tool that appears, vanishes or changes its
//! shape, and a layout rebuild (or edges linked again), forget every gap; a cut that
//! only severs keeps them (the particles keep their places and dense indices, and a
//! block's partners only become fewer).

use crate::cut::blocks::{Blocks, DenseParticles, bounding_ball};
use crate::cut::tool::Pose;
use crate::cut::tool_sweep::ToolSweep;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;

/// What the last full test of a block found.
#[derive(Clone, Copy, Debug)]
struct Tested {
    /// The centre of the block's ball then.
    centre: Vec3A,
    /// The least distance from that centre to what any tool could reach then.
    gap: f32,
    /// The tools' odometer then.
    odometer: f64,
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

/// The culling state of the detect stage: gaps per block, the blocks' neighbours, the
/// tools' odometer.
#[derive(Clone, Debug, Default)]
pub struct ToolCulling {
    /// The layout the neighbour table was built for (`None`: none yet).
    layout: Option<u64>,
    /// Per block, the other blocks that hold partners of its particles: block `b`'s are
    /// `neighbours[starts[b]..starts[b + 1]]`.
    neighbours: Vec<u32>,
    starts: Vec<u32>,
    /// Per block, the last full test (`None`: test it).
    tested: Vec<Option<Tested>>,
    /// Total travel of the tools so far (the largest tool's move each frame, summed; in
    /// f64 so that a long run does not round small moves away).
    odometer: f64,
    /// Each tool and where it ended the last frame, by id.
    tools: Vec<(u64, Pose)>,
    /// Blocks measured against the tools in the last frame.
    measured: usize,
}

impl ToolCulling {
    /// Takes the layout `version` of the dense particles in `blocks`, whose particle `i`
    /// has the edge partners `partners(i)` (dense indices, `u32::MAX` for none); rebuilds
    /// the neighbour table and forgets every gap when the version changed.
    pub fn set_layout(
        &mut self,
        version: u64,
        blocks: &Blocks,
        partners: impl Fn(usize) -> [u32; 3] + Sync,
    ) {
        if self.layout == Some(version) && self.tested.len() == blocks.len() {
            return;
        }
        self.layout = Some(version);
        let lists: Vec<Vec<u32>> = (0..blocks.len())
            .into_par_iter()
            .map(|b| {
                let mut list: Vec<u32> = (blocks.range(b))
                    .flat_map(&partners)
                    .filter(|&j| j != u32::MAX)
                    .map(|j| blocks.of(j as usize) as u32)
                    .filter(|&n| n as usize != b)
                    .collect();
                list.sort_unstable();
                list.dedup();
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
        self.tested = vec![None; blocks.len()];
    }

    /// Forgets the layout: the next [`ToolCulling::set_layout`] builds the neighbour
    /// table again and measures every block.
    pub fn forget_layout(&mut self) {
        self.layout = None;
    }

    /// Follows the tools into this frame: adds their travel to the odometer, and
    /// forgets every gap when a tool appeared, vanished or changed.
    pub fn follow(&mut self, tools: &[(FollowedTool, &ToolSweep)]) {
        let same = tools.len() == self.tools.len()
            && tools
                .iter()
                .zip(&self.tools)
                .all(|((t, _), (id, _))| t.id == *id && !t.changed);
        if same {
            let travel = tools
                .iter()
                .zip(&self.tools)
                .map(|((_, sweep), (_, before))| sweep.travel_from(before))
                .fold(0.0f32, f32::max);
            if travel.is_finite() {
                self.odometer += travel as f64;
            } else {
                self.forget();
            }
        } else {
            self.forget();
        }
        self.tools = tools.iter().map(|(t, _)| (t.id, t.current)).collect();
    }

    /// How many blocks were measured against the tools in the last frame (the others
    /// were skipped on their gaps, or had no particle).
    pub fn measured(&self) -> usize {
        self.measured
    }

    /// Forgets every gap: each block is measured again.
    fn forget(&mut self) {
        self.tested.iter_mut().for_each(|t| *t = None);
    }

    /// Per block of `dense` (the blocks of the last [`Self::set_layout`]): whether some
    /// tool may reach its particles or edges this frame (`false` only where none can).
    /// Blocks whose gap has not run out are not measured against the tools at all; the
    /// others are, and keep what they found.
    pub fn near_blocks(&mut self, dense: DenseParticles, tools: &[&ToolSweep]) -> Vec<bool> {
        self.measured = 0;
        if tools.is_empty() {
            return vec![false; self.tested.len()];
        }
        let own: Vec<Option<(Vec3A, f32)>> = (0..dense.blocks.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|b| {
                let (x, l) = dense.block(b);
                bounding_ball(x, l).map(|(c, r)| (Vec3A::from(c), r))
            })
            .collect();
        let slack = tools.iter().map(|t| t.slack()).fold(0.0f32, f32::max);
        let odometer = self.odometer;
        let (neighbours, starts) = (&self.neighbours, &self.starts);
        let near: Vec<(bool, bool)> = self
            .tested
            .par_iter_mut()
            .enumerate()
            .with_min_len(64)
            .map(|(b, tested)| {
                let Some((centre, own_radius)) = own[b] else {
                    // no live, finite particle: nothing to reach from this block
                    return (false, false);
                };
                // the ball grown over the neighbour blocks' balls (partners lie in them)
                let radius = neighbours[starts[b] as usize..starts[b + 1] as usize]
                    .iter()
                    .filter_map(|&n| own.get(n as usize).copied().flatten())
                    .fold(own_radius, |r, (c, rn)| r.max(c.distance(centre) + rn));
                if let Some(t) = tested {
                    // (the factor covers the margins' share of the moves, see
                    // `ToolSweep::gap`)
                    let moved = t.centre.distance(centre) + radius + (odometer - t.odometer) as f32;
                    let left = t.gap - moved * (1.0 + 1e-4) - 2.0 * slack;
                    if left > 0.0 {
                        return (false, false);
                    }
                }
                let gap = tools
                    .iter()
                    .map(|t| t.gap(Vec3::from(centre), radius))
                    .fold(f32::INFINITY, f32::min);
                *tested = Some(Tested {
                    centre,
                    gap,
                    odometer,
                });
                (gap <= radius, true)
            })
            .collect();
        self.measured = near.iter().filter(|(_, measured)| *measured).count();
        near.into_iter().map(|(near, _)| near).collect()
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
            if culling.measured() < blocks.len() / 2 {
                skipped_frames += 1;
            }
            let removers = [sweeps[0].1.clone()];
            let full = particles_hit(dense, &removers, None);
            assert_eq!(
                particles_hit(dense, &removers, Some(&near)),
                full,
                "frame {frame}"
            );
            let range = 0..positions.len();
            let first = Reported::FirstTool;
            let full_edges =
                edges_separated(dense, range.clone(), partners, &[all[1]], None, first);
            let culled = edges_separated(dense, range, partners, &[all[1]], Some(&near), first);
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
}
