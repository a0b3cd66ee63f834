//! Where a tool crossed an edge, as the lattice keeps it ([`Crossing`]): found on the
//! body as it is (world frame) by the detection's tests, then turned into the body's
//! rest frame by the rotation of the particles around the edge.

use crate::body::crossings::Crossing;
use crate::body::lattice::Lattice;
use crate::math::rotation::extract_rotation;
use glam::{Mat3, Mat3A, Quat, Vec3};

/// Iterations of the bisections and of the search for a least distance (each halves
/// the interval, or shrinks it by the golden ratio): well below a float's resolution of
/// an edge.
const ITERATIONS: u32 = 40;

/// Where along `[0, 1]` a tool's swept surface crosses a segment whose signed distance
/// to what the tool sweeps is `f(t)` at `t` (negative inside): where `f` changes sign
/// when one end is inside and the other not, else the middle of the stretch where `f`
/// is within `tolerance` of its least value or below zero (a blade passing over the
/// segment, a sphere grazing it).
pub fn touching_middle(f: impl Fn(f32) -> f32, tolerance: f32) -> f32 {
    let (f0, f1) = (f(0.0), f(1.0));
    let bisect = |mut outside: f32, mut inside: f32, is_inside: &dyn Fn(f32) -> bool| {
        for _ in 0..ITERATIONS {
            let mid = 0.5 * (outside + inside);
            if is_inside(mid) {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        0.5 * (outside + inside)
    };
    if (f0 < 0.0) != (f1 < 0.0) {
        let (outside, inside) = if f0 < 0.0 { (1.0, 0.0) } else { (0.0, 1.0) };
        return bisect(outside, inside, &|t| f(t) < 0.0);
    }
    // the least distance (golden-section search: the distance to one translating
    // convex set is convex along a segment)
    let ratio = 0.5 * (5f32.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    let (mut x1, mut x2) = (hi - ratio * (hi - lo), lo + ratio * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..ITERATIONS {
        if f1 <= f2 {
            hi = x2;
            (x2, f2) = (x1, f1);
            x1 = hi - ratio * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            (x1, f1) = (x2, f2);
            x2 = lo + ratio * (hi - lo);
            f2 = f(x2);
        }
    }
    let least = 0.5 * (lo + hi);
    let level = f(least).max(0.0) + tolerance;
    let near = |t: f32| f(t) <= level;
    let start = if near(0.0) {
        0.0
    } else {
        bisect(0.0, least, &near)
    };
    let end = if near(1.0) {
        1.0
    } else {
        bisect(1.0, least, &near)
    };
    0.5 * (start + end)
}

/// The rotation that best carries the rest vectors from particle `p` to its linked
/// neighbours onto their vectors now (`position` gives where a particle is): the
/// body's turn around `p`, found from `warm` (a neighbour's turn, say: the search then
/// takes a step or two).
pub fn turn_at(lattice: &Lattice, p: u32, position: impl Fn(u32) -> Vec3, warm: Quat) -> Quat {
    let (x, r) = (position(p), lattice.rest_position(p));
    let mut a = Mat3::ZERO;
    for q in lattice.neighbours(p) {
        let (dx, dr) = (position(q) - x, lattice.rest_position(q) - r);
        a += Mat3::from_cols(dx * dr.x, dx * dr.y, dx * dr.z);
    }
    if !a.is_finite() {
        return warm;
    }
    extract_rotation(Mat3A::from(a), warm, 64)
}

/// A crossing found on the body as it is — `fraction` along the edge from `p` to its
/// neighbour, the surface's `normal` in the world frame — in the lattice's rest frame,
/// measured from `p`, turned back by the body's turn around `p` ([`turn_at`], found
/// from `turn`, where it is left: crossings found in a row start each from the last).
pub fn rest_crossing(
    lattice: &Lattice,
    p: u32,
    fraction: f32,
    normal: Vec3,
    position: impl Fn(u32) -> Vec3,
    turn: &mut Quat,
) -> Crossing {
    *turn = turn_at(lattice, p, position, *turn);
    Crossing {
        fraction: if fraction.is_finite() {
            fraction.clamp(0.0, 1.0)
        } else {
            0.5
        },
        normal: (turn.inverse() * normal).try_normalize().unwrap_or(Vec3::X),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn the_middle_is_where_the_sign_changes_or_the_middle_of_the_touch() {
        // a sign change at 0.3, either way round
        let t = touching_middle(|t| t - 0.3, 0.0);
        assert!((t - 0.3).abs() < 1e-6, "{t}");
        let t = touching_middle(|t| 0.3 - t, 0.0);
        assert!((t - 0.3).abs() < 1e-6, "{t}");
        // a blade passing over [0.2, 0.6]: distance zero there
        let t = touching_middle(|t| (0.2 - t).max(t - 0.6).max(0.0), 1e-6);
        assert!((t - 0.4).abs() < 1e-5, "{t}");
        // a sphere grazing the segment: inside over [0.5, 0.9]
        let t = touching_middle(|t| (t - 0.7).abs() - 0.2, 1e-6);
        assert!((t - 0.7).abs() < 1e-5, "{t}");
    }

    #[test]
    fn a_crossing_is_turned_back_into_the_rest_frame() {
        let l = Shape::cuboid(UVec3::new(3, 3, 3)).voxelise(0.5).unwrap();
        let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.9, -2.1, 0.4);
        let moved = |p: u32| turn * l.rest_position(p) + Vec3::new(4.0, -1.0, 2.0);
        let centre = l.at(l.coord(0) + glam::IVec3::ONE).unwrap();
        let mut identity = Quat::IDENTITY;
        let rest_normal = Vec3::new(0.3, -0.5, 0.8).normalize();
        let c = rest_crossing(&l, centre, 0.25, turn * rest_normal, moved, &mut identity);
        assert_eq!(c.fraction, 0.25);
        assert!(c.normal.distance(rest_normal) < 1e-5, "{}", c.normal);
        // a corner particle (three links) turns as well
        let corner = l.at(l.coord(0)).unwrap();
        let c = rest_crossing(&l, corner, 0.5, turn * rest_normal, moved, &mut identity);
        assert!(c.normal.distance(rest_normal) < 1e-5, "{}", c.normal);
    }
}
