//! Tearing from strain: a body tears where a voxel (the cube of 8 particles at the
//! corners of one lattice cell) is stretched beyond the material's `tear_stretch`.
//!
//! A voxel's deformation gradient F maps its rest corner offsets onto its current ones
//! (least squares over the 8 corners); its largest principal stretch is the square root
//! of the largest eigenvalue of FᵀF, and the matching eigenvector is the rest direction
//! in which it stretches most. A torn voxel loses its 4 edges along the lattice axis
//! nearest that direction: the crack opens across the pull. (Severing all 12 edges would
//! leave strands of particles hanging from the crack faces.) The strongest stretches
//! tear first, at most a budget of voxels per frame, and a tear that would cut off a
//! piece smaller than the material's smallest piece is taken back, so a body does not
//! crumble into dust where it is crushed or whipped.

use crate::body::lattice::Lattice;
use glam::{IVec3, Mat3, Vec3};
use rayon::prelude::*;

/// The corner offsets of a voxel, corner `k` at `(k & 1, k >> 1 & 1, k >> 2 & 1)`.
const CORNERS: [IVec3; 8] = [
    IVec3::new(0, 0, 0),
    IVec3::new(1, 0, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(1, 1, 0),
    IVec3::new(0, 0, 1),
    IVec3::new(1, 0, 1),
    IVec3::new(0, 1, 1),
    IVec3::new(1, 1, 1),
];

/// The deformation gradient of a voxel of spacing `h` whose corners (corner k at cell
/// offset `(k & 1, k >> 1 & 1, k >> 2 & 1)`) are now at `x`: the least-squares F with
/// `x_k − x̄ ≈ F (X_k − X̄)`. The rest offsets are `(h/2)·s_k` with `s_k ∈ {±1}³`, whose moment matrix is `2h²·I`, so
/// `F = Σ_k (x_k − x̄) s_kᵀ / (4h)`.
pub fn deformation_gradient(x: &[Vec3; 8], h: f32) -> Mat3 {
    let mean = x.iter().copied().sum::<Vec3>() / 8.0;
    let mut f = Mat3::ZERO;
    for (k, xk) in x.iter().enumerate() {
        let s = CORNERS[k].as_vec3() * 2.0 - Vec3::ONE;
        let d = *xk - mean;
        f += Mat3::from_cols(d * s.x, d * s.y, d * s.z);
    }
    f * (1.0 / (4.0 * h))
}

/// The largest principal stretch of `f` and its rest direction (a unit vector): the
/// square root of the largest eigenvalue of the symmetric `FᵀF`, found in closed form
/// (the trigonometric solution of the characteristic cubic), and its eigenvector.
pub fn largest_stretch(f: Mat3) -> (f32, Vec3) {
    let c = f.transpose() * f;
    let (a, b) = (c.x_axis, c.y_axis);
    let cc = c.z_axis;
    let off = a.y * a.y + a.z * a.z + b.z * b.z;
    let q = (a.x + b.y + cc.z) / 3.0;
    let p2 = (a.x - q).powi(2) + (b.y - q).powi(2) + (cc.z - q).powi(2) + 2.0 * off;
    let p = (p2 / 6.0).sqrt();
    let lambda = if p <= 1e-12 * q.abs().max(1e-30) {
        q
    } else {
        let m = (c - Mat3::from_diagonal(Vec3::splat(q))) * (1.0 / p);
        let r = (m.determinant() * 0.5).clamp(-1.0, 1.0);
        q + 2.0 * p * (r.acos() / 3.0).cos()
    };
    // the eigenvector: the largest cross product of two rows of C − λI
    let m = c - Mat3::from_diagonal(Vec3::splat(lambda));
    let rows = [m.row(0), m.row(1), m.row(2)];
    let candidates = [
        rows[0].cross(rows[1]),
        rows[1].cross(rows[2]),
        rows[2].cross(rows[0]),
    ];
    let best = candidates
        .into_iter()
        .max_by(|u, v| u.length_squared().total_cmp(&v.length_squared()))
        .unwrap_or(Vec3::X);
    let direction = best.try_normalize().unwrap_or(Vec3::X);
    (lambda.max(0.0).sqrt(), direction)
}

/// The 8 live corners of the voxel whose lowest corner is particle `p` (by lattice
/// cell), or `None` where a corner is missing.
fn voxel_corners(lattice: &Lattice, p: u32) -> Option<[u32; 8]> {
    let c = lattice.coord(p);
    if lattice.at(c) != Some(p) {
        return None;
    }
    let mut out = [p; 8];
    for (k, o) in CORNERS.iter().enumerate().skip(1) {
        out[k] = lattice.at(c + *o)?;
    }
    Some(out)
}

/// The voxel edges along axis `axis` (0 x, 1 y, 2 z) as corner pairs.
fn edges_along(axis: usize) -> [(usize, usize); 4] {
    let bit = 1 << axis;
    let mut out = [(0, 0); 4];
    let mut n = 0;
    for k in 0..8 {
        if k & bit == 0 {
            out[n] = (k, k | bit);
            n += 1;
        }
    }
    out
}

/// Whether corners `a` and `b` of a voxel (neighbours along axis `axis`) are linked.
fn linked(lattice: &Lattice, a: u32, b: u32, axis: usize) -> bool {
    lattice.link(a, 2 * axis + 1) == b
}

/// A voxel stretched past the limit: its stretch, and the edges it would lose.
#[derive(Clone, Debug, PartialEq)]
pub struct Tear {
    /// Largest principal stretch.
    pub stretch: f32,
    /// The voxel's lowest corner.
    pub voxel: u32,
    /// Its 8 corners (corner k at cell offset `(k & 1, k >> 1 & 1, k >> 2 & 1)`).
    pub corners: [u32; 8],
    /// The crack plane it opens: the axis and the lowest corner's coordinate on it.
    pub plane: (usize, i32),
    /// Its edges along the axis nearest the stretch direction that are still linked,
    /// `(a, b)` with `a < b`.
    pub edges: Vec<(u32, u32)>,
}

/// The tears of a body this frame: the voxels whose largest principal stretch exceeds
/// `tear_stretch`, strongest first (ties by voxel), at most `budget` of them.
///
/// Not candidates: a voxel already torn open along some axis (all 4 edges of that axis
/// severed: its corners have parted, its stretch no longer measures the material), and
/// a voxel with a `held` corner (a pinned particle: a grip holds the material it grips).
/// And a voxel that shares a corner with a stronger one torn this frame across another
/// plane waits: the stronger tear relieves it, or it tears later, so one frame opens
/// one crack where two parallel layers are both over the limit, not a slab of loose
/// particles between them. `position` gives a live particle's current position.
pub fn find_tears(
    lattice: &Lattice,
    position: impl Fn(u32) -> Vec3 + Sync,
    held: impl Fn(u32) -> bool + Sync,
    tear_stretch: f32,
    budget: usize,
) -> Vec<Tear> {
    let h = lattice.spacing();
    let live: Vec<u32> = lattice.live_particles().collect();
    let mut tears: Vec<Tear> = live
        .par_iter()
        .with_min_len(1024)
        .filter_map(|&p| {
            let corners = voxel_corners(lattice, p)?;
            if corners.iter().any(|&c| held(c)) {
                return None;
            }
            let open = (0..3).any(|axis| {
                edges_along(axis)
                    .iter()
                    .all(|&(a, b)| !linked(lattice, corners[a], corners[b], axis))
            });
            if open {
                return None;
            }
            let x = corners.map(&position);
            let (stretch, direction) = largest_stretch(deformation_gradient(&x, h));
            if stretch.is_nan() || stretch <= tear_stretch {
                return None;
            }
            let axis = direction.abs().max_position();
            let edges: Vec<(u32, u32)> = edges_along(axis)
                .iter()
                .filter(|&&(a, b)| linked(lattice, corners[a], corners[b], axis))
                .map(|&(a, b)| (corners[a].min(corners[b]), corners[a].max(corners[b])))
                .collect();
            (!edges.is_empty()).then_some(Tear {
                stretch,
                voxel: p,
                corners,
                plane: (axis, lattice.coord(p)[axis]),
                edges,
            })
        })
        .collect();
    tears.sort_by(|a, b| b.stretch.total_cmp(&a.stretch).then(a.voxel.cmp(&b.voxel)));
    // the crack plane of the torn voxel each corner belongs to
    let mut plane_at: rustc_hash::FxHashMap<u32, (usize, i32)> = Default::default();
    let mut chosen = Vec::new();
    for tear in tears {
        if chosen.len() == budget {
            break;
        }
        let clash = tear
            .corners
            .iter()
            .any(|c| plane_at.get(c).is_some_and(|plane| *plane != tear.plane));
        if clash {
            continue;
        }
        for c in tear.corners {
            plane_at.insert(c, tear.plane);
        }
        chosen.push(tear);
    }
    chosen
}

/// Severs `edges` (torn this frame), then links back those that cut off a piece of
/// fewer than `min_piece` particles. Returns the edges that stay severed, in order.
pub fn sever_keeping_pieces(
    lattice: &mut Lattice,
    edges: &[(u32, u32)],
    min_piece: usize,
) -> Vec<(u32, u32)> {
    let severed: Vec<(u32, u32)> = edges
        .iter()
        .copied()
        .filter(|&(a, b)| lattice.sever(a, b))
        .collect();
    if severed.is_empty() || min_piece <= 1 {
        return severed;
    }
    let labels = lattice.pieces();
    let mut size = vec![0usize; labels.count];
    for p in lattice.live_particles() {
        size[labels.label[p as usize] as usize] += 1;
    }
    let small = |p: u32| size[labels.label[p as usize] as usize] < min_piece;
    let (kept, restored): (Vec<_>, Vec<_>) = severed
        .into_iter()
        .partition(|&(a, b)| !small(a) && !small(b));
    for (a, b) in restored {
        lattice.relink(a, b);
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Quat, UVec3};

    fn cube(h: f32, map: impl Fn(Vec3) -> Vec3) -> [Vec3; 8] {
        CORNERS.map(|c| map((c.as_vec3() - Vec3::splat(0.5)) * h))
    }

    #[test]
    fn a_pure_rotation_has_stretch_one() {
        for (axis, angle) in [
            (Vec3::X, 0.3),
            (Vec3::new(1.0, 2.0, -0.5), 2.5),
            (Vec3::Z, 3.1),
        ] {
            let r = Quat::from_axis_angle(axis.normalize(), angle);
            let x = cube(0.1, |p| r * p + Vec3::new(3.0, -1.0, 2.0));
            let (s, _) = largest_stretch(deformation_gradient(&x, 0.1));
            assert!((s - 1.0).abs() < 1e-4, "{s}");
        }
    }

    #[test]
    fn uniform_and_axial_stretches_are_found_with_their_direction() {
        let s = 1.7;
        let x = cube(0.1, |p| p * s);
        let (found, _) = largest_stretch(deformation_gradient(&x, 0.1));
        assert!((found - s).abs() < 1e-4, "{found}");
        // stretched 2.5× along y, squeezed along x, then rotated: stretch 2.5 along y
        let r = Quat::from_rotation_z(0.7);
        let x = cube(0.1, |p| r * Vec3::new(0.8 * p.x, 2.5 * p.y, p.z));
        let (found, direction) = largest_stretch(deformation_gradient(&x, 0.1));
        assert!((found - 2.5).abs() < 1e-3, "{found}");
        assert!(direction.y.abs() > 0.999, "{direction}");
        // a shear: F = [[1, γ], [0, 1]], largest stretch (γ + √(γ² + 4)) / 2
        let g = 0.8;
        let x = cube(0.1, |p| Vec3::new(p.x + g * p.y, p.y, p.z));
        let (found, _) = largest_stretch(deformation_gradient(&x, 0.1));
        let expected = (g + (g * g + 4.0f32).sqrt()) / 2.0;
        assert!((found - expected).abs() < 1e-4, "{found} vs {expected}");
    }

    #[test]
    fn a_pulled_bar_tears_across_the_pull_and_small_pieces_are_kept() {
        let mut lattice = crate::body::shape::Shape::cuboid(UVec3::new(8, 3, 3))
            .voxelise(1.0)
            .unwrap();
        // the cells at x ≥ 0 moved 0.8 further along x: the voxels between x = −1 and 0
        // stretch 1.8× along x
        let at = |p: u32| {
            let r = lattice.rest_position(p);
            r + Vec3::X * if lattice.coord(p).x >= 0 { 0.8 } else { 0.0 }
        };
        let tears = find_tears(&lattice, at, |_| false, 1.5, 100);
        assert_eq!(tears.len(), 4, "{tears:?}");
        for t in &tears {
            assert!((t.stretch - 1.8).abs() < 0.05, "{}", t.stretch);
            for &(a, b) in &t.edges {
                assert_eq!(lattice.coord(b) - lattice.coord(a), IVec3::X);
            }
        }
        let edges: Vec<(u32, u32)> = tears.iter().flat_map(|t| t.edges.clone()).collect();
        // a budget of one takes the strongest alone
        assert_eq!(find_tears(&lattice, at, |_| false, 1.5, 1).len(), 1);
        // held corners do not tear
        assert!(find_tears(&lattice, at, |p| lattice.coord(p).x == 0, 1.5, 100).is_empty());
        // 36 particles per half: a smallest piece of 37 takes the tear back
        let mut kept = lattice.clone();
        assert!(sever_keeping_pieces(&mut kept, &edges, 37).is_empty());
        assert_eq!(kept.piece_count(), 1);
        assert_eq!(kept.edges(), lattice.edges());
        let severed = sever_keeping_pieces(&mut lattice, &edges, 36);
        assert_eq!(severed.len(), 9);
        assert_eq!(lattice.piece_count(), 2);
    }
}
