//! Collider shapes in their local frame: signed distance with the outward normal of the
//! nearest surface point, and the first point where a segment enters the shape (the
//! swept test that keeps fast particles and fast colliders from tunnelling).

use crate::error::{Result, SIZE, SIZE_OR_ZERO};
use crate::geometry::mesh_sdf::MeshSdf;
use glam::{Vec3, Vec3A};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A collider shape in its local frame: a box, ball or capsule centred on the origin, or
/// a closed triangle mesh in its own coordinates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ColliderShape {
    /// A box with the given half size per local axis.
    Box {
        /// Half size per axis.
        half_extents: Vec3,
    },
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
    /// A closed triangle mesh, through its sampled signed distance (scene files name
    /// the OBJ file; see `scene_file`).
    Mesh(Arc<MeshSdf>),
}

impl ColliderShape {
    /// Checks that every size is a [`SIZE`] (a capsule's shaft may be 0); errors name
    /// `{field}.radius` and so on.
    pub fn validate(&self, field: &str) -> Result<()> {
        match *self {
            ColliderShape::Box { half_extents } => {
                SIZE.check_each(&format!("{field}.half_extents"), half_extents)
            }
            ColliderShape::Sphere { radius } => SIZE.check(&format!("{field}.radius"), radius),
            ColliderShape::Capsule {
                radius,
                half_length,
            } => {
                SIZE.check(&format!("{field}.radius"), radius)?;
                SIZE_OR_ZERO.check(&format!("{field}.half_length"), half_length)
            }
            ColliderShape::Mesh(_) => Ok(()),
        }
    }

    /// Half size of the shape's local axis-aligned bounding box about the origin.
    pub fn local_half_extents(&self) -> Vec3 {
        match *self {
            ColliderShape::Box { half_extents } => half_extents,
            ColliderShape::Sphere { radius } => Vec3::splat(radius),
            ColliderShape::Capsule {
                radius,
                half_length,
            } => Vec3::new(radius + half_length, radius, radius),
            ColliderShape::Mesh(ref sdf) => sdf.half_extents(),
        }
    }

    /// Signed distance of `p` to the surface (negative inside).
    pub fn signed_distance(&self, p: Vec3A) -> f32 {
        self.nearest_surface(p).0
    }

    /// Signed distance of `p` to the surface and the outward normal at the nearest
    /// surface point, so that `p − d·n` lies on the surface.
    pub fn nearest_surface(&self, p: Vec3A) -> (f32, Vec3A) {
        match *self {
            ColliderShape::Box { half_extents } => {
                let h = Vec3A::from(half_extents);
                let outside = p - p.clamp(-h, h);
                if outside != Vec3A::ZERO {
                    let d = outside.length();
                    return (d, outside / d);
                }
                // inside: the nearest face
                let (mut depth, mut normal) = (f32::INFINITY, Vec3A::Y);
                for (axis, unit) in [Vec3A::X, Vec3A::Y, Vec3A::Z].into_iter().enumerate() {
                    let (below, above) = (p[axis] + h[axis], h[axis] - p[axis]);
                    if below < depth {
                        (depth, normal) = (below, -unit);
                    }
                    if above < depth {
                        (depth, normal) = (above, unit);
                    }
                }
                (-depth, normal)
            }
            ColliderShape::Sphere { radius } => round_around(p, radius),
            ColliderShape::Capsule {
                radius,
                half_length,
            } => {
                let axis = Vec3A::new(p.x.clamp(-half_length, half_length), 0.0, 0.0);
                round_around(p - axis, radius)
            }
            ColliderShape::Mesh(ref sdf) => (sdf.distance(p), sdf.normal(p)),
        }
    }

    /// The smallest `t ∈ [0, 1]` at which the segment `a → b` enters the shape, for an `a`
    /// outside it; `None` if the segment does not reach the shape.
    pub fn segment_entry(&self, a: Vec3A, b: Vec3A) -> Option<f32> {
        self.segment_entry_within(a, b, 0.0)
    }

    /// [`ColliderShape::segment_entry`] of the shape grown by `margin ≥ 0` (the points
    /// within `margin` of it: a ball's centre touching the shape). Its signed distance
    /// is the shape's less `margin`, with the same normal, so only this test needs the
    /// margin.
    pub fn segment_entry_within(&self, a: Vec3A, b: Vec3A, margin: f32) -> Option<f32> {
        let d = b - a;
        let t = match *self {
            ColliderShape::Box { half_extents } => {
                let h = Vec3A::from(half_extents);
                if margin > 0.0 {
                    rounded_box_entry(a, d, h, margin)?
                } else {
                    slab_entry(a, d, h)?
                }
            }
            ColliderShape::Sphere { radius } => ray_ball(a, d, radius + margin)?,
            ColliderShape::Capsule {
                radius,
                half_length,
            } => capsule_entry(a, d, half_length, radius + margin)?,
            ColliderShape::Mesh(ref sdf) => sdf.segment_entry_within(a, b, margin)?,
        };
        (0.0..=1.0).contains(&t).then_some(t)
    }
}

/// The first `t` at which `a + t·d` (`t ∈ [0, 1]`) is in the box of half size `h`.
fn slab_entry(a: Vec3A, d: Vec3A, h: Vec3A) -> Option<f32> {
    let (mut enter, mut exit) = (0.0f32, 1.0f32);
    for axis in 0..3 {
        if d[axis].abs() < 1e-12 {
            if a[axis].abs() > h[axis] {
                return None;
            }
            continue;
        }
        let (t0, t1) = (
            (-h[axis] - a[axis]) / d[axis],
            (h[axis] - a[axis]) / d[axis],
        );
        enter = enter.max(t0.min(t1));
        exit = exit.min(t0.max(t1));
    }
    (enter <= exit).then_some(enter)
}

/// The first `t ≥ 0` at which `a + t·d` is in the capsule of `radius` about the X axis
/// from `−half_length` to `half_length`.
fn capsule_entry(a: Vec3A, d: Vec3A, half_length: f32, radius: f32) -> Option<f32> {
    let ends =
        [-half_length, half_length].map(|x| ray_ball(a - Vec3A::new(x, 0.0, 0.0), d, radius));
    // the shaft: the infinite cylinder about X, where it lies along the shaft
    let shaft = ray_ball(
        a * Vec3A::new(0.0, 1.0, 1.0),
        d * Vec3A::new(0.0, 1.0, 1.0),
        radius,
    )
    .filter(|t| (a.x + d.x * t).abs() <= half_length);
    ends.into_iter().chain([shaft]).flatten().reduce(f32::min)
}

/// The first `t ∈ [0, 1]` at which `a + t·d` is within `margin` of the box of half size
/// `h`: the rounded box is the union of the box grown by `margin` along one axis at a
/// time and the capsules of radius `margin` about its 12 edges.
fn rounded_box_entry(a: Vec3A, d: Vec3A, h: Vec3A, margin: f32) -> Option<f32> {
    let slabs = (0..3).filter_map(|axis| {
        let mut grown = h;
        grown[axis] += margin;
        slab_entry(a, d, grown)
    });
    // each edge along `axis`, in coordinates where that axis is X
    let edges = (0..3).flat_map(|axis| {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let swizzle = move |p: Vec3A| Vec3A::new(p[axis], p[u], p[v]);
        [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
            .into_iter()
            .filter_map(move |(su, sv)| {
                let centre = Vec3A::new(0.0, su * h[u], sv * h[v]);
                capsule_entry(swizzle(a) - centre, swizzle(d), h[axis], margin)
            })
    });
    slabs.chain(edges).reduce(f32::min)
}

/// Distance and outward normal of `v` to a ball of `radius` about the origin.
fn round_around(v: Vec3A, radius: f32) -> (f32, Vec3A) {
    let length = v.length();
    let normal = if length > 0.0 { v / length } else { Vec3A::Y };
    (length - radius, normal)
}

/// The first `t ≥ 0` at which `a + t·d` is on the ball of `radius` about the origin, if
/// the line enters it at or after `t = 0` (a start inside gives `0`).
fn ray_ball(a: Vec3A, d: Vec3A, radius: f32) -> Option<f32> {
    let c = a.length_squared() - radius * radius;
    if c <= 0.0 {
        return Some(0.0);
    }
    let (qa, half_b) = (d.length_squared(), a.dot(d));
    if qa == 0.0 || half_b >= 0.0 {
        return None; // standing still, or moving away
    }
    let disc = half_b * half_b - qa * c;
    (disc >= 0.0).then(|| (-half_b - disc.sqrt()) / qa)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPES: [ColliderShape; 3] = [
        ColliderShape::Box {
            half_extents: Vec3::new(0.3, 0.2, 0.5),
        },
        ColliderShape::Sphere { radius: 0.4 },
        ColliderShape::Capsule {
            radius: 0.2,
            half_length: 0.5,
        },
    ];

    #[test]
    fn the_nearest_surface_point_is_on_the_surface_and_the_normal_points_out() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for shape in SHAPES {
            for _ in 0..500 {
                let p = Vec3A::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let (d, n) = shape.nearest_surface(p);
                let on = p - n * d;
                assert!(shape.signed_distance(on).abs() < 1e-5, "{shape:?} {p}");
                // a little outside along the normal is outside, a little inside is inside
                assert!(shape.signed_distance(on + n * 1e-3) > 0.0, "{shape:?} {p}");
                assert!(shape.signed_distance(on - n * 1e-3) < 0.0, "{shape:?} {p}");
            }
        }
    }

    #[test]
    fn a_segment_enters_where_it_first_meets_the_surface() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let mut v = || {
            Vec3A::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
            )
        };
        for shape in SHAPES {
            let (mut hits, mut misses) = (0, 0);
            for _ in 0..2000 {
                let (a, b) = (v(), v());
                if shape.signed_distance(a) <= 0.0 {
                    continue;
                }
                // reference: dense sampling of the segment
                let first_inside = (0..=4000)
                    .map(|i| i as f32 / 4000.0)
                    .find(|t| shape.signed_distance(a + (b - a) * *t) < 0.0);
                match (shape.segment_entry(a, b), first_inside) {
                    (Some(t), Some(r)) => {
                        hits += 1;
                        assert!(t <= r + 1e-4 && r - t < 1e-3, "{shape:?}: {t} vs {r}");
                        let entry = a + (b - a) * t;
                        assert!(shape.signed_distance(entry).abs() < 1e-4, "{shape:?}");
                    }
                    (None, None) => misses += 1,
                    // a graze the sampling can miss: the entry touches the surface
                    (Some(t), None) => {
                        assert!(shape.signed_distance(a + (b - a) * t).abs() < 1e-4)
                    }
                    (None, Some(r)) => panic!("{shape:?}: missed an entry at {r} ({a} → {b})"),
                }
            }
            assert!(
                hits > 100 && misses > 100,
                "{shape:?}: {hits} hits, {misses} misses"
            );
        }
    }

    #[test]
    fn a_grown_segment_entry_is_where_the_distance_first_falls_to_the_margin() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut entered = 0;
        for shape in SHAPES {
            for _ in 0..300 {
                let mut point = || {
                    Vec3A::new(
                        rng.random_range(-1.2..1.2),
                        rng.random_range(-1.2..1.2),
                        rng.random_range(-1.2..1.2),
                    )
                };
                let (a, b, margin) = (point(), point(), rng.random_range(0.01..0.3));
                if shape.signed_distance(a) <= margin {
                    continue;
                }
                // the first of 20,000 samples within the margin, against the test
                let steps = 20_000;
                let sampled = (0..=steps)
                    .map(|k| k as f32 / steps as f32)
                    .find(|t| shape.signed_distance(a + (b - a) * *t) <= margin);
                let found = shape.segment_entry_within(a, b, margin);
                match (sampled, found) {
                    (None, None) => {}
                    (Some(s), Some(t)) => {
                        entered += 1;
                        assert!(
                            (s - t).abs() < 2e-3,
                            "{shape:?} {a} → {b} ({margin}): {t} vs {s}"
                        );
                    }
                    // a chord that only grazes the grown shape between samples
                    (None, Some(t)) => {
                        let at = a + (b - a) * t;
                        assert!(
                            (shape.signed_distance(at) - margin).abs() < 1e-4,
                            "{shape:?}"
                        );
                    }
                    (Some(s), None) => panic!("{shape:?} {a} → {b} ({margin}): missed at {s}"),
                }
            }
        }
        assert!(entered > 200, "only {entered} segments entered");
    }
}
