//! A render mesh cut where the tools passed: its triangles that span a cut are clipped
//! at the cut, and each piece's rim is closed by a cap, so that the mesh a piece draws
//! is closed (every edge in two triangles) and its cut face lies where the blade went.
//!
//! **Sides.** Each vertex of the mesh belongs to a piece: where a cut passes among the
//! particles around it, the piece on its own side of the cut (its nearest particle
//! there); else the piece of the particle carrying most of it. A vertex carried by particles of other pieces than its
//! own is bound again to its own piece's alone, so that pieces that part do not stretch
//! it between them.
//!
//! **Clipping.** An edge of the mesh whose two vertices belong to different pieces
//! crosses the cut there: where, is found from the crossings the tools left on the
//! lattice edges of its vertices' particles ([`crate::body::crossings`]) — the plane
//! through their mean point with their mean normal; the edge's middle where there is
//! none. Both sides get a vertex of their own at that point, bound to their own
//! particles, shared by the two triangles of the edge, so that the clipped triangles
//! meet edge to edge. A triangle with vertices in two pieces becomes a triangle on one
//! side and a quad on the other; one whose vertices lie in three pieces (a corner where
//! cuts meet) stays whole, in its first vertex's piece.
//!
//! **Caps.** The clipped triangles' new edges on one side form loops around the cut
//! (the mesh being closed); each loop is closed by a fan from a vertex at its mean
//! point, bound to the side's particles, its triangles turned against the loop's.

use super::extract::{Binding, SurfaceTopology};
use super::trilinear::bind_vertex;
use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS};
use glam::{IVec3, Vec3};
use rustc_hash::FxHashMap;

/// The side of a mesh vertex resting at `at`: where a cut passes among the particles of
/// the 27 cells around it (the crossings on their edges), the piece of the nearest of
/// them on its own side of the cut; elsewhere the piece of the particle carrying most
/// of it. (A vertex of the mesh lies up to half a cell beyond the particles carrying
/// it, so a cut close to the outside can pass between them and it.)
fn piece_of(lattice: &Lattice, at: Vec3, bindings: &[Binding]) -> u32 {
    let label = &lattice.pieces().label;
    let cell = (at / lattice.spacing() - Vec3::splat(0.5))
        .round()
        .as_ivec3();
    let around: Vec<u32> = (0..27)
        .filter_map(|k| lattice.at(cell + IVec3::new(k % 3, k / 3 % 3, k / 9) - IVec3::ONE))
        .collect();
    let first = around.first().map(|&p| label[p as usize]);
    if around.iter().any(|&p| Some(label[p as usize]) != first)
        && let Some((c, n)) = cut_plane(lattice, &around)
    {
        let side = n.dot(at - c) >= 0.0;
        let nearest = (around.iter())
            .filter(|&&p| (n.dot(lattice.rest_position(p) - c) >= 0.0) == side)
            .min_by(|&&a, &&b| {
                let d = |p: u32| lattice.rest_position(p).distance_squared(at);
                d(a).total_cmp(&d(b)).then(a.cmp(&b))
            });
        if let Some(&p) = nearest {
            return label[p as usize];
        }
    }
    bindings
        .iter()
        .max_by(|a, b| {
            a.weight
                .total_cmp(&b.weight)
                .then(b.particle.cmp(&a.particle))
        })
        .map_or(u32::MAX, |b| label[b.particle as usize])
}

/// Where the cut between the particles `around` lies: the mean point and normal of the
/// crossings on their lattice edges (rest frame); `None` without a crossing.
fn cut_plane(lattice: &Lattice, around: &[u32]) -> Option<(Vec3, Vec3)> {
    let (mut at, mut normal, mut n) = (Vec3::ZERO, Vec3::ZERO, 0);
    // (measured between the cells' centres: a split half rests off its own)
    let centre = |p: u32| (lattice.coord(p).as_vec3() + Vec3::splat(0.5)) * lattice.spacing();
    for &p in around {
        for offset in NEIGHBOUR_OFFSETS {
            let Some(q) = lattice.at(lattice.coord(p) + offset) else {
                continue;
            };
            let Some(c) = lattice.crossing_between(p, q) else {
                continue;
            };
            let (rp, rq) = (centre(p), centre(q));
            at += rp + c.fraction * (rq - rp);
            // (normals either way round: turned to agree with the first)
            normal += if n > 0 && c.normal.dot(normal) < 0.0 {
                -c.normal
            } else {
                c.normal
            };
            n += 1;
        }
    }
    let normal = normal.try_normalize()?;
    Some((at / n as f32, normal))
}

/// The mesh `mesh` (vertices bound to `lattice`'s particles) clipped at its cuts and
/// capped, appended to `out` — its vertices first, in order and of the same number,
/// then the clipped and capping ones — with each triangle's piece; triangles of the mesh
/// that `skip` names (carried by a particle no longer live) are left out.
pub fn clip(
    lattice: &Lattice,
    mesh: &SurfaceTopology,
    skip: impl Fn(usize) -> bool,
    out: &mut SurfaceTopology,
) {
    let label = &lattice.pieces().label;
    let vertices = mesh.vertex_count();
    let side: Vec<u32> = (0..vertices)
        .map(|v| piece_of(lattice, mesh.rest[v], mesh.bindings_of(v)))
        .collect();
    // the mesh's vertices, each bound to its own side's particles alone
    out.rest = mesh.rest.clone();
    out.binding_start = vec![0];
    out.bindings.clear();
    for (v, &piece) in side.iter().enumerate() {
        let own = mesh.bindings_of(v);
        // (kept as it was when all of its own piece, or none of it is near)
        let mixed = !own.iter().all(|b| label[b.particle as usize] == piece);
        if !mixed || bind_vertex(lattice, mesh.rest[v], Some(piece), &mut out.bindings).is_none() {
            out.bindings.extend_from_slice(own);
        }
        out.binding_start.push(out.bindings.len() as u32);
    }
    // the vertex each side has where an edge crosses the cut
    let mut crossing: FxHashMap<(u32, u32), (u32, u32)> = FxHashMap::default();
    // each side's new edges along the cut, wound as the clipped triangles wind them
    let mut rims: FxHashMap<u32, Vec<[u32; 2]>> = FxHashMap::default();
    let mut add = |out: &mut SurfaceTopology, at: Vec3, piece: u32| -> u32 {
        let v = out.rest.len() as u32;
        out.rest.push(at);
        if bind_vertex(lattice, at, Some(piece), &mut out.bindings).is_none() {
            // (nothing of the piece within reach: the nearest particle of any)
            bind_vertex(lattice, at, None, &mut out.bindings);
        }
        out.binding_start.push(out.bindings.len() as u32);
        v
    };
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if skip(t) {
            continue;
        }
        let s = tri.map(|v| side[v as usize]);
        if s[0] == s[1] && s[1] == s[2] || s[0] != s[1] && s[1] != s[2] && s[0] != s[2] {
            out.triangles.push(*tri);
            out.triangle_piece.push(s[0]);
            continue;
        }
        // the vertex alone on its side first: (lone, a, b) in the triangle's winding
        // (the triangle is not all one side, so two sides leave one vertex alone and
        // three leave every vertex alone)
        let k = (0..3)
            .find(|&k| s[k] != s[(k + 1) % 3] && s[k] != s[(k + 2) % 3])
            .expect("one vertex alone");
        let (lone, a, b) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let (lone_side, other) = (side[lone as usize], side[a as usize]);
        let mut meet = |x: u32, y: u32, out: &mut SurfaceTopology| -> (u32, u32) {
            let key = (x.min(y), x.max(y));
            if let Some(&(low, high)) = crossing.get(&key) {
                return if x < y { (low, high) } else { (high, low) };
            }
            let (rx, ry) = (mesh.rest[x as usize], mesh.rest[y as usize]);
            let around: Vec<u32> = (mesh.bindings_of(x as usize).iter())
                .chain(mesh.bindings_of(y as usize))
                .map(|b| b.particle)
                .filter(|&p| lattice.is_live(p))
                .collect();
            let t = cut_plane(lattice, &around)
                .and_then(|(c, n)| {
                    let (dx, dy) = (n.dot(rx - c), n.dot(ry - c));
                    (dx != dy).then(|| (dx / (dx - dy)).clamp(0.0, 1.0))
                })
                .unwrap_or(0.5);
            let at = rx + t * (ry - rx);
            let (vx, vy) = (
                add(out, at, side[x as usize]),
                add(out, at, side[y as usize]),
            );
            crossing.insert(key, if x < y { (vx, vy) } else { (vy, vx) });
            (vx, vy)
        };
        // the cut meets lone–a at p and b–lone at q
        let (p_lone, p_other) = meet(lone, a, out);
        let (q_other, q_lone) = meet(b, lone, out);
        out.triangles.push([lone, p_lone, q_lone]);
        out.triangle_piece.push(lone_side);
        out.triangles.push([p_other, a, b]);
        out.triangles.push([p_other, b, q_other]);
        out.triangle_piece.extend([other, other]);
        // the new edges, as these triangles run along them
        rims.entry(lone_side).or_default().push([p_lone, q_lone]);
        rims.entry(other).or_default().push([q_other, p_other]);
    }
    let mut sides: Vec<u32> = rims.keys().copied().collect();
    sides.sort_unstable();
    for piece in sides {
        cap(&rims[&piece], piece, &mut add, out);
    }
}

/// Closes the loops of `rim` (edges wound as the clipped triangles of `piece` run along
/// them) with a fan each from a new vertex at the loop's mean point.
fn cap(
    rim: &[[u32; 2]],
    piece: u32,
    add: &mut impl FnMut(&mut SurfaceTopology, Vec3, u32) -> u32,
    out: &mut SurfaceTopology,
) {
    // loops: the edges' components (union–find over their vertices)
    let mut parent: FxHashMap<u32, u32> = FxHashMap::default();
    fn find(parent: &mut FxHashMap<u32, u32>, x: u32) -> u32 {
        let mut r = x;
        while let Some(&p) = parent.get(&r).filter(|&&p| p != r) {
            r = p;
        }
        parent.insert(x, r);
        r
    }
    for &[a, b] in rim {
        parent.entry(a).or_insert(a);
        parent.entry(b).or_insert(b);
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent.insert(ra.max(rb), ra.min(rb));
        }
    }
    let mut loops: Vec<(u32, Vec<[u32; 2]>)> = Vec::new();
    for &edge in rim {
        let root = find(&mut parent, edge[0]);
        match loops.iter_mut().find(|(r, _)| *r == root) {
            Some((_, edges)) => edges.push(edge),
            None => loops.push((root, vec![edge])),
        }
    }
    for (_, edges) in loops {
        let mut mean = Vec3::ZERO;
        for &[a, _] in &edges {
            mean += out.rest[a as usize];
        }
        let centre = add(out, mean / edges.len() as f32, piece);
        for [a, b] in edges {
            out.triangles.push([b, a, centre]);
            out.triangle_piece.push(piece);
        }
    }
}
