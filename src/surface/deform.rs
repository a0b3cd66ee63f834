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

use super::extract::SurfaceTopology;
use crate::body::lattice::Lattice;
use crate::math::rotation::extract_rotation;
use glam::{Mat3A, Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Rotation iterations per frame: frames turn little between frames, and each iteration
/// starts from the last frame's.
const ITERATIONS: u32 = 4;

/// Vertices per parallel task.
const PER_TASK: usize = 1024;

/// Updates `frames[p]` for every particle `p` of `topology`, from `positions` (indexed
/// by particle; read at those particles and their linked neighbours).
pub fn particle_frames(
    lattice: &Lattice,
    topology: &SurfaceTopology,
    positions: &[Vec3],
    frames: &mut [Quat],
) {
    let updated: Vec<Quat> = topology
        .particles
        .par_iter()
        .with_min_len(PER_TASK)
        .map(|&p| {
            let (x, r) = (positions[p as usize], lattice.rest_position(p));
            let mut a = Mat3A::ZERO;
            for q in lattice.neighbours(p) {
                let dx = Vec3A::from(positions[q as usize] - x);
                let dr = Vec3A::from(lattice.rest_position(q) - r);
                a += Mat3A::from_cols(dx * dr.x, dx * dr.y, dx * dr.z);
            }
            extract_rotation(a, frames[p as usize], ITERATIONS)
        })
        .collect();
    for (&p, q) in topology.particles.iter().zip(updated) {
        frames[p as usize] = q;
    }
}

/// The vertices' positions from the particles' `positions` and `frames` (indexed by
/// particle), into `out`.
pub fn vertex_positions(
    topology: &SurfaceTopology,
    positions: &[Vec3],
    frames: &[Quat],
    out: &mut Vec<Vec3>,
) {
    out.resize(topology.vertex_count(), Vec3::ZERO);
    out.par_iter_mut()
        .with_min_len(PER_TASK)
        .enumerate()
        .for_each(|(v, at)| {
            *at = topology
                .bindings_of(v)
                .iter()
                .map(|b| {
                    let p = b.particle as usize;
                    b.weight * (positions[p] + frames[p] * b.offset)
                })
                .sum();
        });
}

/// Unit vertex normals of `triangles` over `positions` (area-weighted), into `out`; a
/// vertex whose triangles have no area gets a zero normal.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]], out: &mut Vec<Vec3>) {
    out.clear();
    out.resize(positions.len(), Vec3::ZERO);
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // twice the area times the unit normal
        let n = (b - a).cross(c - a);
        for i in t {
            out[*i as usize] += n;
        }
    }
    out.par_iter_mut()
        .with_min_len(PER_TASK)
        .for_each(|n| *n = n.normalize_or_zero());
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use crate::surface::extract::extract;
    use glam::UVec3;

    /// The vertices of `t` where the particles carry them when each particle of `l`
    /// sits at `map` of its rest position (the frames given ten frames to settle).
    fn carried(l: &Lattice, t: &SurfaceTopology, map: impl Fn(Vec3) -> Vec3) -> Vec<Vec3> {
        let moved: Vec<Vec3> = (0..l.len() as u32)
            .map(|p| map(l.rest_position(p)))
            .collect();
        let mut frames = vec![Quat::IDENTITY; l.len()];
        for _ in 0..10 {
            particle_frames(l, t, &moved, &mut frames);
        }
        let mut at = Vec::new();
        vertex_positions(t, &moved, &frames, &mut at);
        at
    }

    #[test]
    fn a_rigid_motion_moves_every_vertex_rigidly() {
        let l = Shape::cuboid(UVec3::new(4, 3, 2)).voxelise(0.5).unwrap();
        let t = extract(&l);
        let turn = Quat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 0.7);
        let shift = Vec3::new(3.0, -2.0, 0.5);
        let at = carried(&l, &t, |x| turn * x + shift);
        for (v, x) in at.iter().enumerate() {
            let expected = turn * t.rest[v] + shift;
            assert!((*x - expected).length() < 1e-5, "{x} vs {expected}");
        }
        let mut normals = Vec::new();
        vertex_normals(&at, &t.triangles, &mut normals);
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
        let at = carried(&l, &t, twisted);
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
