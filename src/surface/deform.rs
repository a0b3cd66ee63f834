//! Where a surface's vertices are each frame: carried by their particles, rigidly.
//!
//! A particle's *frame* is the rotation that best maps the rest vectors to its linked
//! neighbours onto their current vectors (the rotation of `Σ (xⱼ − xᵢ)(rⱼ − rᵢ)ᵀ`,
//! extracted warm-started from the last frame's, as in ARAP's local step). A vertex is
//! the weighted mean of where each of its particles carries it,
//! `Σ wᵢ (xᵢ + Rᵢ (v̄ − r̄ᵢ))`: a rigid motion of the body moves every vertex rigidly, and
//! a vertex between stretched particles lands between them. Normals are the
//! area-weighted means of the triangles' normals around each vertex.
//!
//! A particle with one link (or a chain of them) fixes no rotation about that link: its
//! frame keeps the last frame's twist there.

use super::carry::CarryLayout;
use super::extract::SurfaceTopology;
use crate::math::lanes::{LANES, Mat3x8, Quatx8, Vec3x8};
use crate::math::rotation::extract_rotation_x8;
use crate::math::simd::{Lane, WithLanes, dispatch};
use glam::{Mat3A, Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Rotation iterations per frame: frames turn little between frames, and each iteration
/// starts from the last frame's.
const ITERATIONS: u32 = 2;

/// Vertices (or carriers) per parallel task.
const PER_TASK: usize = 1024;

/// Updates the carriers' `frames` (warm starts in, results out) and their rotation
/// matrices `rotations`, from `positions` (one per slot of `layout`).
///
/// # Panics
/// When the lengths of `positions`, `frames` or `rotations` are not the layout's.
pub fn particle_frames(
    layout: &CarryLayout,
    positions: &[Vec3A],
    frames: &mut [Quat],
    rotations: &mut [Mat3A],
) {
    assert_eq!(positions.len(), layout.read.len(), "a position per slot");
    assert_eq!(frames.len(), layout.carrier_count(), "a frame per carrier");
    assert_eq!(
        rotations.len(),
        layout.carrier_count(),
        "a rotation per carrier"
    );
    frames
        .par_chunks_mut(PER_TASK)
        .zip(rotations.par_chunks_mut(PER_TASK))
        .enumerate()
        .for_each(|(task, (frames, rotations))| {
            dispatch(FrameTask {
                layout,
                positions,
                first: task * PER_TASK,
                frames,
                rotations,
            })
        });
}

/// The frames of one task's carriers, eight at a time.
struct FrameTask<'a> {
    layout: &'a CarryLayout,
    positions: &'a [Vec3A],
    /// The carrier of `frames[0]`.
    first: usize,
    frames: &'a mut [Quat],
    rotations: &'a mut [Mat3A],
}

impl WithLanes for FrameTask<'_> {
    type Output = ();
    #[inline(always)]
    fn run<L: Lane>(self) {
        for (b, batch) in self.layout.batches[self.first / LANES..].iter().enumerate() {
            let start = b * LANES;
            if start >= self.frames.len() {
                break;
            }
            let centre = gather::<L>(self.positions, &batch.own);
            let mut a = Mat3x8::<L>::ZERO;
            for (links, spoke) in batch.links.iter().zip(&batch.spokes) {
                let dx = gather::<L>(self.positions, links) - centre;
                let dr = Vec3x8::<L>::load(spoke);
                a.x_axis = dx.mul_add(dr.x, a.x_axis);
                a.y_axis = dx.mul_add(dr.y, a.y_axis);
                a.z_axis = dx.mul_add(dr.z, a.z_axis);
            }
            let mut warm = [Quat::IDENTITY; LANES];
            for (l, w) in warm.iter_mut().enumerate() {
                *w = self.frames[batch.own[l] as usize - self.first];
            }
            let q = extract_rotation_x8(&a, Quatx8::from_lanes(warm), ITERATIONS);
            let (q, r) = (q.to_lanes(), Mat3x8::from_quat(q).to_lanes());
            let n = LANES.min(self.frames.len() - start);
            self.frames[start..start + n].copy_from_slice(&q[..n]);
            self.rotations[start..start + n].copy_from_slice(&r[..n]);
        }
    }
}

/// The positions of eight slots, one per lane.
#[inline(always)]
fn gather<L: Lane>(positions: &[Vec3A], slots: &[u32; LANES]) -> Vec3x8<L> {
    let mut v = [Vec3A::ZERO; LANES];
    for (v, &s) in v.iter_mut().zip(slots) {
        *v = positions[s as usize];
    }
    Vec3x8::from_lanes(v)
}

/// The vertices' positions from the slots' `positions` and the carriers' `rotations`,
/// into `out`.
pub fn vertex_positions(
    topology: &SurfaceTopology,
    layout: &CarryLayout,
    positions: &[Vec3A],
    rotations: &[Mat3A],
    out: &mut Vec<Vec3>,
) {
    out.resize(topology.vertex_count(), Vec3::ZERO);
    let (start, bindings) = (&topology.binding_start, &topology.bindings);
    // (a plain loop per task: the vertices are many and each is a few instructions)
    (out.par_chunks_mut(PER_TASK).enumerate()).for_each(|(task, out)| {
        for (v, at) in (task * PER_TASK..).zip(out) {
            let range = start[v] as usize..start[v + 1] as usize;
            let mut sum = Vec3A::ZERO;
            for (b, &s) in bindings[range.clone()]
                .iter()
                .zip(&layout.binding_slots[range])
            {
                let s = s as usize;
                sum += b.weight * (positions[s] + rotations[s] * Vec3A::from(b.offset));
            }
            *at = sum.into();
        }
    });
}

/// Unit vertex normals of the topology's triangles over `positions` (area-weighted),
/// into `out`, with `faces` as scratch; a vertex whose triangles have no area gets a
/// zero normal.
pub fn vertex_normals(
    topology: &SurfaceTopology,
    layout: &CarryLayout,
    positions: &[Vec3],
    faces: &mut Vec<Vec3A>,
    out: &mut Vec<Vec3>,
) {
    faces.resize(topology.triangles.len(), Vec3A::ZERO);
    (faces.par_chunks_mut(PER_TASK))
        .zip(topology.triangles.par_chunks(PER_TASK))
        .for_each(|(faces, triangles)| {
            for (n, t) in faces.iter_mut().zip(triangles) {
                let a = Vec3A::from(positions[t[0] as usize]);
                let b = Vec3A::from(positions[t[1] as usize]);
                let c = Vec3A::from(positions[t[2] as usize]);
                // twice the area times the unit normal
                *n = (b - a).cross(c - a);
            }
        });
    out.resize(positions.len(), Vec3::ZERO);
    let (start, around) = (&layout.triangle_start, &layout.vertex_triangles);
    (out.par_chunks_mut(PER_TASK).enumerate()).for_each(|(task, out)| {
        for (v, n) in (task * PER_TASK..).zip(out) {
            let mut sum = Vec3A::ZERO;
            for &t in &around[start[v] as usize..start[v + 1] as usize] {
                sum += faces[t as usize];
            }
            *n = sum.normalize_or_zero().into();
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::lattice::Lattice;
    use crate::body::shape::Shape;
    use crate::surface::extract::extract;
    use glam::UVec3;

    /// The vertices of `t` where the particles carry them when each particle of `l`
    /// sits at `map` of its rest position (the frames given ten frames to settle), and
    /// their normals.
    fn carried(
        l: &Lattice,
        t: &SurfaceTopology,
        map: impl Fn(Vec3) -> Vec3,
    ) -> (Vec<Vec3>, Vec<Vec3>) {
        let layout = CarryLayout::new(l, t);
        let moved: Vec<Vec3A> = layout
            .read
            .iter()
            .map(|&p| map(l.rest_position(p)).into())
            .collect();
        let mut frames = vec![Quat::IDENTITY; layout.carrier_count()];
        let mut rotations = vec![Mat3A::IDENTITY; layout.carrier_count()];
        for _ in 0..10 {
            particle_frames(&layout, &moved, &mut frames, &mut rotations);
        }
        let (mut at, mut normals) = (Vec::new(), Vec::new());
        vertex_positions(t, &layout, &moved, &rotations, &mut at);
        vertex_normals(t, &layout, &at, &mut Vec::new(), &mut normals);
        (at, normals)
    }

    #[test]
    fn a_rigid_motion_moves_every_vertex_rigidly() {
        let l = Shape::cuboid(UVec3::new(4, 3, 2)).voxelise(0.5).unwrap();
        let t = extract(&l);
        let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 0.7);
        let shift = Vec3::new(3.0, -2.0, 0.5);
        let (at, normals) = carried(&l, &t, |x| turn * x + shift);
        for (v, x) in at.iter().enumerate() {
            let expected = turn * t.rest[v] + shift;
            assert!((*x - expected).length() < 1e-5, "{x} vs {expected}");
        }
        // a box corner's normal points away from the box's centre
        let centre = turn * (l.rest_position(0) + l.rest_position(l.len() as u32 - 1)) / 2.0;
        for (x, n) in at.iter().zip(&normals) {
            assert!((*x - shift - centre).dot(*n) > 0.0);
        }
    }

    #[test]
    fn a_twisted_box_flips_no_triangle_and_keeps_its_volume() {
        // a 6×6×16 box twisted a quarter turn about its long axis: each layer turned
        // by an angle growing with its height
        let l = Shape::cuboid(UVec3::new(6, 6, 16)).voxelise(1.0).unwrap();
        let t = extract(&l);
        let centre = Vec3::new(3.0, 3.0, 0.0);
        let twist = |z: f32| Quat::from_rotation_z(std::f32::consts::FRAC_PI_2 * z / 16.0);
        let twisted = |x: Vec3| twist(x.z) * (x - centre) + centre;
        let (at, _) = carried(&l, &t, twisted);
        let normal = |x: &[Vec3], tri: &[u32; 3]| {
            let [a, b, c] = tri.map(|v| x[v as usize]);
            (b - a).cross(c - a).normalize()
        };
        let volume = |x: &[Vec3]| -> f32 {
            t.triangles
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|v| x[v as usize]);
                    a.dot(b.cross(c)) / 6.0
                })
                .sum()
        };
        // the exact normal: the rest normal through the twist's deformation gradient
        // F = [R eₓ, R e_y, R e_z + θ′ e_z × R (x − c)], turned by F⁻ᵀ
        let rate = std::f32::consts::FRAC_PI_2 / 16.0;
        for tri in &t.triangles {
            let x = tri.iter().map(|v| t.rest[*v as usize]).sum::<Vec3>() / 3.0;
            let r = twist(x.z);
            let f = glam::Mat3::from_cols(r * Vec3::X, r * Vec3::Y, r * Vec3::Z)
                + glam::Mat3::from_cols(
                    Vec3::ZERO,
                    Vec3::ZERO,
                    rate * Vec3::Z.cross(r * (x - centre)),
                );
            let expected = (f.inverse().transpose() * normal(&t.rest, tri)).normalize();
            let got = normal(&at, tri);
            assert!(got.dot(expected) > 0.95, "{got} vs {expected}");
        }
        // a twist keeps the volume; the corners, carried rigidly by particles that the
        // twist shears, follow it to within 2 %
        let ratio = volume(&at) / volume(&t.rest);
        assert!((ratio - 1.0).abs() < 0.02, "{ratio}");
    }
}
