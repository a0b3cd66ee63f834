//! The tests of the detect stage as plain functions: which particles come
//! within reach of a tool anywhere along its motion since the last frame
//! ([`particles_hit`]), and which edges a tool separates ([`edges_separated`]). Both are
//! exact for a translating tool (see [`crate::cut::tool::Sweep`]), whatever its speed.
//!
//! Particles are tested in blocks of consecutive ones that lie close together
//! ([`crate::cut::blocks`]): a block whose bounding ball cannot come within reach of the
//! tool during the motion is skipped whole, so a tool costs one test per block away
//! from its path and the full per-particle test only near it. The skip is exact: the
//! distance to what a tool sweeps is 1-Lipschitz, so no particle of a ball of radius `r`
//! around `c` is nearer to it than `d(c) − r`. Across frames, a block is tested only
//! against the tools that may have reached it since they were last measured
//! ([`NearBlocks`], kept by [`crate::cut::culling`]). Which blocks the particles fall
//! in changes how much is tested, never what is found.

use crate::cut::blocks::{BLOCK, DenseParticles, ball_around, bounding_ball};
use crate::cut::culling::NearTools;
use crate::cut::tool_sweep::ToolSweep;
use glam::Vec3;
use rayon::prelude::*;
use smallvec::SmallVec;
use std::ops::Not;

/// Which of the tools a test is given may reach which blocks of the dense particles:
/// the culling's table, and each tool's column in it, ascending (see
/// [`crate::cut::culling`]); `None`: every tool may reach every block.
pub type NearBlocks<'a> = Option<(&'a NearTools, &'a [usize])>;

/// The tools of `tools` (with their indices) that may reach block `b`: by the set bits
/// of the block's row when the table knows the block and every tool's column (the
/// columns ascend with the tools, as the detect stage groups them), else all.
fn tools_near<'t>(
    near: NearBlocks,
    b: usize,
    tools: &[&'t ToolSweep],
) -> SmallVec<[(usize, &'t ToolSweep); 4]> {
    let all = || tools.iter().copied().enumerate().collect();
    let Some((table, columns)) = near else {
        return all();
    };
    match table.near(b) {
        Some(near) if columns.iter().all(|&c| c < table.tools()) => near
            .filter_map(|c| columns.binary_search(&c).ok())
            .map(|k| (k, tools[k]))
            .collect(),
        _ => all(),
    }
}

/// The live particles (indices into the positions, ascending) that some tool hits.
/// Blocks run in parallel, those `near` marks far are skipped; the result does not
/// depend on the thread count.
pub fn particles_hit(dense: DenseParticles, tools: &[&ToolSweep], near: NearBlocks) -> Vec<usize> {
    particles_where(dense, tools, near, ToolSweep::hits)
}

/// The live particles (ascending) inside some tool at some time of its motion
/// ([`ToolSweep::contains`]): what a carving tool carves.
pub fn particles_inside(
    dense: DenseParticles,
    tools: &[&ToolSweep],
    near: NearBlocks,
) -> Vec<usize> {
    particles_where(dense, tools, near, ToolSweep::contains)
}

/// The live particles for which `test` holds with some tool, culled by blocks (`test`
/// must hold only within reach of the tool).
fn particles_where(
    dense: DenseParticles,
    tools: &[&ToolSweep],
    near_blocks: NearBlocks,
    test: impl Fn(&ToolSweep, Vec3) -> bool + Sync,
) -> Vec<usize> {
    if tools.is_empty() {
        return Vec::new();
    }
    (0..dense.blocks.len())
        .into_par_iter()
        .with_min_len(64)
        .flat_map_iter(|block| {
            let (positions, live) = dense.block(block);
            let mut near = tools_near(near_blocks, block, tools);
            if !near.is_empty() {
                match bounding_ball(positions, live) {
                    Some((centre, r)) => near.retain(|(_, t)| t.may_hit_ball(centre, r)),
                    None => near.clear(),
                }
            }
            // a culled block's particles are not visited at all
            let tested = if near.is_empty() { 0 } else { positions.len() };
            let first = dense.blocks.range(block).start;
            let found: Vec<usize> = positions[..tested]
                .iter()
                .zip(live)
                .enumerate()
                .filter(|(_, (x, live))| {
                    **live && near.iter().any(|(_, t)| test(t, Vec3::from(**x)))
                })
                .map(|(i, _)| first + i)
                .collect();
            found
        })
        .collect()
}

/// An edge a tool separates, found by [`edges_separated`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Separated {
    /// The edge's dense ends: a particle of the range tested, and its partner.
    pub ends: (usize, usize),
    /// Where `tool` crossed it ([`ToolSweep::crossing`]): the fraction from the first
    /// end, and the swept surface's unit normal (world frame).
    pub fraction: f32,
    /// See `fraction`.
    pub normal: Vec3,
    /// The tool that separates it (an index into the tools tested).
    pub tool: usize,
}

/// Which tools [`edges_separated`] reports for an edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reported {
    /// The first of the tools (in their order) that separates it.
    FirstTool,
    /// Every tool that separates it, in their order: what each of several tools
    /// separates, in one pass over the particles.
    EveryTool,
}

/// The edges some tool separates ([`ToolSweep::separates`]), among the edges from the
/// particles `range` of `dense` (dense indices) to their `partners` (the dense
/// indices of the particles linked along +x, +y and +z, `u32::MAX` where none, so that
/// each edge is tested once), each with the tool that separates it (as `reported` says)
/// and where it crossed it. In ascending order of their first end, then along +x, +y,
/// +z, then in the tools' order. The range is taken in `dense`'s blocks; blocks
/// `near` marks far are skipped, the others are culled by a ball
/// around their particles and partners, and run in parallel; the result does not depend
/// on the thread count.
///
/// A blade that stays in its plane ([`ToolSweep::in_plane`]) is tested in closed form
/// (a sign test per edge, then the crossing point against the blade's sweep); the other
/// tools by their distances to the edges' ends, then to the edges.
pub fn edges_separated(
    dense: DenseParticles,
    range: std::ops::Range<usize>,
    partners: impl Fn(usize) -> [u32; 3] + Sync,
    tools: &[&ToolSweep],
    near_blocks: NearBlocks,
    reported: Reported,
) -> Vec<Separated> {
    if tools.is_empty() || range.is_empty() {
        return Vec::new();
    }
    let (positions, live) = (dense.positions, dense.live);
    dense
        .blocks
        .overlapping(range.clone())
        .into_par_iter()
        .with_min_len(16)
        .flat_map_iter(|block| {
            // the tools that may reach the block, with their indices in `tools`
            let mut near = tools_near(near_blocks, block, tools);
            if near.is_empty() {
                return Vec::new();
            }
            let particles = dense.blocks.range(block);
            let start = particles.start.max(range.start);
            let end = particles.end.min(range.end);
            // every edge of the block: its particles' and their partners' positions
            let mut edges: SmallVec<[(usize, usize); 3 * BLOCK]> = SmallVec::new();
            for i in (start..end).filter(|&i| live[i]) {
                for j in partners(i) {
                    if j != u32::MAX && live[j as usize] {
                        edges.push((i, j as usize));
                    }
                }
            }
            let ends = edges
                .iter()
                .flat_map(|&(i, j)| [positions[i], positions[j]]);
            match ball_around(ends) {
                Some((centre, radius)) => near.retain(|(_, t)| t.may_hit_ball(centre, radius)),
                None => near.clear(),
            }
            if near.is_empty() {
                edges.clear();
            }
            // the tools not in one plane need each end's distance to them, once: most
            // partners lie in the block, whose particles' distances are kept
            let general: SmallVec<[usize; 4]> = (0..near.len())
                .filter(|&t| near[t].1.in_plane().is_none())
                .collect();
            let distances = |k: usize| -> SmallVec<[f32; 4]> {
                let x = Vec3::from(positions[k]);
                general
                    .iter()
                    .map(|&t| near[t].1.surface_distance(x))
                    .collect()
            };
            let own: Vec<SmallVec<[f32; 4]>> = if edges.is_empty() || general.is_empty() {
                Vec::new()
            } else {
                (start..end).map(distances).collect()
            };
            let of = |k: usize| {
                if (start..end).contains(&k) {
                    own[k - start].clone()
                } else {
                    distances(k)
                }
            };
            let kept: Vec<Separated> = edges
                .into_iter()
                .flat_map(|(i, j)| {
                    let (a, b) = (Vec3::from(positions[i]), Vec3::from(positions[j]));
                    let ends = general.is_empty().not().then(|| (of(i), of(j)));
                    let mut by = near.iter().enumerate().filter_map(|(t, &(index, tool))| {
                        let (fraction, normal) = match tool.in_plane() {
                            Some(plane) => (tool.plane_crossing(plane, a, b)?, plane.normal),
                            None => {
                                let (da, db) = ends.as_ref()?;
                                let g = general.iter().position(|&k| k == t)?;
                                if !tool.separates_at((a, da[g]), (b, db[g])) {
                                    return None;
                                }
                                tool.crossing(a, b)
                            }
                        };
                        Some(Separated {
                            ends: (i, j),
                            fraction,
                            normal,
                            tool: index,
                        })
                    });
                    let found: SmallVec<[Separated; 1]> = match reported {
                        Reported::EveryTool => by.collect(),
                        Reported::FirstTool => by.next().into_iter().collect(),
                    };
                    found
                })
                .collect();
            kept
        })
        .collect()
}

/// An n³ cube of spacing 0.1 in the layout's Morton order: its rest positions and
/// each particle's +x, +y, +z partners (dense indices, `u32::MAX` for none).
#[cfg(test)]
pub(crate) fn morton_cube(n: u32) -> (Vec<glam::Vec3A>, Vec<[u32; 3]>) {
    use crate::body::shape::Shape;
    let lattice = Shape::cuboid(glam::UVec3::splat(n))
        .voxelise(0.1)
        .expect("a small cube");
    let order = lattice.live_in_morton_order();
    let mut dense = vec![u32::MAX; lattice.len()];
    for (d, &p) in order.iter().enumerate() {
        dense[p as usize] = d as u32;
    }
    let positions = order
        .iter()
        .map(|&p| glam::Vec3A::from(lattice.rest_position(p)))
        .collect();
    let partners = order
        .iter()
        .map(|&p| {
            [1, 3, 5].map(|d| match lattice.link(p, d) {
                u32::MAX => u32::MAX,
                n => dense[n as usize],
            })
        })
        .collect();
    (positions, partners)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::blocks::Blocks;
    use crate::cut::tool::Tool;
    use crate::cut::tool::{CutMode, Pose, ToolShape};
    use glam::{Quat, Vec3A};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_pose(rng: &mut ChaCha8Rng) -> Pose {
        Pose {
            position: Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ),
            rotation: Quat::from_euler(
                glam::EulerRot::XYZ,
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
                rng.random_range(-0.6..0.6),
            ),
        }
    }

    /// Blocks of `n` particles: fixed runs for an even `case`, else runs of random
    /// lengths (1 to [`BLOCK`]), as a layout that straddles cubes has them.
    fn blocks(n: usize, case: usize, rng: &mut ChaCha8Rng) -> Blocks {
        if case.is_multiple_of(2) {
            return Blocks::uniform(n);
        }
        let mut run = 0;
        let runs: Vec<usize> = (0..n)
            .map(|_| {
                run += usize::from(rng.random_bool(0.05));
                run
            })
            .collect();
        Blocks::by_key(n, |i| runs[i])
    }

    #[test]
    fn culling_by_blocks_finds_exactly_the_particles_a_full_test_finds() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let (mut hits, mut tested) = (0, 0);
        for case in 0..60 {
            // a jittered lattice in blocks of 4×4×4 (like the layout's Morton order),
            // some particles dead
            let h = 0.1;
            let mut positions = Vec::new();
            for b in 0..(8 * 8 * 8) {
                let corner =
                    Vec3::new((b % 8) as f32, ((b / 8) % 8) as f32, (b / 64) as f32) * 4.0 * h
                        - Vec3::splat(1.6);
                for i in 0..BLOCK {
                    let cell = Vec3::new((i % 4) as f32, ((i / 4) % 4) as f32, (i / 16) as f32);
                    let jitter = Vec3::new(
                        rng.random_range(-0.3..0.3),
                        rng.random_range(-0.3..0.3),
                        rng.random_range(-0.3..0.3),
                    );
                    positions.push(Vec3A::from(corner + (cell + jitter) * h));
                }
            }
            let live: Vec<bool> = (0..positions.len()).map(|_| rng.random_bool(0.9)).collect();
            // a diverged particle must not hide its block's others
            for _ in 0..4 {
                let i = rng.random_range(0..positions.len());
                positions[i] = Vec3A::new(f32::NAN, 0.0, f32::INFINITY);
            }
            let shape = crate::cut::tool::random_shape(&mut rng, case % 3);
            let tool = Tool {
                shape,
                cut_width: rng.random_range(0.01..0.3),
                mode: CutMode::Remove,
            };
            let (last, current) = (random_pose(&mut rng), random_pose(&mut rng));
            let sweeps: Vec<ToolSweep> =
                ToolSweep::new(&tool, &last, &current).into_iter().collect();
            let tools: Vec<&ToolSweep> = sweeps.iter().collect();
            let full: Vec<usize> = (0..positions.len())
                .filter(|&i| live[i] && tools[0].hits(Vec3::from(positions[i])))
                .collect();
            let blocks = blocks(positions.len(), case / 3, &mut rng);
            let dense = DenseParticles {
                positions: &positions,
                live: &live,
                blocks: &blocks,
            };
            assert_eq!(particles_hit(dense, &tools, None), full, "case {case}");
            hits += full.len();
            tested += positions.len();
        }
        // the cases exercise both hits and culled blocks
        assert!(hits > 0 && hits < tested / 2, "{hits} of {tested}");
    }

    #[test]
    fn edges_found_by_blocks_are_the_edges_that_cross_the_blade() {
        let (positions, partner_table) = morton_cube(8);
        let live = vec![true; positions.len()];
        let partners = |i: usize| partner_table[i];
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for case in 0..40 {
            // the first case: a blade on the plane x = 0 between two layers of cells,
            // whose crossing edges have both ends at exactly half an edge from it
            let (rotation, offset) = if case == 0 {
                (
                    Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
                    Vec3::ZERO,
                )
            } else {
                let p = random_pose(&mut rng);
                (p.rotation, p.position * 0.2)
            };
            let along = rotation * Vec3::Y;
            let pose = |s: f32| Pose {
                position: offset + along * s,
                rotation,
            };
            let shape = if case % 2 == 0 {
                ToolShape::Blade {
                    half_width: 2.0,
                    half_height: 0.3,
                }
            } else {
                ToolShape::Sphere { radius: 0.2 }
            };
            let tool = Tool {
                shape,
                cut_width: 0.01,
                mode: CutMode::Sever,
            };
            let sweep = ToolSweep::new(&tool, &pose(2.0), &pose(-2.0)).unwrap();
            let blocks = blocks(positions.len(), case / 2, &mut rng);
            let dense = DenseParticles {
                positions: &positions,
                live: &live,
                blocks: &blocks,
            };
            let found: Vec<(usize, usize)> = edges_separated(
                dense,
                0..positions.len(),
                partners,
                &[&sweep],
                None,
                Reported::FirstTool,
            )
            .into_iter()
            .map(|s| s.ends)
            .collect();
            let mut brute = Vec::new();
            for i in 0..positions.len() {
                for j in partners(i).into_iter().filter(|j| *j != u32::MAX) {
                    let (a, b) = (Vec3::from(positions[i]), Vec3::from(positions[j as usize]));
                    if sweep.separates(a, b) {
                        brute.push((i, j as usize));
                    }
                }
            }
            assert_eq!(found, brute, "case {case}");
            if case == 0 {
                assert_eq!(found.len(), 64, "every x edge across the middle");
            }
        }
    }

    #[test]
    fn one_pass_for_several_tools_finds_what_each_finds_alone() {
        // blades and spheres crossing a cube: every tool's edges, in one pass, are those
        // it separates alone; the first tool's of each edge, those of the tools in order
        let (positions, partner_table) = morton_cube(8);
        let live = vec![true; positions.len()];
        let partners = |i: usize| partner_table[i];
        let all = 0..positions.len();
        let blocks = Blocks::uniform(positions.len());
        let dense = DenseParticles {
            positions: &positions,
            live: &live,
            blocks: &blocks,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let (mut found, mut shared) = (0, 0);
        for case in 0..20 {
            let sweeps: Vec<ToolSweep> = (0..4)
                .filter_map(|k| {
                    let shape = if k % 2 == 0 {
                        ToolShape::Blade {
                            half_width: rng.random_range(0.3..1.0),
                            half_height: 0.3,
                        }
                    } else {
                        ToolShape::Sphere {
                            radius: rng.random_range(0.1..0.3),
                        }
                    };
                    let tool = Tool {
                        shape,
                        cut_width: 0.01,
                        mode: CutMode::Sever,
                    };
                    // a tool translating across the cube
                    let (from, to) = (random_pose(&mut rng), random_pose(&mut rng));
                    let at = |p: Pose| Pose {
                        position: p.position * 0.3,
                        rotation: from.rotation,
                    };
                    ToolSweep::new(&tool, &at(from), &at(to))
                })
                .collect();
            let tools: Vec<&ToolSweep> = sweeps.iter().collect();
            let separated = |tools: &[&ToolSweep], reported| {
                edges_separated(dense, all.clone(), partners, tools, None, reported)
            };
            let each = separated(&tools, Reported::EveryTool);
            let mut alone: Vec<Separated> = (tools.iter().enumerate())
                .flat_map(|(t, tool)| {
                    separated(&[*tool], Reported::FirstTool)
                        .into_iter()
                        .map(move |s| Separated { tool: t, ..s })
                })
                .collect();
            // (an edge's tools follow each other, in order)
            let mut first = each.clone();
            first.dedup_by_key(|s| s.ends);
            let together = separated(&tools, Reported::FirstTool);
            assert!(together == first, "case {case}: the first tools differ");
            let mut each = each;
            each.sort_by_key(|s| (s.ends, s.tool));
            alone.sort_by_key(|s| (s.ends, s.tool));
            assert!(each == alone, "case {case}: the tools' edges differ");
            found += each.len();
            shared += each.len() - first.len();
        }
        // the cases hold edges that two tools separate
        assert!(shared > 0 && shared < found, "{shared} of {found}");
    }

    #[test]
    fn a_blade_turning_in_its_plane_separates_exactly_the_edges_across_the_plane() {
        use crate::body::shape::Shape;
        use crate::cut::stroke::stroke_cut;
        let lattice = Shape::cuboid(glam::UVec3::splat(8)).voxelise(0.1).unwrap();
        let positions: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|p| lattice.rest_position(p))
            .collect();
        let tool = |shape| Tool {
            shape,
            cut_width: 0.101,
            mode: CutMode::Sever,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for case in 0..6 {
            // a stroke seen from 3 m away whose fan covers the whole box
            let eye = random_pose(&mut rng).rotation * Vec3::new(0.0, 0.0, 3.0);
            let across = eye.any_orthonormal_vector();
            let (from, to) = (across - 0.3 * eye, -across - 0.3 * eye);
            let cut = stroke_cut(eye, from, to, 0.0, 5.0).unwrap();
            let normal = from.cross(to).normalize();
            let mut found = std::collections::BTreeSet::new();
            for pair in cut.poses.windows(2) {
                let sweep = ToolSweep::new(&tool(cut.shape), &pair[0], &pair[1]).unwrap();
                for (a, b) in lattice.edges() {
                    if sweep.separates(positions[a as usize], positions[b as usize]) {
                        found.insert((a, b));
                    }
                }
            }
            let side = |p: u32| normal.dot(positions[p as usize] - eye) < 0.0;
            let across: std::collections::BTreeSet<_> = lattice
                .edges()
                .into_iter()
                .filter(|&(a, b)| side(a) != side(b))
                .collect();
            assert!(!across.is_empty(), "case {case}");
            assert_eq!(found, across, "case {case}");
        }
    }

    #[test]
    fn a_tool_that_cannot_cut_is_refused() {
        let pose = Pose::at(Vec3::ZERO);
        let sphere = ToolShape::Sphere { radius: 1.0 };
        for cut_width in [0.0, -1.0, f32::NAN] {
            let tool = Tool {
                shape: sphere,
                cut_width,
                mode: CutMode::Remove,
            };
            assert!(ToolSweep::new(&tool, &pose, &pose).is_none());
        }
        let tool = Tool {
            shape: sphere,
            cut_width: 0.1,
            mode: CutMode::Remove,
        };
        let nan = Pose::at(Vec3::new(f32::NAN, 0.0, 0.0));
        assert!(ToolSweep::new(&tool, &nan, &pose).is_none());
        assert!(ToolSweep::new(&tool, &pose, &pose).is_some());
    }
}
