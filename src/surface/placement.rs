//! Where the vertices of cut faces rest: on the cut the tools made, not on the lattice's
//! faces. A cut face of the surface is a face between two particles that are not joined
//! (a severed edge, the halves of a split particle); its corners would rest on the grid
//! of cells, a staircase around the blade's slanted path. Each vertex of a cut face is
//! placed instead by dual contouring (Ju, Losasso, Schaefer and Warren 2002; on the
//! hexahedral grid of a cut as in Wu, Dick and Westermann 2015) from where the tools
//! crossed the lattice's edges ([`crate::body::crossings`]).
//!
//! **The planes a vertex fits.** Around the vertex's grid corner `v` lies a box one cell
//! wide; every lattice edge that passes through it (from centre to centre of two
//! neighbouring cells) gives a plane where it is cut: through its crossing, with the
//! crossing's normal, where a tool crossed it; through its middle, across the edge, where
//! it runs from a solid cell to an empty one or between two solid cells not linked
//! without a crossing (the body's outside, a removed particle, a tear) — the faces that
//! stay where they were. Edges still linked give none. At one sub-cell per cell the box
//! is the dual cell of the corner and its edges the twelve among the eight cells around
//! it.
//!
//! **The point.** The point nearest `v` that minimises the summed squared distances to
//! the planes (the quadric error function, solved on its eigen-directions whose weight
//! passes a hundredth of the largest, so that nearly parallel planes do not throw it
//! far): on a planar cut's plane, at a cut's rim on the line where it meets the outside,
//! at the corner of two cuts. It may move up to a cell from its corner along each axis
//! (a rim lies beyond the box of the corner its faces end at when the cut slants);
//! should it go farther, the same solve about the mean of the planes' points is taken,
//! and failing that the point is clamped. A
//! vertex whose box holds no crossing (a face cut without a tool, as a tear) stays at its
//! corner, as does one whose planes give no finite point.
//!
//! All vertices at one corner fit the same planes, so the faces on the two sides of a
//! cut rest on each other and the body's pieces still fill it exactly.

use super::cells::CellOwners;
use super::fans::Quad;
use crate::body::lattice::{NEIGHBOUR_OFFSETS, NO_PARTICLE};
use crate::math::eigen::symmetric_eigen;
use glam::{IVec3, Mat3, Vec3};
use smallvec::SmallVec;

/// How far a vertex may move from its corner along each axis, in cells: within the
/// cells around the corner. A cut's rim meets the body's outside up to about
/// `½ tan θ` of a cell beyond the box of the corner whose faces end there (θ the angle
/// between the cut and the outside's normal): half a cell at 45°.
const REACH: f32 = 1.0;

/// Largest root-mean-square distance, in cells, from a placed vertex to the planes it
/// fits: planes that meet nowhere near a point within reach (a cell cut by more
/// planes than its corners can follow) leave the vertex at its corner.
const MISFIT: f32 = 0.25;

/// Eigen-directions of the quadric lighter than this share of the heaviest are left to
/// the starting point (singular values under a tenth).
const DOMINANT: f32 = 1e-2;

/// One plane a vertex fits: a point on it (in cells, from the vertex's corner) and its
/// unit normal.
#[derive(Clone, Copy, Debug)]
struct Plane {
    at: Vec3,
    normal: Vec3,
    /// Whether a tool's crossing gave it (not a face that stays).
    cut: bool,
}

/// Where the vertex at sub-cell grid corner `w` rests (in the lattice's rest frame),
/// when it lies on a cut face and its box holds a crossing (see the module docs);
/// `None` to leave it at its corner.
pub fn cut_vertex_position(owners: &CellOwners, w: IVec3) -> Option<Vec3> {
    let lattice = owners.lattice();
    let h = lattice.spacing();
    // the corner, in cells
    let v = w.as_vec3() / owners.resolution() as f32;
    let mut planes: SmallVec<[Plane; 16]> = SmallVec::new();
    let mut crossings = 0;
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        // cells whose centres lie within half a cell of `v` across the axis, and whose
        // edge along it overlaps the box by more than a point
        for lower in candidate_cells(v, axis) {
            let (from, to) = (
                owners.particles_in(lower),
                owners.particles_in(lower + NEIGHBOUR_OFFSETS[2 * axis + 1]),
            );
            let centre = lower.as_vec3() + Vec3::splat(0.5) - v;
            debug_assert!(centre[b].abs() <= 0.5 && centre[c].abs() <= 0.5);
            let solid = (!from.is_empty(), !to.is_empty());
            // (only an edge between two solid cells reads its crossing)
            let crossing = match solid {
                (true, true) => lattice.crossing_at(lower, axis),
                _ => None,
            };
            let linked = || {
                from.iter().any(|&p| {
                    let q = lattice.link(p, 2 * axis + 1);
                    q != NO_PARTICLE && to.contains(&q)
                })
            };
            let plane = match (solid, crossing) {
                ((true, true), Some(crossing)) if crossing.is_valid() => {
                    let mut at = centre;
                    at[axis] += crossing.fraction;
                    Plane {
                        at,
                        normal: crossing.normal,
                        cut: true,
                    }
                }
                ((true, true), _) if linked() => continue,
                ((false, false), _) => continue,
                // the outside, a removed particle, a cut without a crossing: the face
                _ => {
                    let mut at = centre;
                    at[axis] += 0.5;
                    let mut normal = Vec3::ZERO;
                    normal[axis] = 1.0;
                    Plane {
                        at,
                        normal,
                        cut: false,
                    }
                }
            };
            if plane.at.abs().max_element() <= 0.5 + 1e-6 {
                crossings += plane.cut as usize;
                planes.push(plane);
            }
        }
    }
    if crossings == 0 {
        return None;
    }
    let inside = |x: Vec3| x.abs().max_element() <= REACH;
    let about = |start: Vec3| fit(&planes, start).filter(|x| inside(*x));
    let mean = planes.iter().map(|p| p.at).sum::<Vec3>() / planes.len() as f32;
    let x = about(Vec3::ZERO).or_else(|| about(mean)).or_else(|| {
        fit(&planes, Vec3::ZERO).map(|x| x.clamp(Vec3::splat(-REACH), Vec3::splat(REACH)))
    })?;
    let misfit = planes
        .iter()
        .map(|p| p.normal.dot(x - p.at).powi(2))
        .sum::<f32>()
        / planes.len() as f32;
    (misfit <= MISFIT * MISFIT).then_some((v + x) * h)
}

/// The point nearest `start` minimising the squared distances to `planes`, on the
/// dominant eigen-directions of their quadric; `None` when it is not finite.
fn fit(planes: &[Plane], start: Vec3) -> Option<Vec3> {
    // one plane however many crossings (a flat cut): the point of it nearest `start`
    let n = planes.first()?.normal;
    if planes.iter().all(|p| p.normal.dot(n).abs() > 1.0 - 1e-6) {
        let offset = planes
            .iter()
            .map(|p| p.normal.dot(p.at - start) * p.normal.dot(n))
            .sum::<f32>();
        let x = start + n * (offset / planes.len() as f32);
        return x.is_finite().then_some(x);
    }
    let mut a = Mat3::ZERO;
    let mut rhs = Vec3::ZERO;
    for p in planes {
        let n = p.normal;
        a += Mat3::from_cols(n * n.x, n * n.y, n * n.z);
        rhs += n * n.dot(p.at - start);
    }
    let (values, vectors) = symmetric_eigen(a);
    let largest = values.max_element();
    if largest.is_nan() || largest <= 0.0 {
        return None;
    }
    let mut x = start;
    for k in 0..3 {
        if values[k] > DOMINANT * largest {
            let u = vectors.col(k);
            x += u * (u.dot(rhs) / values[k]);
        }
    }
    x.is_finite().then_some(x)
}

/// The lower cells of the edges along `axis` that may pass through the box around `v`
/// (in cells): centres within half a cell of `v` across the axis, and an edge overlapping
/// the box along it by more than a point.
fn candidate_cells(v: Vec3, axis: usize) -> impl Iterator<Item = IVec3> {
    let range = |lo: f32, hi: f32| (lo.ceil() as i32)..=(hi.floor() as i32);
    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
    // centre k + ½ within [v − ½, v + ½]: k in [v − 1, v]
    let across_b = range(v[b] - 1.0, v[b]);
    let across_c = range(v[c] - 1.0, v[c]);
    // edge [k + ½, k + 3/2] overlapping [v − ½, v + ½] by more than a point
    let along = range(v[axis] - 2.0 + 1e-3, v[axis] - 1e-3);
    along.flat_map(move |ka| {
        let across_c = across_c.clone();
        across_b.clone().flat_map(move |kb| {
            across_c.clone().map(move |kc| {
                let mut k = IVec3::ZERO;
                k[axis] = ka;
                k[b] = kb;
                k[c] = kc;
                k
            })
        })
    })
}

/// Whether `quad` lies on a cut face: across it lies a sub-cell of a live particle it
/// is not joined to (a quad is a face toward a sub-cell not joined to it).
pub(super) fn is_cut_face(owners: &CellOwners, quad: &Quad) -> bool {
    owners
        .owner(quad.cell + NEIGHBOUR_OFFSETS[quad.direction as usize])
        .is_some()
}

#[cfg(test)]
mod tests {
    use crate::body::crossings::Crossing;
    use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS};
    use crate::body::shape::Shape;
    use crate::surface::extract;
    use glam::{IVec3, UVec3, Vec3};
    use rand::{Rng, SeedableRng};
    use std::collections::HashMap;

    /// Per piece, the rest volume of `lattice`'s surface, after checking that every
    /// directed edge appears once and its reverse once.
    fn volumes(lattice: &Lattice) -> HashMap<u32, f64> {
        let t = extract(lattice);
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        let mut volume: HashMap<u32, f64> = HashMap::new();
        for (tri, piece) in t.triangles.iter().zip(&t.triangle_piece) {
            for k in 0..3 {
                *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
            }
            let [a, b, c] = tri.map(|v| t.rest[v as usize].as_dvec3());
            assert!(a.is_finite() && b.is_finite() && c.is_finite());
            *volume.entry(*piece).or_default() += a.dot(b.cross(c)) / 6.0;
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1);
            assert_eq!(directed.get(&(b, a)), Some(&1));
        }
        volume
    }

    #[test]
    fn a_plane_across_a_cell_moves_its_faces_onto_it() {
        // a 4×1×1 bar severed between its middle cells at a quarter of the edge, the
        // cut tilted: the two cut faces rest on the tilted plane, at its fraction
        let mut l = Shape::cuboid(UVec3::new(4, 1, 1)).voxelise(1.0).unwrap();
        let origin = l.coord(0);
        let (a, b) = (
            l.at(origin + IVec3::new(1, 0, 0)).unwrap(),
            l.at(origin + IVec3::new(2, 0, 0)).unwrap(),
        );
        assert!(l.sever(a, b));
        let normal = Vec3::new(1.0, 0.2, 0.0).normalize();
        l.set_crossing(
            a,
            b,
            Crossing {
                fraction: 0.25,
                normal,
            },
        );
        let at = l.rest_position(a) + 0.25 * (l.rest_position(b) - l.rest_position(a));
        let t = extract(&l);
        let mut on_plane = 0;
        for x in &t.rest {
            if (x.x - at.x).abs() < 0.6 {
                assert!((*x - at).dot(normal).abs() < 1e-5, "{x}");
                on_plane += 1;
            }
        }
        // the four corners of each side's cut face
        assert_eq!(on_plane, 8);
        let v = volumes(&l);
        assert!((v.values().sum::<f64>() - 4.0).abs() < 1e-5, "{v:?}");
    }

    #[test]
    fn cells_cut_every_way_stay_closed_and_whole() {
        // every edge of a 4³ block severed, each with a crossing of a random plane:
        // 64 single cells whose corners fit planes that meet nowhere
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(62);
        let mut l = Shape::cuboid(UVec3::splat(4)).voxelise(1.0).unwrap();
        for (a, b) in l.edges() {
            assert!(l.sever(a, b));
            let normal = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize();
            let fraction = rng.random_range(0.0..1.0);
            assert!(l.set_crossing(a, b, Crossing { fraction, normal }));
        }
        // a crossing that is not one is refused outright
        let (a, b) = (0, l.link(0, 1));
        let nan = Crossing {
            fraction: f32::NAN,
            normal: Vec3::X,
        };
        assert!(
            b == u32::MAX
                && !l.set_crossing(a, l.at(l.coord(0) + NEIGHBOUR_OFFSETS[1]).unwrap(), nan)
        );
        let v = volumes(&l);
        assert_eq!(v.len(), 64);
        assert!(v.values().all(|v| *v > 0.4), "{v:?}");
        let total: f64 = v.values().sum();
        assert!((total - 64.0).abs() < 0.05 * 64.0, "{total}");
    }
}
