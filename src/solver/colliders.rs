//! Static colliders of the solver: a ground plane and axis-aligned boxes, with Coulomb
//! friction against the displacement of the current substep.

use crate::config::{GroundPlane, StaticBox};
use glam::Vec3A;
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
use wide::f32x8;

/// Static colliders applied after every solver iteration.
#[derive(Clone, Debug, Default)]
pub struct Colliders {
    /// Ground plane.
    pub ground: Option<GroundPlane>,
    /// Static boxes.
    pub boxes: Vec<StaticBox>,
}

impl Colliders {
    /// Whether a collider reaches into the box `[lo, hi]`; false guarantees that
    /// [`resolve_colliders`] leaves every point of the box where it is, so the solver
    /// skips whole blocks of particles far from every collider.
    pub fn may_touch(&self, lo: Vec3A, hi: Vec3A) -> bool {
        self.ground.is_some_and(|g| lo.y < g.height)
            || self
                .boxes
                .iter()
                .any(|b| hi.cmpgt(b.min.into()).all() && lo.cmplt(b.max.into()).all())
    }
}

/// The bounding box of positions, grown point by point; a NaN or infinite point makes it
/// unbounded (so a block holding one is never skipped).
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    lo: Vec3A,
    hi: Vec3A,
    /// Σ 0·p: stays zero while every point is finite, NaN from the first one that is not
    /// (one multiply-add per point where a NaN test costs five instructions).
    probe: Vec3A,
}

impl Default for Bounds {
    fn default() -> Self {
        Self {
            lo: Vec3A::INFINITY,
            hi: Vec3A::NEG_INFINITY,
            probe: Vec3A::ZERO,
        }
    }
}

impl Bounds {
    /// Grows the box to hold `p`.
    #[inline(always)]
    pub fn add(&mut self, p: Vec3A) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
        self.probe = p.mul_add(Vec3A::ZERO, self.probe);
    }

    /// The bounds of points taken two at a time in eight lanes (a pair of `Vec3A`s, see
    /// the Jacobi particle pass): the lane-wise `lo`, `hi` and probe of both halves.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    pub(super) fn from_pairs(lo: f32x8, hi: f32x8, probe: f32x8) -> Self {
        let halves = |v: f32x8| {
            let [a, b, c, _, d, e, f, _] = v.to_array();
            (Vec3A::new(a, b, c), Vec3A::new(d, e, f))
        };
        let ((lo0, lo1), (hi0, hi1), (probe0, probe1)) = (halves(lo), halves(hi), halves(probe));
        Self {
            lo: lo0.min(lo1),
            hi: hi0.max(hi1),
            probe: probe0 + probe1,
        }
    }

    /// The box's corners, and whether every point was finite.
    #[cfg(test)]
    pub(super) fn corners(&self) -> (Vec3A, Vec3A, bool) {
        (self.lo, self.hi, !self.probe.is_nan())
    }

    /// Whether a collider may move a point of the box.
    pub fn touches(&self, colliders: &Colliders) -> bool {
        self.probe.is_nan() || colliders.may_touch(self.lo, self.hi)
    }
}

/// The particles of one block, as the solver's passes hand them to [`collide_block`].
pub(super) struct Block<'a> {
    /// Positions, pushed out of the colliders.
    pub(super) positions: &'a mut [Vec3A],
    /// Total corrections, which receive the pushes.
    pub(super) corrections: &'a mut [Vec3A],
    /// Positions at the start of the substep (friction).
    pub(super) previous: &'a [Vec3A],
    /// Inverse masses: pinned particles (0) are never moved.
    pub(super) inv_mass: &'a [f32],
}

/// Applies the colliders to every unpinned particle of a block whose bounding box is
/// `bounds`, adding each push to the particle's correction; a block no collider
/// reaches is skipped whole.
pub(super) fn collide_block(block: Block, bounds: &Bounds, colliders: &Colliders) {
    if !bounds.touches(colliders) {
        return;
    }
    // Most particles of a block a collider reaches are not in it: a point test comes
    // first, and only a particle in a collider has the rest of its state read (the
    // previous positions are not in cache: no other step of the pass reads them).
    for (i, p) in block.positions.iter_mut().enumerate() {
        if block.inv_mass[i] == 0.0 || !colliders.may_touch(*p, *p) {
            continue;
        }
        let unconstrained = *p;
        resolve_colliders(p, block.previous[i], colliders);
        block.corrections[i] += *p - unconstrained;
    }
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

    #[test]
    fn skipped_blocks_are_exactly_the_untouched_ones() {
        use rand::{Rng, SeedableRng};
        let colliders = Colliders {
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.5,
            }),
            boxes: vec![StaticBox {
                min: glam::Vec3::new(1.0, 0.5, 1.0),
                max: glam::Vec3::new(2.0, 1.5, 2.0),
                friction: 0.5,
            }],
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut skipped, mut touched) = (0, 0);
        for _ in 0..2000 {
            // a block of 16 points around a random centre
            let centre = Vec3A::new(
                rng.random_range(-1.0..3.0),
                rng.random_range(-1.0..3.0),
                rng.random_range(-1.0..3.0),
            );
            let block: Vec<Vec3A> = (0..16)
                .map(|_| centre + Vec3A::splat(0.3) * rng.random_range(-1.0..1.0))
                .collect();
            let mut bounds = Bounds::default();
            block.iter().for_each(|p| bounds.add(*p));
            let moves = block.iter().any(|p| {
                let mut q = *p;
                resolve_colliders(&mut q, *p - Vec3A::X * 0.01, &colliders);
                q != *p
            });
            assert!(
                bounds.touches(&colliders) || !moves,
                "a skipped block had a contact"
            );
            if bounds.touches(&colliders) {
                touched += 1;
            } else {
                skipped += 1;
            }
        }
        assert!(
            skipped > 500 && touched > 500,
            "{skipped} skipped, {touched} touched"
        );
        // a NaN point is never skipped over
        let mut bounds = Bounds::default();
        bounds.add(Vec3A::new(0.0, 10.0, 0.0));
        assert!(!bounds.touches(&colliders));
        let finite = bounds;
        bounds.add(Vec3A::NAN);
        assert!(bounds.touches(&colliders));
        bounds.add(Vec3A::new(0.0, 10.0, 0.0));
        assert!(bounds.touches(&colliders), "a NaN point is not forgotten");
        let mut infinite = finite;
        infinite.add(Vec3A::new(f32::INFINITY, 10.0, 0.0));
        assert!(infinite.touches(&colliders));
    }
}
