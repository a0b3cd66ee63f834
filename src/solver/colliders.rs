//! Static colliders of the solver: a ground plane and axis-aligned boxes, with Coulomb
//! friction against the displacement of the current substep.

use crate::config::{GroundPlane, StaticBox};
use glam::Vec3A;

/// Static colliders applied after every solver iteration.
#[derive(Clone, Debug, Default)]
pub struct Colliders {
    /// Ground plane.
    pub ground: Option<GroundPlane>,
    /// Static boxes.
    pub boxes: Vec<StaticBox>,
}

/// Pushes `p` out of the ground and static boxes, with Coulomb friction against the
/// displacement since `previous`.
#[inline]
pub fn resolve_colliders(p: &mut Vec3A, previous: Vec3A, colliders: &Colliders) {
    if let Some(g) = &colliders.ground
        && p.y < g.height
    {
        let depth = g.height - p.y;
        p.y = g.height;
        apply_friction(p, previous, Vec3A::Y, depth, g.friction);
    }
    for b in &colliders.boxes {
        let (min, max) = (Vec3A::from(b.min), Vec3A::from(b.max));
        if p.cmpgt(min).all() && p.cmplt(max).all() {
            let below = *p - min;
            let above = max - *p;
            let (mut depth, mut normal) = (f32::INFINITY, Vec3A::ZERO);
            for (axis, unit) in [Vec3A::X, Vec3A::Y, Vec3A::Z].into_iter().enumerate() {
                if below[axis] < depth {
                    depth = below[axis];
                    normal = -unit;
                }
                if above[axis] < depth {
                    depth = above[axis];
                    normal = unit;
                }
            }
            *p += normal * depth;
            apply_friction(p, previous, normal, depth, b.friction);
        }
    }
}

#[inline]
fn apply_friction(p: &mut Vec3A, previous: Vec3A, normal: Vec3A, depth: f32, friction: f32) {
    let moved = *p - previous;
    let tangential = moved - normal * moved.dot(normal);
    let length = tangential.length();
    let limit = friction * depth;
    if length <= limit {
        *p -= tangential;
    } else if length > 0.0 {
        *p -= tangential * (limit / length);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ground_and_boxes_push_out() {
        let colliders = Colliders {
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.0,
            }),
            boxes: vec![StaticBox {
                min: glam::Vec3::splat(1.0),
                max: glam::Vec3::splat(2.0),
                friction: 0.0,
            }],
        };
        let mut p = Vec3A::new(0.0, -0.5, 0.0);
        resolve_colliders(&mut p, Vec3A::ZERO, &colliders);
        assert_eq!(p.y, 0.0);
        let mut p = Vec3A::new(1.5, 1.9, 1.5);
        resolve_colliders(&mut p, Vec3A::new(1.5, 2.5, 1.5), &colliders);
        assert_eq!(p, Vec3A::new(1.5, 2.0, 1.5));
    }

    #[test]
    fn friction_stops_small_slides() {
        let colliders = Colliders {
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 1.0,
            }),
            boxes: vec![],
        };
        // slid 0.05 sideways while sinking 0.1: the friction cone holds it
        let mut p = Vec3A::new(0.05, -0.1, 0.0);
        resolve_colliders(&mut p, Vec3A::ZERO, &colliders);
        assert_eq!(p, Vec3A::ZERO);
        // slid 0.5 sideways while sinking 0.1: kinetic friction removes 0.1 of it
        let mut p = Vec3A::new(0.5, -0.1, 0.0);
        resolve_colliders(&mut p, Vec3A::ZERO, &colliders);
        assert!((p.x - 0.4).abs() < 1e-6 && p.y == 0.0, "{p}");
    }
}
