//! A tool ready for the detect stage's tests: its motion since the last frame as
//! translations ([`crate::cut::tool::Sweep`]), what it reaches, and the distances from
//! points, segments and balls to it — exact for a translating tool, whatever its speed,
//! and conservative by the sweep's slack for a turning one.

use crate::cut::tool::{BladePlane, CutMode, Pose, Sweep, Tool, ToolShape};
use crate::geometry::convex::Convex;
use glam::Vec3;

/// The distance from the segment `from`–`to` to the rectangle `[−half, half]` (both in
/// the rectangle's plane): 0 when they meet.
fn rectangle_segment_distance(half: glam::Vec2, from: glam::Vec2, to: glam::Vec2) -> f32 {
    // clip the segment's parameter to the slab of each axis (Liang–Barsky)
    let d = to - from;
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for axis in 0..2 {
        let (p, q) = (from[axis], d[axis]);
        if q == 0.0 {
            if p.abs() > half[axis] {
                hi = -1.0;
            }
        } else {
            let (t0, t1) = ((-half[axis] - p) / q, (half[axis] - p) / q);
            lo = lo.max(t0.min(t1));
            hi = hi.min(t0.max(t1));
        }
    }
    if lo <= hi {
        return 0.0;
    }
    let to_rectangle = |x: glam::Vec2| (x.abs() - half).max(glam::Vec2::ZERO).length();
    let to_segment = |x: glam::Vec2| {
        let s = if d == glam::Vec2::ZERO {
            0.0
        } else {
            ((x - from).dot(d) / d.length_squared()).clamp(0.0, 1.0)
        };
        x.distance(from + s * d)
    };
    let corners = [
        glam::Vec2::new(-half.x, -half.y),
        glam::Vec2::new(half.x, -half.y),
        glam::Vec2::new(half.x, half.y),
        glam::Vec2::new(-half.x, half.y),
    ];
    corners
        .into_iter()
        .map(to_segment)
        .fold(to_rectangle(from).min(to_rectangle(to)), f32::min)
}

/// A tool ready for point and edge tests: its motion since the last frame as
/// translations, its convex core and radius, its reach (half the cut width), and the
/// bounding box of everything it can touch.
#[derive(Clone, Debug)]
pub struct ToolSweep {
    shape: ToolShape,
    core: Convex,
    radius: f32,
    reach: f32,
    mode: CutMode,
    sweep: Sweep,
    /// A box around everything the tool reaches over its motion.
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
    /// Where the motion starts and ends.
    last: Pose,
    current: Pose,
    /// How far from its position a point the tool reaches can be: a turn by θ moves
    /// such a point by at most θ times this.
    lever: f32,
}

impl ToolSweep {
    /// The sweep of `tool` from pose `last` to `current`; `None` for a tool that cannot
    /// cut (invalid shape, cut width not finite and positive, or a non-finite pose).
    pub fn new(tool: &Tool, last: &Pose, current: &Pose) -> Option<Self> {
        let valid = tool.shape.validate("tool").is_ok()
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
        let (lo, hi) = (
            last.position.min(current.position),
            last.position.max(current.position),
        );
        let far = lo.abs().max(hi.abs()).max_element();
        let (core, radius) = tool.shape.core();
        // the box around what each piece's core sweeps (its corners where the piece
        // starts and ends), grown by what the tool reaches around its core and by a
        // margin well above the rounding
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for piece in &sweep.pieces {
            let turn = piece.inverse.inverse();
            for &v in core.vertices() {
                for x in [piece.from + turn * v, piece.to + turn * v] {
                    (lo, hi) = (lo.min(x), hi.max(x));
                }
            }
        }
        let scale = far + bounding + reach;
        let grow = (radius + reach + sweep.slack) * (1.0 + 1e-4) + 128.0 * f32::EPSILON * scale;
        let extent = Vec3::splat(grow);
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
            shape: tool.shape,
            plane,
            in_plane,
            core,
            radius,
            reach,
            mode: tool.mode,
            min: lo - extent,
            max: hi + extent,
            scale,
            sweep,
            last: *last,
            current: *current,
            lever: bounding + reach,
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
            && self.point_distance(x) - self.radius <= self.reach
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
        if let Some(plane) = self.in_plane() {
            return self.plane_crossing(plane, a, b).is_some();
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

    /// The least distance from `x` to the tool's core over the motion, less the sweep's
    /// slack. A blade in one plane sweeps a flat set: the distance is the height over
    /// the plane and, in the plane, the distance of the point's trace in the blade's
    /// frame to the rectangle, piece by piece, in closed form.
    fn point_distance(&self, x: Vec3) -> f32 {
        let (
            Some(plane),
            ToolShape::Blade {
                half_width,
                half_height,
            },
        ) = (self.in_plane(), self.shape)
        else {
            return self.sweep.point_distance(&self.core, x);
        };
        let half = glam::Vec2::new(half_width, half_height);
        let across = self
            .sweep
            .pieces
            .iter()
            .map(|piece| {
                let from = (piece.inverse * (x - piece.from)).truncate();
                let to = (piece.inverse * (x - piece.to)).truncate();
                rectangle_segment_distance(half, from, to)
            })
            .fold(f32::INFINITY, f32::min);
        across.hypot(plane.distance(x)) - self.sweep.slack
    }

    /// The plane of a blade that stays in it throughout its motion (turning about its
    /// normal, moving along the plane); `None` for any other motion or tool. Such a
    /// blade separates exactly the edges whose ends lie on both sides of the plane and
    /// whose crossing point it passes over ([`Self::plane_crossing`]).
    pub fn in_plane(&self) -> Option<BladePlane> {
        self.plane.filter(|_| self.in_plane)
    }

    /// For a blade staying in `plane` ([`Self::in_plane`]): where along `a`–`b` (the
    /// fraction from `a`) the blade separates the segment, if it does — its ends lie on
    /// both sides of the plane (one on it counts as the positive side) and the point
    /// where it crosses the plane comes within the sweep's slack of the blade's
    /// rectangle at some time of the motion. Closed form: a sign test, then per piece
    /// of the motion the crossing point's trace in the blade's frame (a segment in its
    /// plane) against the rectangle.
    pub fn plane_crossing(&self, plane: BladePlane, a: Vec3, b: Vec3) -> Option<f32> {
        let (sa, sb) = (plane.distance(a), plane.distance(b));
        if !(sa < 0.0 && sb >= 0.0 || sb < 0.0 && sa >= 0.0) {
            return None;
        }
        let t = sa / (sa - sb);
        let x = a + t * (b - a);
        let ToolShape::Blade {
            half_width,
            half_height,
        } = self.shape
        else {
            return None;
        };
        let half = glam::Vec2::new(half_width, half_height);
        let slack = self.sweep.slack;
        self.sweep
            .pieces
            .iter()
            .any(|piece| {
                let from = (piece.inverse * (x - piece.from)).truncate();
                let to = (piece.inverse * (x - piece.to)).truncate();
                rectangle_segment_distance(half, from, to) <= slack
            })
            .then_some(t)
    }

    /// Where the tool's swept surface crosses the segment `a`–`b` — one it separates,
    /// or one from a particle inside the tool to one outside: the fraction along it from
    /// `a`, and the surface's unit normal there (world frame, either way round). A blade
    /// in one plane crosses where the segment meets the plane, with the plane's normal;
    /// otherwise the crossing is where the distance to what the tool sweeps changes sign
    /// along the segment, or the middle of the stretch the tool passes over, and its
    /// normal the distance's gradient there (a blade's: its plane's).
    pub fn crossing(&self, a: Vec3, b: Vec3) -> (f32, Vec3) {
        if let Some(plane) = self.in_plane() {
            let (sa, sb) = (plane.distance(a), plane.distance(b));
            let t = if sa == sb { 0.5 } else { sa / (sa - sb) };
            return (t.clamp(0.0, 1.0), plane.normal);
        }
        let along = |t: f32| self.surface_distance(a + t * (b - a));
        let t = crate::cut::crossings::touching_middle(
            along,
            self.rounding(a.abs().max(b.abs()).max_element()),
        );
        let x = a + t * (b - a);
        let normal = match self.plane {
            Some(plane) => plane.normal,
            None => {
                let step = 1e-3 * a.distance(b).max(f32::MIN_POSITIVE);
                let slope = |e: Vec3| {
                    self.surface_distance(x + step * e) - self.surface_distance(x - step * e)
                };
                Vec3::new(slope(Vec3::X), slope(Vec3::Y), slope(Vec3::Z))
                    .try_normalize()
                    .or_else(|| (b - a).try_normalize())
                    .unwrap_or(Vec3::X)
            }
        };
        (t, normal)
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
        let d = self.point_distance(x) - self.radius;
        if self.radius > 0.0 { d } else { d.max(0.0) }
    }

    fn touches_box(&self, lo: Vec3, hi: Vec3) -> bool {
        hi.cmpge(self.min).all() && lo.cmple(self.max).all()
    }

    /// A margin well above the rounding of the distances from a ball `(centre,
    /// radius)` to this tool.
    fn margin(&self, centre: Vec3, radius: f32) -> f32 {
        1e-4 * (radius + self.reach) + self.rounding(centre.abs().max_element())
    }

    /// Whether some point of the ball `(centre, radius)` may come within reach of the
    /// tool; false only when none does. The ball is grown by a margin well above the
    /// rounding of the distances, so that a point [`Self::hits`] accepts is never
    /// culled.
    pub(super) fn may_hit_ball(&self, centre: Vec3, radius: f32) -> bool {
        let r = Vec3::splat(radius + self.margin(centre, radius));
        self.touches_box(centre - r, centre + r) && self.gap(centre, radius) <= radius
    }

    /// The least distance from `centre` to what the tool reaches over its motion, less
    /// the margin of a ball of `radius` there: no point of that ball comes within reach
    /// when this is above `radius`.
    fn gap(&self, centre: Vec3, radius: f32) -> f32 {
        self.point_distance(centre) - self.radius - self.reach - self.margin(centre, radius)
    }

    /// A lower bound on the distance from every point of the box `lo`–`hi` to what the
    /// tool reaches over its motion, less a margin well above the rounding: no point of
    /// the box comes within reach when this is positive (see [`crate::cut::culling`]).
    /// The gap between the box and the tool's box (tight beside a face of the box), or
    /// where they overlap, the larger of that and the distance from the box's centre
    /// less its half diagonal (tight for a thin tool crossing the box's diagonal).
    pub fn clearance_to_box(&self, lo: Vec3, hi: Vec3) -> f32 {
        let centre = (lo + hi) * 0.5;
        let half_diagonal = (hi - centre).length();
        let apart = (self.min - hi).max(lo - self.max).max(Vec3::ZERO).length()
            - self.margin(centre, half_diagonal);
        if apart > 0.0 {
            return apart;
        }
        apart.max(self.gap(centre, half_diagonal) - half_diagonal)
    }

    /// How far its sweep stands off its poses (see [`crate::cut::tool::Sweep::slack`]).
    pub fn slack(&self) -> f32 {
        self.sweep.slack
    }

    /// How far, at most, what the tool reaches has moved from where it was at pose
    /// `before` to anywhere in this motion: the move from `before` to where the motion
    /// starts, and the motion itself, each a translation plus the turn times the lever.
    pub fn travel_from(&self, before: &Pose) -> f32 {
        let step = |a: &Pose, b: &Pose| {
            let angle = a.rotation.normalize().angle_between(b.rotation.normalize());
            a.position.distance(b.position) + angle * self.lever
        };
        step(before, &self.last) + step(&self.last, &self.current)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::tool::random_shape;
    use crate::geometry::convex::random_vec;
    use glam::Quat;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn every_point_a_turning_tool_reaches_lies_in_its_box_and_beyond_no_clearance() {
        // points the tool reaches at random times of its true motion (position lerp,
        // rotation slerp): a random point of its core, moved by up to its radius plus
        // its reach; each lies inside the tool's box, and a small box around it has no
        // positive clearance
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for case in 0..300 {
            let shape = random_shape(&mut rng, case % 3);
            let tool = Tool {
                shape,
                cut_width: rng.random_range(0.01..0.2),
                mode: CutMode::Sever,
            };
            let pose = |rng: &mut ChaCha8Rng| Pose {
                position: random_vec(rng, 3.0),
                rotation: Quat::from_scaled_axis(random_vec(rng, 1.5)),
            };
            let (last, current) = (pose(&mut rng), pose(&mut rng));
            let sweep = ToolSweep::new(&tool, &last, &current).expect("a valid tool");
            let (core, radius) = shape.core();
            for _ in 0..50 {
                let s = rng.random_range(0.0..=1.0f32);
                let position = last.position.lerp(current.position, s);
                let rotation = last.rotation.slerp(current.rotation, s);
                let weights: Vec<f32> = core.vertices().iter().map(|_| rng.random()).collect();
                let total: f32 = weights.iter().sum::<f32>().max(f32::MIN_POSITIVE);
                let on_core: Vec3 = (core.vertices().iter().zip(&weights))
                    .map(|(v, w)| *v * (w / total))
                    .sum();
                let off = random_vec(&mut rng, 1.0).normalize_or_zero()
                    * rng.random_range(0.0..=1.0f32)
                    * (radius + sweep.reach);
                let x = position + rotation * on_core + off;
                assert!(
                    x.cmpge(sweep.min).all() && x.cmple(sweep.max).all(),
                    "case {case}: {x} outside {}..{}",
                    sweep.min,
                    sweep.max
                );
                let tiny = Vec3::splat(1e-3);
                let clearance = sweep.clearance_to_box(x - tiny, x + tiny);
                assert!(clearance <= 0.0, "case {case}: clearance {clearance}");
            }
        }
    }
}
