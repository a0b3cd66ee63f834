//! A cut drawn as a stroke across a view: the blade lies in the plane through the eye
//! and the stroke, reaching from just in front of the eye to past everything in view,
//! and turns about the eye from the stroke's first ray to its last — so it cuts what
//! the stroke crossed on the screen, at every depth, and nothing behind the eye.
//!
//! A tool set to these poses frame by frame is swept between them by the cut stage's
//! detection, which interpolates poses (lerp of the centre, slerp of the rotation).
//! Between two poses the blade's centre then runs along the chord of its arc about the
//! eye instead of the arc: turning by `θ` at a centre `r` from the eye, the sweep lies
//! at most `r·(1 − cos θ/2) ≈ r·θ²/8` off the exact fan, so the turn per frame is
//! bounded ([`MAX_TURN_PER_FRAME`]).

use super::tool::{Pose, ToolShape};
use crate::error::{CleaveError, MAX_COORDINATE, Result, check_vec_within};
use glam::{Mat3, Quat, Vec3};

/// Most a stroke's blade turns about the eye in one frame (radians): 2°, so a blade
/// centred 5 m from the eye strays at most 0.8 mm from the fan it should sweep.
pub const MAX_TURN_PER_FRAME: f32 = 2.0 * std::f32::consts::PI / 180.0;

/// Fewest frames a stroke's sweep takes, however short the stroke.
pub const MIN_STROKE_FRAMES: usize = 4;

/// The blade of a stroke and its poses, one per frame, first to last.
#[derive(Clone, Debug, PartialEq)]
pub struct StrokeCut {
    /// The blade: local X along the ray (the blade's reach), local Y the way it turns,
    /// local Z the normal of the stroke's plane.
    pub shape: ToolShape,
    /// Where the blade is at the end of each frame of the sweep; the first pose is
    /// where it starts.
    pub poses: Vec<Pose>,
}

/// The blade that cuts along a stroke seen from `eye`: from the ray toward `from` to
/// the ray toward `to` (directions, any length), reaching from `near` to `far` along
/// every ray between. An error when a value is not finite, `eye` lies beyond ±1e6 m,
/// a direction is zero, the two rays are parallel or opposite (no plane, or no turn
/// to make), or not `0 ≤ near < far ≤ 1e6`.
pub fn stroke_cut(eye: Vec3, from: Vec3, to: Vec3, near: f32, far: f32) -> Result<StrokeCut> {
    check_vec_within("stroke.eye", eye, &crate::error::POSITION)?;
    let direction = |field: &str, d: Vec3| {
        d.try_normalize()
            .ok_or_else(|| CleaveError::InvalidEntity(format!("{field}: {d} is not a direction")))
    };
    let (a, b) = (direction("stroke.from", from)?, direction("stroke.to", to)?);
    if !(near.is_finite() && far.is_finite() && 0.0 <= near && near < far && far <= MAX_COORDINATE)
    {
        return Err(CleaveError::InvalidEntity(format!(
            "stroke: reach {near}..{far} m (allowed 0 ≤ near < far ≤ 1e6)"
        )));
    }
    let normal = a.cross(b);
    let angle = a.angle_between(b);
    if normal.length() < 1e-6 || angle > std::f32::consts::PI - 1e-3 {
        return Err(CleaveError::InvalidEntity(
            "stroke: its two rays are parallel or opposite, so they span no blade".into(),
        ));
    }
    let normal = normal.normalize();
    let frames = ((angle / MAX_TURN_PER_FRAME).ceil() as usize).max(MIN_STROKE_FRAMES);
    let (middle, half_reach) = (0.5 * (near + far), 0.5 * (far - near));
    let poses = (0..=frames)
        .map(|k| {
            let ray = Quat::from_axis_angle(normal, angle * k as f32 / frames as f32) * a;
            Pose {
                position: eye + middle * ray,
                rotation: Quat::from_mat3(&Mat3::from_cols(ray, normal.cross(ray), normal)),
            }
        })
        .collect();
    Ok(StrokeCut {
        shape: ToolShape::Blade {
            half_width: half_reach,
            // thin across the turn: the sweep, not the blade, covers the stroke
            half_height: 1e-3 * half_reach.max(1.0),
        },
        poses,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_blade_turns_about_the_eye_in_the_strokes_plane_from_the_first_ray_to_the_last() {
        let eye = Vec3::new(0.3, 2.0, 5.0);
        let (from, to) = (Vec3::new(-0.5, -0.2, -1.0), Vec3::new(0.6, -0.4, -1.0));
        let cut = stroke_cut(eye, from, to, 0.5, 20.0).unwrap();
        let ToolShape::Blade { half_width, .. } = cut.shape else {
            panic!("a blade")
        };
        assert!((half_width - 9.75).abs() < 1e-5);
        let plane = from.cross(to).normalize();
        let angle = from.angle_between(to);
        assert_eq!(
            cut.poses.len(),
            (angle / MAX_TURN_PER_FRAME).ceil() as usize + 1
        );
        for (k, pose) in cut.poses.iter().enumerate() {
            let ray = pose.rotation * Vec3::X;
            // both ends of the blade on the ray through the eye, in the stroke's plane
            for (end, depth) in [(-half_width, 0.5), (half_width, 20.0)] {
                let x = pose.position + pose.rotation * Vec3::new(end, 0.0, 0.0);
                assert!((x - (eye + depth * ray)).length() < 1e-4, "pose {k}");
                assert!(plane.dot(x - eye).abs() < 1e-4, "pose {k}");
            }
            assert!((pose.rotation * Vec3::Z).dot(plane) > 1.0 - 1e-5);
            let expected = ray.angle_between(from.normalize());
            assert!((expected - angle * k as f32 / (cut.poses.len() - 1) as f32).abs() < 1e-4);
        }
        assert!((cut.poses[0].rotation * Vec3::X).dot(from.normalize()) > 1.0 - 1e-6);
        let last = cut.poses.last().unwrap();
        assert!((last.rotation * Vec3::X).dot(to.normalize()) > 1.0 - 1e-6);
    }

    #[test]
    fn a_stroke_without_a_plane_or_with_bad_numbers_is_refused() {
        let eye = Vec3::ZERO;
        let d = Vec3::NEG_Z;
        for (from, to, near, far) in [
            (d, d, 0.1, 10.0),
            (d, -d, 0.1, 10.0),
            (Vec3::ZERO, Vec3::X, 0.1, 10.0),
            (Vec3::new(f32::NAN, 0.0, -1.0), Vec3::X, 0.1, 10.0),
            (d, Vec3::X, 5.0, 1.0),
            (d, Vec3::X, -1.0, 1.0),
            (d, Vec3::X, 0.1, f32::INFINITY),
        ] {
            assert!(stroke_cut(eye, from, to, near, far).is_err(), "{from} {to}");
        }
        assert!(stroke_cut(Vec3::splat(f32::NAN), d, Vec3::X, 0.1, 1.0).is_err());
        assert!(stroke_cut(Vec3::splat(2e6), d, Vec3::X, 0.1, 1.0).is_err());
        // a short stroke still sweeps over a few frames
        let short = stroke_cut(eye, d, Vec3::new(1e-3, 0.0, -1.0), 0.1, 1.0).unwrap();
        assert_eq!(short.poses.len(), MIN_STROKE_FRAMES + 1);
    }
}
