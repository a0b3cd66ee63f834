//! Exact distances between small convex sets in 3-D: points, segments and planar convex
//! quadrilaterals. A cutting tool's core is one of these (a sphere's centre, a capsule's
//! axis, a blade's rectangle), and so is what a particle or an edge traces in the tool's
//! frame while the tool translates (a segment, a parallelogram). The distance between
//! the two decides whether the tool touched the particle or crossed the edge at any time
//! during the motion, without sampling the motion.
//!
//! The distance between two convex polytopes is reached between features: an edge of
//! one and an edge of the other (which covers vertex–vertex and vertex–edge pairs), or a
//! vertex of one over the face of the other; it is 0 when an edge of one passes through
//! the face of the other.

use glam::Vec3;

/// A point (1 vertex), a segment (2) or a planar convex quadrilateral (4, in order
/// around it; it may be degenerate, e.g. a segment swept along itself).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convex {
    vertices: [Vec3; 4],
    count: usize,
}

impl Convex {
    /// A point.
    pub fn point(a: Vec3) -> Self {
        Self {
            vertices: [a; 4],
            count: 1,
        }
    }

    /// The segment `a`–`b`.
    pub fn segment(a: Vec3, b: Vec3) -> Self {
        Self {
            vertices: [a, b, b, b],
            count: 2,
        }
    }

    /// The quadrilateral `a b c d` (planar and convex, vertices in order around it).
    pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> Self {
        Self {
            vertices: [a, b, c, d],
            count: 4,
        }
    }

    /// The vertices.
    pub fn vertices(&self) -> &[Vec3] {
        &self.vertices[..self.count]
    }

    /// The edges as segments (a point is one degenerate edge).
    fn edges(&self) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        let v = self.vertices();
        let n = match v.len() {
            1 => 1,
            2 => 1,
            n => n,
        };
        (0..n).map(move |i| (v[i], v[(i + 1) % v.len()]))
    }

    /// The face of a quadrilateral whose area is not negligible.
    fn face(&self) -> Option<Face<'_>> {
        if self.count < 3 {
            return None;
        }
        let v = &self.vertices;
        let normal = (v[2] - v[0]).cross(v[3] - v[1]);
        let scale = (v[2] - v[0]).length_squared() + (v[3] - v[1]).length_squared();
        // (a sliver: its edges carry the distance alone)
        if normal.length_squared() <= 1e-10 * scale * scale {
            return None;
        }
        Some(Face {
            vertices: v,
            normal: normal.normalize(),
        })
    }
}

/// The plane and outline of a quadrilateral.
struct Face<'a> {
    vertices: &'a [Vec3; 4],
    normal: Vec3,
}

impl Face<'_> {
    /// Whether `x`, a point of the face's plane, lies inside the outline (or on it).
    fn contains_in_plane(&self, x: Vec3) -> bool {
        let v = self.vertices;
        (0..4).all(|i| {
            let (a, b) = (v[i], v[(i + 1) % 4]);
            (b - a).cross(x - a).dot(self.normal) >= 0.0
        })
    }

    /// The distance from `x` to the face when `x` lies over it (its projection onto
    /// the plane falls inside the outline).
    fn distance_over(&self, x: Vec3) -> Option<f32> {
        let height = (x - self.vertices[0]).dot(self.normal);
        self.contains_in_plane(x - height * self.normal)
            .then_some(height.abs())
    }

    /// Whether the segment `a`–`b` passes through the face (touching counts).
    fn crossed_by(&self, a: Vec3, b: Vec3) -> bool {
        let (sa, sb) = (
            (a - self.vertices[0]).dot(self.normal),
            (b - self.vertices[0]).dot(self.normal),
        );
        if sa * sb > 0.0 || sa == sb {
            // both ends on one side, or the segment lies in the plane (then a vertex
            // over the face or an edge pair finds the contact)
            return false;
        }
        self.contains_in_plane(a + (sa / (sa - sb)) * (b - a))
    }
}

/// The distance between the convex sets `a` and `b` (0 when they touch or overlap).
pub fn distance(a: &Convex, b: &Convex) -> f32 {
    let mut best = f32::INFINITY;
    for (p0, p1) in a.edges() {
        for (q0, q1) in b.edges() {
            best = best.min(segment_distance(p0, p1, q0, q1));
        }
    }
    for (one, other) in [(a, b), (b, a)] {
        let Some(face) = other.face() else {
            continue;
        };
        if one.edges().any(|(p0, p1)| face.crossed_by(p0, p1)) {
            return 0.0;
        }
        for &v in one.vertices() {
            if let Some(d) = face.distance_over(v) {
                best = best.min(d);
            }
        }
    }
    best
}

/// The distance between the segments `p0`–`p1` and `q0`–`q1` (either may be a point):
/// the closest points minimise over both parameters, clamped to the segments
/// (Ericson, Real-Time Collision Detection, §5.1.9).
pub fn segment_distance(p0: Vec3, p1: Vec3, q0: Vec3, q1: Vec3) -> f32 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let tiny = f32::MIN_POSITIVE;
    let (s, t) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    (p0 + d1 * s).distance(q0 + d2 * t)
}

/// A random vector with each coordinate in `−scale..scale` (for tests).
#[cfg(test)]
pub(crate) fn random_vec(rng: &mut impl rand::Rng, scale: f32) -> Vec3 {
    Vec3::new(
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
        rng.random_range(-scale..scale),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random convex set: a point, a segment, or a parallelogram (sometimes flat).
    fn random_convex(rng: &mut ChaCha8Rng) -> Convex {
        let a = random_vec(rng, 0.8);
        match rng.random_range(0..4) {
            0 => Convex::point(a),
            1 => Convex::segment(a, a + random_vec(rng, 1.5)),
            2 => {
                let (u, v) = (random_vec(rng, 1.5), random_vec(rng, 1.5));
                Convex::quad(a, a + u, a + u + v, a + v)
            }
            _ => {
                // a parallelogram swept along its own edge: degenerate
                let u = random_vec(rng, 1.5);
                Convex::quad(a, a + u, a + 1.5 * u, a + 0.5 * u)
            }
        }
    }

    /// The distance by brute force: the closest pair over a fine grid of points of both
    /// sets (parallelograms by their two edge vectors).
    fn sampled_distance(a: &Convex, b: &Convex, n: usize) -> f32 {
        let points = |c: &Convex| -> Vec<Vec3> {
            let v = c.vertices();
            let (o, u, w) = match v.len() {
                1 => (v[0], Vec3::ZERO, Vec3::ZERO),
                2 => (v[0], v[1] - v[0], Vec3::ZERO),
                _ => (v[0], v[1] - v[0], v[3] - v[0]),
            };
            let mut out = Vec::new();
            for i in 0..=n {
                for j in 0..=n {
                    out.push(o + u * (i as f32 / n as f32) + w * (j as f32 / n as f32));
                }
            }
            out
        };
        let (pa, pb) = (points(a), points(b));
        pa.iter()
            .flat_map(|p| pb.iter().map(move |q| p.distance(*q)))
            .fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn distances_agree_with_a_brute_force_search() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (mut touching, mut apart) = (0, 0);
        for case in 0..800 {
            let (a, b) = (random_convex(&mut rng), random_convex(&mut rng));
            let exact = distance(&a, &b);
            // the grid's spacing bounds how far its closest pair is from the true one
            let grid = 24;
            let sampled = sampled_distance(&a, &b, grid);
            let spacing = 2.0 * 3.0 * 3f32.sqrt() / grid as f32;
            assert!(
                exact <= sampled + 1e-4 && sampled <= exact + spacing,
                "case {case}: exact {exact}, sampled {sampled}, {a:?} {b:?}"
            );
            if exact == 0.0 {
                touching += 1;
            } else {
                apart += 1;
            }
        }
        assert!(
            touching > 10 && apart > 200,
            "{touching} touching, {apart} apart"
        );
    }

    #[test]
    fn a_segment_through_a_square_touches_it() {
        let square = Convex::quad(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        );
        let through = Convex::segment(Vec3::new(0.2, 0.3, -1.0), Vec3::new(0.2, 0.3, 1.0));
        assert_eq!(distance(&through, &square), 0.0);
        let beside = Convex::segment(Vec3::new(1.5, 0.0, -1.0), Vec3::new(1.5, 0.0, 1.0));
        assert!((distance(&beside, &square) - 0.5).abs() < 1e-6);
        let over = Convex::point(Vec3::new(0.5, -0.5, 0.25));
        assert!((distance(&over, &square) - 0.25).abs() < 1e-6);
    }
}
