//! The tests of the detect stage as plain functions: which particles come
//! within reach of a tool anywhere along its motion since the last frame
//! ([`particles_hit`]), and which edges a tool separates ([`edges_separated`]). Both are
//! exact for a translating tool (see [`crate::cut::tool::Sweep`]), whatever its speed.
//!
//! Particles are tested in blocks of [`BLOCK`] consecutive ones (the solver layout's
//! Morton order keeps a block compact): a block whose bounding ball cannot come within
//! reach of the tool during the motion is skipped whole, so a tool costs one test per
//! block away from its path and the full per-particle test only near it. The skip is
//! exact: the distance to what a tool sweeps is 1-Lipschitz, so no particle of a ball of
//! radius `r` around `c` is nearer to it than `d(c) − r`.

use crate::cut::tool::{BladePlane, CutMode, Pose, Sweep, ToolShape};
use crate::ecs::components::Tool;
use crate::geometry::convex::Convex;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use smallvec::SmallVec;

/// Particles culled together by one bounding ball.
pub const BLOCK: usize = 64;

/// A tool ready for point and edge tests: its motion since the last frame as
/// translations, its convex core and radius, its reach (half the cut width), and the
/// bounding box of everything it can touch.
#[derive(Clone, Debug)]
pub struct ToolSweep {
    core: Convex,
    radius: f32,
    reach: f32,
    mode: CutMode,
    sweep: Sweep,
    min: Vec3,
    max: Vec3,
    /// Largest coordinate magnitude of the sweep's positions plus the tool's size: the
    /// scale of the rounding in a distance computed against this tool.
    scale: f32,
    /// A blade's plane at the end of the motion.
    plane: Option<BladePlane>,
    /// Whether a blade stays in that one plane throughout the motion (turning about
    /// its normal, moving along the plane).
    in_plane: bool,
}

impl ToolSweep {
    /// The sweep of `tool` from pose `last` to `current`; `None` for a tool that cannot
    /// cut (invalid shape, cut width not finite and positive, or a non-finite pose).
    pub fn new(tool: &Tool, last: &Pose, current: &Pose) -> Option<Self> {
        let valid = tool.shape.validate().is_ok()
            && tool.cut_width.is_finite()
            && tool.cut_width > 0.0
            && current.is_finite()
            && last.is_finite();
        if !valid {
            return None;
        }
        let reach = tool.cut_width * 0.5;
        let bounding = tool.shape.bounding_radius();
        let sweep = Sweep::new(last, current, bounding, reach);
        let extent = Vec3::splat(bounding + reach + sweep.slack);
        let (lo, hi) = (
            last.position.min(current.position),
            last.position.max(current.position),
        );
        let far = lo.abs().max(hi.abs()).max_element();
        let (core, radius) = tool.shape.core();
        let plane = matches!(tool.shape, ToolShape::Blade { .. }).then(|| {
            let normal = current.rotation.normalize() * Vec3::Z;
            BladePlane {
                normal,
                offset: normal.dot(current.position),
            }
        });
        // a blade that turns about its normal and moves along its plane never leaves
        // it: then only an edge with its ends on both sides can be separated — a test
        // that also keeps the sweep's slack from severing edges that lie along the
        // plane (which would free the particles on it)
        let in_plane = plane.is_some_and(|p| {
            let before = last.rotation.normalize() * Vec3::Z;
            let moved = current.position - last.position;
            before.dot(p.normal) > 1.0 - 1e-6 && p.normal.dot(moved).abs() <= 1e-6 * (1.0 + far)
        });
        Some(Self {
            plane,
            in_plane,
            core,
            radius,
            reach,
            mode: tool.mode,
            min: lo - extent,
            max: hi + extent,
            scale: far + bounding + reach,
            sweep,
        })
    }

    /// The tool's cut mode.
    pub fn mode(&self) -> CutMode {
        self.mode
    }

    /// A blade's plane where the motion ends (`None` for a sphere or a capsule): a
    /// particle it splits is split by side of this plane.
    pub fn blade_plane(&self) -> Option<BladePlane> {
        self.plane
    }

    /// Whether the point `x` comes within reach of the tool at some time of its motion.
    pub fn hits(&self, x: Vec3) -> bool {
        x.cmpge(self.min).all()
            && x.cmple(self.max).all()
            && self.sweep.point_distance(&self.core, x) - self.radius <= self.reach
    }

    /// Whether the tool's surface crosses the segment `a`–`b` with neither end inside
    /// the tool at any time of its motion: a blade (which has no inside) slicing between
    /// two particles, or a sphere grazing an edge past both its ends. The edges from a
    /// particle inside the tool to one outside are the carving's (see [`crate::cut::carve`]).
    /// The cut width plays no part: severing removes no material.
    pub fn separates(&self, a: Vec3, b: Vec3) -> bool {
        self.separates_at((a, self.surface_distance(a)), (b, self.surface_distance(b)))
    }

    /// Whether the segment `a`–`b` comes within reach of the tool at some time of its
    /// motion.
    pub fn reaches_segment(&self, a: Vec3, b: Vec3) -> bool {
        self.touches_box(a.min(b), a.max(b))
            && self.sweep.segment_distance(&self.core, a, b) - self.radius <= self.reach
    }

    /// [`Self::separates`] for ends whose [`Self::surface_distance`]s are known.
    pub fn separates_at(&self, (a, da): (Vec3, f32), (b, db): (Vec3, f32)) -> bool {
        if da < 0.0 || db < 0.0 {
            return false;
        }
        if let Some(plane) = self.plane.filter(|_| self.in_plane) {
            let (sa, sb) = (plane.distance(a), plane.distance(b));
            if !(sa < 0.0 && sb >= 0.0 || sb < 0.0 && sa >= 0.0) {
                return false;
            }
        }
        // every point of the segment lies within half its length of an end: when both
        // ends are farther than that, the segment cannot touch the tool (and the point
        // tests spare most edges the parallelogram test). The margin covers the
        // rounding of the distances: a segment crossing the blade at its middle has
        // both ends at exactly half its length.
        let margin = 1e-3 * a.distance(b) + self.rounding(a.abs().max(b.abs()).max_element());
        da.min(db) <= 0.5 * a.distance(b) + margin
            && self.sweep.segment_distance(&self.core, a, b) <= self.radius
    }

    /// A bound, with room to spare, on the rounding of a distance from this tool to a
    /// point whose largest coordinate magnitude is `magnitude`.
    fn rounding(&self, magnitude: f32) -> f32 {
        64.0 * f32::EPSILON * (magnitude + self.scale)
    }

    /// Whether `x` is inside the tool at some time of its motion (never for a blade).
    pub fn contains(&self, x: Vec3) -> bool {
        self.radius > 0.0 && self.surface_distance(x) < 0.0
    }

    /// Whether the tool has an inside (a sphere or a capsule: it carves when it severs).
    pub fn carves(&self) -> bool {
        self.radius > 0.0
    }

    /// The least distance from `x` to the tool's surface over the motion, negative when
    /// `x` is inside the tool at some time (never for a blade, whose distance is ≥ 0).
    pub fn surface_distance(&self, x: Vec3) -> f32 {
        let d = self.sweep.point_distance(&self.core, x) - self.radius;
        if self.radius > 0.0 { d } else { d.max(0.0) }
    }

    fn touches_box(&self, lo: Vec3, hi: Vec3) -> bool {
        hi.cmpge(self.min).all() && lo.cmple(self.max).all()
    }

    /// Whether some point of the ball `(centre, radius)` may come within reach of the
    /// tool; false only when none does. The ball is grown by a margin well above the
    /// rounding of the distances, so that a point [`Self::hits`] accepts is never
    /// culled.
    fn may_hit_ball(&self, centre: Vec3, radius: f32) -> bool {
        let margin = 1e-4 * (radius + self.reach) + self.rounding(centre.abs().max_element());
        let r = Vec3::splat(radius + margin);
        self.touches_box(centre - r, centre + r)
            && self.sweep.point_distance(&self.core, centre) - self.radius
                <= self.reach + radius + margin
    }
}

/// The live particles (indices into `positions`, ascending) that some tool hits. Blocks
/// of [`BLOCK`] particles run in parallel; the result does not depend on the thread
/// count. `live` has one flag per position.
pub fn particles_hit(positions: &[Vec3A], live: &[bool], tools: &[ToolSweep]) -> Vec<usize> {
    particles_where(positions, live, tools, ToolSweep::hits)
}

/// The live particles (ascending) inside some tool at some time of its motion
/// ([`ToolSweep::contains`]): what a carving tool carves.
pub fn particles_inside(positions: &[Vec3A], live: &[bool], tools: &[ToolSweep]) -> Vec<usize> {
    particles_where(positions, live, tools, ToolSweep::contains)
}

/// The live particles for which `test` holds with some tool, culled by blocks (`test`
/// must hold only within reach of the tool).
fn particles_where(
    positions: &[Vec3A],
    live: &[bool],
    tools: &[ToolSweep],
    test: impl Fn(&ToolSweep, Vec3) -> bool + Sync,
) -> Vec<usize> {
    if tools.is_empty() {
        return Vec::new();
    }
    positions
        .par_chunks(BLOCK)
        .zip(live.par_chunks(BLOCK))
        .enumerate()
        .with_min_len(64)
        .flat_map_iter(|(block, (positions, live))| {
            let (centre, radius) = bounding_ball(positions, live);
            let near: SmallVec<[&ToolSweep; 4]> = match radius {
                Some(r) => tools.iter().filter(|t| t.may_hit_ball(centre, r)).collect(),
                None => SmallVec::new(),
            };
            // a culled block's particles are not visited at all
            let tested = if near.is_empty() { 0 } else { positions.len() };
            let found: Vec<usize> = positions[..tested]
                .iter()
                .zip(live)
                .enumerate()
                .filter(|(_, (x, live))| **live && near.iter().any(|t| test(t, Vec3::from(**x))))
                .map(|(i, _)| block * BLOCK + i)
                .collect();
            found
        })
        .collect()
}

/// The edges some tool separates ([`ToolSweep::separates`]), among the edges from the
/// particles `range` of `positions` (dense indices) to their `partners` (the dense
/// indices of the particles linked along +x, +y and +z, `u32::MAX` where none, so that
/// each edge is tested once). Returns `(particle, partner)` pairs in ascending order.
/// Blocks of [`BLOCK`] particles are culled by a ball around their particles and
/// partners, and run in parallel; the result does not depend on the thread count.
pub fn edges_separated(
    positions: &[Vec3A],
    live: &[bool],
    range: std::ops::Range<usize>,
    partners: impl Fn(usize) -> [u32; 3] + Sync,
    tools: &[&ToolSweep],
) -> Vec<(usize, usize)> {
    if tools.is_empty() || range.is_empty() {
        return Vec::new();
    }
    let first = range.start;
    let blocks = range.len().div_ceil(BLOCK);
    (0..blocks)
        .into_par_iter()
        .with_min_len(16)
        .flat_map_iter(|block| {
            let start = first + block * BLOCK;
            let end = (start + BLOCK).min(range.end);
            // every edge of the block: its particles' and their partners' positions
            let mut edges: SmallVec<[(usize, usize); 3 * BLOCK]> = SmallVec::new();
            for i in (start..end).filter(|&i| live[i]) {
                for j in partners(i) {
                    if j != u32::MAX && live[j as usize] {
                        edges.push((i, j as usize));
                    }
                }
            }
            let (lo, hi) = edges.iter().flat_map(|&(i, j)| [i, j]).fold(
                (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
                |(lo, hi), k| {
                    let x = positions[k];
                    if x.is_finite() {
                        (lo.min(x), hi.max(x))
                    } else {
                        (lo, hi)
                    }
                },
            );
            let near: SmallVec<[&ToolSweep; 4]> = if lo.cmple(hi).all() {
                let centre = (lo + hi) * 0.5;
                let radius = (hi - centre).length();
                tools
                    .iter()
                    .copied()
                    .filter(|t| t.may_hit_ball(Vec3::from(centre), radius))
                    .collect()
            } else {
                SmallVec::new()
            };
            if near.is_empty() {
                edges.clear();
            }
            // each end's distance to each near tool once: most partners lie in the
            // block, whose particles' distances are kept
            let distances = |k: usize| -> SmallVec<[f32; 4]> {
                let x = Vec3::from(positions[k]);
                near.iter().map(|t| t.surface_distance(x)).collect()
            };
            let own: Vec<SmallVec<[f32; 4]>> = if edges.is_empty() {
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
            let kept: Vec<(usize, usize)> = edges
                .into_iter()
                .filter(|&(i, j)| {
                    let (a, b) = (Vec3::from(positions[i]), Vec3::from(positions[j]));
                    let (da, db) = (of(i), of(j));
                    near.iter()
                        .enumerate()
                        .any(|(t, tool)| tool.separates_at((a, da[t]), (b, db[t])))
                })
                .collect();
            kept
        })
        .collect()
}

/// Centre and radius of a ball around the live, finite positions of a block (the box's
/// centre and half diagonal); `None` radius when there is none. (A non-finite position
/// fails the box test of [`ToolSweep::hits`], so leaving it out culls nothing a full test
/// would find.)
fn bounding_ball(positions: &[Vec3A], live: &[bool]) -> (Vec3, Option<f32>) {
    let usable = |(x, l): &(&Vec3A, &bool)| **l && x.is_finite();
    let (lo, hi) = positions.iter().zip(live).filter(usable).fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), (x, _)| (lo.min(*x), hi.max(*x)),
    );
    if !lo.cmple(hi).all() {
        return (Vec3::ZERO, None);
    }
    let centre = (lo + hi) * 0.5;
    (Vec3::from(centre), Some((hi - centre).length()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;
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
            let shape = match case % 3 {
                0 => ToolShape::Sphere {
                    radius: rng.random_range(0.05..0.8),
                },
                1 => ToolShape::Capsule {
                    radius: rng.random_range(0.05..0.4),
                    half_length: rng.random_range(0.1..1.0),
                },
                _ => ToolShape::Blade {
                    half_width: rng.random_range(0.2..2.0),
                    half_height: rng.random_range(0.2..2.0),
                },
            };
            let tool = Tool {
                shape,
                cut_width: rng.random_range(0.01..0.3),
                mode: CutMode::Remove,
            };
            let (last, current) = (random_pose(&mut rng), random_pose(&mut rng));
            let tools: Vec<ToolSweep> =
                ToolSweep::new(&tool, &last, &current).into_iter().collect();
            let full: Vec<usize> = (0..positions.len())
                .filter(|&i| live[i] && tools[0].hits(Vec3::from(positions[i])))
                .collect();
            assert_eq!(
                particles_hit(&positions, &live, &tools),
                full,
                "case {case}"
            );
            hits += full.len();
            tested += positions.len();
        }
        // the cases exercise both hits and culled blocks
        assert!(hits > 0 && hits < tested / 2, "{hits} of {tested}");
    }

    #[test]
    fn edges_found_by_blocks_are_the_edges_that_cross_the_blade() {
        use crate::body::shape::Shape;
        let lattice = Shape::cuboid(glam::UVec3::splat(8)).voxelise(0.1).unwrap();
        let order = lattice.live_in_morton_order();
        let mut dense = vec![u32::MAX; lattice.len()];
        for (d, &p) in order.iter().enumerate() {
            dense[p as usize] = d as u32;
        }
        let positions: Vec<Vec3A> = order
            .iter()
            .map(|&p| Vec3A::from(lattice.rest_position(p)))
            .collect();
        let live = vec![true; positions.len()];
        let partners = |i: usize| {
            [1, 3, 5].map(|d| match lattice.link(order[i], d) {
                u32::MAX => u32::MAX,
                n => dense[n as usize],
            })
        };
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
            let found = edges_separated(&positions, &live, 0..positions.len(), partners, &[&sweep]);
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
