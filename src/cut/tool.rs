//! Cutting tools: shapes with a signed distance in their local frame, poses, keyframed
//! paths, and the swept test that detection uses: exact for a translating tool, so a fast
//! tool cannot skip particles and cuts what a slow one cuts along the same path.

use crate::error::{MAX_SPEED, Result, SIZE, check_vec_within, out_of_range};
use crate::geometry::convex::{self, Convex};
use crate::math::rotation::unit_quaternion;
use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

/// Shape of a cutting tool in its local frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ToolShape {
    /// A ball.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// A capsule along the local X axis.
    Capsule {
        /// Radius.
        radius: f32,
        /// Half length of the shaft.
        half_length: f32,
    },
    /// A thin rectangle in the local XY plane (normal = local Z).
    Blade {
        /// Half size along local X.
        half_width: f32,
        /// Half size along local Y.
        half_height: f32,
    },
}

impl ToolShape {
    /// Signed distance from a local-frame point to the tool surface (negative inside).
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        match *self {
            ToolShape::Sphere { radius } => p.length() - radius,
            ToolShape::Capsule {
                radius,
                half_length,
            } => (p - Vec3::new(p.x.clamp(-half_length, half_length), 0.0, 0.0)).length() - radius,
            ToolShape::Blade {
                half_width,
                half_height,
            } => {
                let q = Vec3::new(
                    p.x.clamp(-half_width, half_width),
                    p.y.clamp(-half_height, half_height),
                    0.0,
                );
                (p - q).length()
            }
        }
    }

    /// The tool as a convex core and a radius: the tool is every point within the
    /// radius of the core (a sphere: its centre; a capsule: its axis; a blade: its
    /// rectangle, radius 0).
    pub fn core(&self) -> (Convex, f32) {
        match *self {
            ToolShape::Sphere { radius } => (Convex::point(Vec3::ZERO), radius),
            ToolShape::Capsule {
                radius,
                half_length,
            } => (
                Convex::segment(Vec3::X * -half_length, Vec3::X * half_length),
                radius,
            ),
            ToolShape::Blade {
                half_width: w,
                half_height: h,
            } => (
                Convex::quad(
                    Vec3::new(-w, -h, 0.0),
                    Vec3::new(w, -h, 0.0),
                    Vec3::new(w, h, 0.0),
                    Vec3::new(-w, h, 0.0),
                ),
                0.0,
            ),
        }
    }

    /// Radius of a ball around the tool origin that contains the tool.
    pub fn bounding_radius(&self) -> f32 {
        match *self {
            ToolShape::Sphere { radius } => radius,
            ToolShape::Capsule {
                radius,
                half_length,
            } => radius + half_length,
            ToolShape::Blade {
                half_width,
                half_height,
            } => half_width.hypot(half_height),
        }
    }

    /// Checks that every size is a [`SIZE`]; errors name `{field}.radius` and so on.
    pub fn validate(&self, field: &str) -> Result<()> {
        let sizes: &[(&str, f32)] = match self {
            ToolShape::Sphere { radius } => &[("radius", *radius)],
            ToolShape::Capsule {
                radius,
                half_length,
            } => &[("radius", *radius), ("half_length", *half_length)],
            ToolShape::Blade {
                half_width,
                half_height,
            } => &[("half_width", *half_width), ("half_height", *half_height)],
        };
        for (name, value) in sizes {
            // (the field's name is spelt out only for an error: every tool's sweep
            // checks its shape again each frame)
            if !SIZE.allows(f64::from(*value)) {
                SIZE.check(&format!("{field}.{name}"), *value)?;
            }
        }
        Ok(())
    }
}

/// A cutting tool: shape, cut width (how far from its surface `remove` and `split` reach)
/// and cut mode. Plain data of this layer; a tool entity carries it as its component.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tool {
    /// Shape in the local frame.
    pub shape: ToolShape,
    /// Width of the cut zone (> 0).
    pub cut_width: f32,
    /// What the tool does where it passes.
    pub mode: CutMode,
}

/// What a tool does to the body where it passes. In files, on the command line and in
/// JSON: `"remove"`, `"sever"`, `"split"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CutMode {
    /// Particles that come within reach of the tool are removed (their mass is lost).
    #[default]
    Remove,
    /// Every edge the tool separates is severed (see
    /// [`crate::cut::tool_sweep::ToolSweep::separates`]); no particle is removed, no mass is
    /// lost.
    Sever,
    /// A particle a blade passes through is split in two, one on each side of the blade,
    /// each with half the mass; its edges go to the half on their side, and every other
    /// edge the blade separates is severed. A sphere or capsule severs, as in `Sever`.
    Split,
}

crate::util::named_enum::named_enum!(CutMode, "cut mode", [
    Remove => "remove",
    Sever => "sever",
    Split => "split",
]);

/// The plane of a blade, `normal · x = offset`; its two sides are where
/// [`BladePlane::distance`] is ≥ 0 and where it is < 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BladePlane {
    /// Unit normal.
    pub normal: Vec3,
    /// `normal · x` on the plane.
    pub offset: f32,
}

impl BladePlane {
    /// The signed distance of `x` from the plane.
    pub fn distance(&self, x: Vec3) -> f32 {
        self.normal.dot(x) - self.offset
    }

    /// The same plane with its sides swapped.
    pub fn flipped(&self) -> Self {
        Self {
            normal: -self.normal,
            offset: -self.offset,
        }
    }
}

/// A rigid pose. A scene file writes it `(position: (x, y, z), rotation: (x, y, z, w))`,
/// the rotation optional.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Translation.
    pub position: Vec3,
    /// Orientation.
    #[serde(default)]
    pub rotation: Quat,
}

impl Pose {
    /// Pose at `position` with no rotation.
    pub fn at(position: Vec3) -> Self {
        Self {
            position,
            rotation: Quat::IDENTITY,
        }
    }

    /// Whether translation and rotation are finite.
    pub fn is_finite(&self) -> bool {
        self.position.is_finite() && self.rotation.is_finite()
    }

    /// Interpolates between two poses (lerp / slerp).
    pub fn lerp(&self, other: &Pose, t: f32) -> Pose {
        Pose {
            position: self.position.lerp(other.position, t),
            rotation: self.rotation.slerp(other.rotation, t),
        }
    }
}

/// A keyframed path: poses at increasing times, linearly interpolated, held at the ends.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Path {
    /// `(time in seconds, pose)`, sorted by time.
    pub keys: Vec<(f32, Pose)>,
}

impl Path {
    /// Checks that times strictly increase, every key is finite and within the world's
    /// bounds (a rotation: finite and non-zero) and no stretch between two keys is faster
    /// than [`MAX_SPEED`]; the error names the key as `{owner}.path[i]` (`owner`: `tool`,
    /// `collider`, …).
    pub fn validate(&self, owner: &str) -> Result<()> {
        self.validate_keys(&format!("{owner}.path"))
    }

    /// [`Path::validate`], the error naming the key as `{field}[i]` (a scene file's
    /// reader gives an empty `field`).
    pub fn validate_keys(&self, field: &str) -> Result<()> {
        for (i, (t, pose)) in self.keys.iter().enumerate() {
            if !t.is_finite() {
                return Err(out_of_range(&format!("{field}[{i}].time"), t, "finite"));
            }
            check_vec_within(
                &format!("{field}[{i}].position"),
                pose.position,
                &crate::error::POSITION,
            )?;
            if unit_quaternion(pose.rotation).is_none() {
                return Err(out_of_range(
                    &format!("{field}[{i}].rotation"),
                    pose.rotation,
                    crate::error::ROTATION,
                ));
            }
            if let Some((before, from)) = i.checked_sub(1).map(|j| self.keys[j]) {
                if *t <= before {
                    return Err(out_of_range(
                        &format!("{field}[{i}].time"),
                        t,
                        "times strictly increasing (no two keys at one time)",
                    ));
                }
                let speed = (pose.position - from.position).length() / (t - before);
                if speed.is_nan() || speed > MAX_SPEED {
                    return Err(out_of_range(
                        &format!("{field}[{i}]"),
                        format_args!("{speed} m/s from the key before"),
                        "≤ 1e4 m/s between keys",
                    ));
                }
            }
        }
        Ok(())
    }

    /// The path with every key's rotation scaled to unit length (a key that is not a
    /// finite, non-zero quaternion stays as it is: [`Path::validate`] refuses it).
    pub fn normalized(&self) -> Path {
        let unit = |p: Pose| Pose {
            rotation: unit_quaternion(p.rotation).unwrap_or(p.rotation),
            ..p
        };
        Path {
            keys: self.keys.iter().map(|(t, p)| (*t, unit(*p))).collect(),
        }
    }

    /// Pose at time `t`, or `None` for an empty path.
    pub fn sample(&self, t: f32) -> Option<Pose> {
        crate::util::keyframes::sample(&self.keys, t, |a, b, s| a.lerp(b, s))
    }
}

/// Most pieces a rotating sweep is cut into; past it the pieces' slack grows instead
/// (the test stays conservative: it may cut more, never less).
pub const MAX_SWEEP_PIECES: usize = 4096;

/// One piece of a tool's motion: a translation from `from` to `to` with the rotation
/// held fixed (`inverse` is the inverse of that rotation).
#[derive(Clone, Copy, Debug)]
pub struct SweepPiece {
    /// Inverse of the piece's rotation.
    pub inverse: Quat,
    /// Position at the start of the piece.
    pub from: Vec3,
    /// Position at the end of the piece.
    pub to: Vec3,
}

impl SweepPiece {
    /// What the world point `x` traces in the tool's frame during the piece: a segment.
    pub fn trace_point(&self, x: Vec3) -> Convex {
        Convex::segment(self.inverse * (x - self.from), self.inverse * (x - self.to))
    }

    /// What the world segment `a`–`b` traces in the tool's frame: a parallelogram.
    pub fn trace_segment(&self, a: Vec3, b: Vec3) -> Convex {
        let (start, end) = (self.inverse * (-self.from), self.inverse * (-self.to));
        let (a, b) = (self.inverse * a, self.inverse * b);
        Convex::quad(a + start, b + start, b + end, a + end)
    }
}

/// A tool's motion from one pose to the next as translations: one piece when the
/// rotation does not change (then the test is exact), else pieces short enough that
/// holding each one's middle rotation moves no point of interest by more than `slack`.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The pieces, in order along the motion.
    pub pieces: Vec<SweepPiece>,
    /// How far holding a piece's rotation may misplace a point within `reach` of a tool
    /// of bounding radius `radius` (0 without rotation); the tests add it to the reach.
    pub slack: f32,
}

impl Sweep {
    /// The motion `from → to` (position lerp, rotation slerp, one parameter) of a tool
    /// of bounding radius `radius`, cut into pieces whose slack stays under a quarter of
    /// `reach` (up to [`MAX_SWEEP_PIECES`]).
    pub fn new(from: &Pose, to: &Pose, radius: f32, reach: f32) -> Self {
        let (r0, r1) = (from.rotation.normalize(), to.rotation.normalize());
        let angle = r0.angle_between(r1);
        let lever = radius + reach;
        if !(angle > 0.0 && angle.is_finite()) {
            return Self {
                pieces: vec![SweepPiece {
                    inverse: r0.inverse(),
                    from: from.position,
                    to: to.position,
                }],
                slack: 0.0,
            };
        }
        let wanted = (angle * lever / (0.25 * reach)).ceil();
        let count = if wanted.is_finite() {
            (wanted as usize).clamp(1, MAX_SWEEP_PIECES)
        } else {
            MAX_SWEEP_PIECES
        };
        let at = |i: usize| i as f32 / count as f32;
        Self {
            pieces: (0..count)
                .map(|i| SweepPiece {
                    inverse: r0
                        .slerp(r1, (at(i) + at(i + 1)) * 0.5)
                        .normalize()
                        .inverse(),
                    from: from.position.lerp(to.position, at(i)),
                    to: from.position.lerp(to.position, at(i + 1)),
                })
                .collect(),
            // half a piece's turn, at the lever of a point within reach of the tool
            slack: angle / (2 * count) as f32 * lever,
        }
    }

    /// The least distance from the world point `x` to the convex `core` (in the tool's
    /// frame) over the motion, less the slack.
    pub fn point_distance(&self, core: &Convex, x: Vec3) -> f32 {
        self.pieces
            .iter()
            .map(|p| convex::distance(&p.trace_point(x), core))
            .fold(f32::INFINITY, f32::min)
            - self.slack
    }

    /// The least distance from the world segment `a`–`b` to the convex `core` over the
    /// motion, less the slack.
    pub fn segment_distance(&self, core: &Convex, a: Vec3, b: Vec3) -> f32 {
        self.pieces
            .iter()
            .map(|p| convex::distance(&p.trace_segment(a, b), core))
            .fold(f32::INFINITY, f32::min)
            - self.slack
    }
}

/// A random sphere, capsule or blade (as `kind` is 0, 1 or other), of sizes up to about
/// 2 (for tests).
#[cfg(test)]
pub(crate) fn random_shape(rng: &mut impl rand::Rng, kind: usize) -> ToolShape {
    match kind {
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shape_with_a_size_out_of_range_is_refused_naming_that_size() {
        let blade = |half_width, half_height| ToolShape::Blade {
            half_width,
            half_height,
        };
        assert!(blade(0.5, 0.3).validate("tool").is_ok());
        for (shape, field) in [
            (blade(0.5, 0.0), "tool.half_height"),
            (blade(f32::NAN, 0.3), "tool.half_width"),
            (ToolShape::Sphere { radius: -1.0 }, "tool.radius"),
        ] {
            let error = shape.validate("tool").unwrap_err().to_string();
            assert!(error.contains(field), "{error}");
        }
    }

    /// `n + 1` poses evenly spaced along the motion, as (position, inverse rotation):
    /// a brute-force reference for the swept test.
    fn sampled_poses(from: &Pose, to: &Pose, n: usize) -> Vec<(Vec3, Quat)> {
        (0..=n)
            .map(|i| {
                let pose = from.lerp(to, i as f32 / n as f32);
                (pose.position, pose.rotation.normalize().inverse())
            })
            .collect()
    }

    fn sampled_hit(shape: &ToolShape, poses: &[(Vec3, Quat)], x: Vec3, reach: f32) -> bool {
        poses
            .iter()
            .any(|(c, inverse)| shape.signed_distance(*inverse * (x - *c)) <= reach)
    }

    #[test]
    fn the_swept_test_agrees_with_dense_sampling() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let shapes = [
            ToolShape::Blade {
                half_width: 1.0,
                half_height: 0.2,
            },
            ToolShape::Sphere { radius: 0.3 },
            ToolShape::Capsule {
                radius: 0.1,
                half_length: 0.6,
            },
        ];
        let (mut hits, mut doubtful) = (0, 0);
        for (k, shape) in shapes.iter().enumerate() {
            let from = Pose {
                position: Vec3::new(0.0, 3.0, 0.0),
                rotation: Quat::from_rotation_y(0.3),
            };
            for turn in [0.0, 0.8] {
                let to = Pose {
                    position: Vec3::new(0.5, -2.0, 0.2),
                    rotation: Quat::from_rotation_y(0.3 + turn),
                };
                let reach = 0.05;
                let sweep = Sweep::new(&from, &to, shape.bounding_radius(), reach);
                let (core, radius) = shape.core();
                let n = 3000;
                let poses = sampled_poses(&from, &to, n);
                for _ in 0..1000 {
                    let x = Vec3::new(
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-3.0..4.0),
                        rng.random_range(-2.0..2.0),
                    );
                    let exact = sweep.point_distance(&core, x) - radius <= reach;
                    // samples ~2e-3 apart: a point the sweep reaches is within reach of a
                    // sample grown by that spacing (and the slack); one within reach of a
                    // sample is reached by the sweep
                    let near = reach + 0.5 * 6.0 / n as f32 + 2.0 * sweep.slack;
                    if sampled_hit(shape, &poses, x, reach) {
                        assert!(exact, "shape {k}, turn {turn}: {x} missed");
                    }
                    if exact {
                        hits += 1;
                        if !sampled_hit(shape, &poses, x, near) {
                            doubtful += 1;
                        }
                    }
                }
            }
        }
        assert!(
            hits > 100 && doubtful == 0,
            "{hits} hits, {doubtful} unexplained"
        );
    }

    #[test]
    fn blade_distance_is_distance_to_rectangle() {
        let b = ToolShape::Blade {
            half_width: 1.0,
            half_height: 2.0,
        };
        assert_eq!(b.signed_distance(Vec3::new(0.5, 0.5, 0.3)), 0.3);
        assert!((b.signed_distance(Vec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn path_interpolates_and_validates() {
        let p = Path {
            keys: vec![(0.0, Pose::at(Vec3::ZERO)), (1.0, Pose::at(Vec3::X * 2.0))],
        };
        assert_eq!(p.sample(0.5).unwrap().position, Vec3::X);
        assert_eq!(p.sample(9.0).unwrap().position, Vec3::X * 2.0);
        p.validate("tool").unwrap();
        let bad = Path {
            keys: vec![(0.0, Pose::at(Vec3::new(f32::NAN, 0.0, 0.0)))],
        };
        assert!(
            bad.validate("tool")
                .unwrap_err()
                .to_string()
                .contains("tool.path[0].position")
        );
        assert!(ToolShape::Sphere { radius: 0.0 }.validate("tool").is_err());
    }
}
