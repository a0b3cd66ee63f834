//! Cutting tools: shapes with a signed distance in their local frame, poses, keyframed
//! paths, and the swept test that detection uses so a fast tool cannot skip particles.

use crate::error::{Result, check_finite_vec, check_positive, out_of_range};
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

    /// Checks that every size is finite and positive.
    pub fn validate(&self) -> Result<()> {
        match *self {
            ToolShape::Sphere { radius } => check_positive("tool.radius", radius),
            ToolShape::Capsule {
                radius,
                half_length,
            } => {
                check_positive("tool.radius", radius)?;
                check_positive("tool.half_length", half_length)
            }
            ToolShape::Blade {
                half_width,
                half_height,
            } => {
                check_positive("tool.half_width", half_width)?;
                check_positive("tool.half_height", half_height)
            }
        }
    }
}

/// A rigid pose.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Translation.
    pub position: Vec3,
    /// Orientation.
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
    /// Checks that times increase and every key is finite; the error names the key as
    /// `{owner}.path[i]` (`owner`: `tool`, `collider`).
    pub fn validate(&self, owner: &str) -> Result<()> {
        for (i, (t, pose)) in self.keys.iter().enumerate() {
            if !t.is_finite() {
                return Err(out_of_range(
                    &format!("{owner}.path[{i}].time"),
                    t,
                    "finite",
                ));
            }
            check_finite_vec(&format!("{owner}.path[{i}].position"), pose.position)?;
            if !pose.rotation.is_finite() || pose.rotation.length() < 1e-6 {
                return Err(out_of_range(
                    &format!("{owner}.path[{i}].rotation"),
                    pose.rotation,
                    "finite, non-zero quaternion",
                ));
            }
            if i > 0 && *t < self.keys[i - 1].0 {
                return Err(out_of_range(
                    &format!("{owner}.path[{i}].time"),
                    t,
                    "times in increasing order",
                ));
            }
        }
        Ok(())
    }

    /// Pose at time `t`, or `None` for an empty path.
    pub fn sample(&self, t: f32) -> Option<Pose> {
        let (first, last) = (self.keys.first()?, self.keys.last()?);
        if t <= first.0 {
            return Some(first.1);
        }
        if t >= last.0 {
            return Some(last.1);
        }
        let i = self.keys.partition_point(|(kt, _)| *kt <= t);
        let ((t0, p0), (t1, p1)) = (self.keys[i - 1], self.keys[i]);
        let span = t1 - t0;
        Some(if span > 0.0 {
            p0.lerp(&p1, (t - t0) / span)
        } else {
            p1
        })
    }
}

/// Poses sampled along the motion from `from` to `to`, close enough (≤ `step` apart at
/// any point of a tool of bounding radius `radius`) that the union of the samples'
/// cut zones covers the swept volume. At most 256 samples.
pub fn sweep_samples(from: &Pose, to: &Pose, radius: f32, step: f32) -> Vec<Pose> {
    let travel =
        from.position.distance(to.position) + from.rotation.angle_between(to.rotation) * radius;
    let n = if travel.is_finite() && step > 0.0 {
        (travel / step).ceil().clamp(1.0, 255.0) as usize
    } else {
        1
    };
    (0..=n)
        .map(|i| from.lerp(to, i as f32 / n as f32))
        .collect()
}

/// Poses sampled along a tool's motion, ready for point tests: each with the inverse
/// of its rotation, plus a bound on how far any tool point moves between neighbours.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// `(pose, inverse rotation)` per sample, in order along the motion.
    pub samples: Vec<(Pose, Quat)>,
    /// Upper bound on the distance any point of the tool moves from one sample to the
    /// next (0 for a tool at rest).
    pub step: f32,
}

impl Sweep {
    /// Samples the motion `from → to` of a tool of bounding radius `radius` so that no
    /// point moves more than `step` between samples (see [`sweep_samples`]).
    pub fn new(from: &Pose, to: &Pose, radius: f32, step: f32) -> Self {
        let poses = sweep_samples(from, to, radius, step);
        let travel =
            from.position.distance(to.position) + from.rotation.angle_between(to.rotation) * radius;
        let gaps = poses.len().saturating_sub(1).max(1) as f32;
        Self {
            step: if travel.is_finite() {
                travel / gaps
            } else {
                0.0
            },
            samples: poses
                .into_iter()
                .map(|p| (p, p.rotation.normalize().inverse()))
                .collect(),
        }
    }

    /// Whether `x` comes within `reach` of `shape`'s surface (or inside it) at some
    /// sample. A sample's signed distance changes by at most `step` from one sample to the
    /// next, so from a distance `d` the next `⌈(d − reach)/step⌉ − 1` samples cannot hit
    /// and are skipped: far particles cost a few tests instead of one per sample.
    pub fn hits(&self, shape: &ToolShape, x: Vec3, reach: f32) -> bool {
        let mut j = 0;
        while let Some((pose, inverse)) = self.samples.get(j) {
            let d = shape.signed_distance(*inverse * (x - pose.position));
            if d <= reach {
                return true;
            }
            if self.step <= 0.0 {
                return false;
            }
            let skip = ((d - reach) / self.step).ceil();
            j += if skip.is_finite() && skip > 1.0 {
                skip.min(self.samples.len() as f32) as usize
            } else {
                1
            };
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skipping_sweep_test_agrees_with_testing_every_sample() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let blade = ToolShape::Blade {
            half_width: 1.0,
            half_height: 0.2,
        };
        let from = Pose {
            position: Vec3::new(0.0, 3.0, 0.0),
            rotation: Quat::from_rotation_y(0.3),
        };
        let to = Pose {
            position: Vec3::new(0.5, -2.0, 0.2),
            rotation: Quat::from_rotation_y(1.1),
        };
        let reach = 0.05;
        let sweep = Sweep::new(&from, &to, blade.bounding_radius(), reach);
        let mut hits = 0;
        for _ in 0..20_000 {
            let x = Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-3.0..4.0),
                rng.random_range(-2.0..2.0),
            );
            let brute = sweep
                .samples
                .iter()
                .any(|(p, inv)| blade.signed_distance(*inv * (x - p.position)) <= reach);
            assert_eq!(sweep.hits(&blade, x, reach), brute, "{x}");
            hits += usize::from(brute);
        }
        assert!(
            hits > 100,
            "only {hits} hits: the test would not see a difference"
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
        assert!(ToolShape::Sphere { radius: 0.0 }.validate().is_err());
    }

    #[test]
    fn sweep_samples_are_dense_enough() {
        let s = sweep_samples(&Pose::at(Vec3::ZERO), &Pose::at(Vec3::X * 10.0), 1.0, 0.5);
        assert_eq!(s.len(), 21);
    }
}
