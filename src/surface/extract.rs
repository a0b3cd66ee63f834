//! The surface of a body's lattice: a triangle mesh of the boundary of the solid its
//! live particles own ([`super::cells`]), each vertex bound to the particles whose
//! positions carry it ([`super::deform`]).
//!
//! Every sub-cell face between a solid sub-cell and one it is not joined to is a quad
//! (two triangles), wound counter-clockwise seen from outside. Which quads share a
//! corner vertex is decided around each grid edge ([`super::fans`]): going round the
//! edge, each run of joined solid sub-cells is bounded by two quads, and those two
//! share the edge's end vertices. So corners are shared only between particles that
//! stay linked around them: a sever or a split opens the surface into two closed ones
//! along the cut, a severed edge inside a piece leaves a closed slit, and two pieces
//! that touch at a corner or an edge get vertices of their own. A vertex is bound to
//! the particles owning the solid sub-cells joined to its quads around its corner,
//! each weighted by the sub-cells it owns there.

use super::cells::{CellOwners, face_corners, octant};
use super::fans::{Quad, vertex_classes};
use super::placement::{cut_vertex_position, is_cut_face};
use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS};
use crate::util::room::make_room;
use glam::{IVec3, Vec3};
use rayon::prelude::*;

/// The surface's topology and its binding to the particles: what changes only when the
/// lattice does.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SurfaceTopology {
    /// Per vertex, its rest position in the body's lattice frame (the frame of
    /// [`Lattice::rest_position`]).
    pub rest: Vec<Vec3>,
    /// Per vertex `v`, its bindings are `bindings[binding_start[v]..binding_start[v + 1]]`.
    pub binding_start: Vec<u32>,
    /// The particles carrying each vertex; a vertex's weights sum to 1.
    pub bindings: Vec<Binding>,
    /// Triangles (vertex indices), counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, the piece (connected component of the body, as
    /// [`Lattice::pieces`] numbers them) it bounds.
    pub triangle_piece: Vec<u32>,
    /// The particles any vertex is bound to, ascending.
    pub particles: Vec<u32>,
    /// For a lattice's surface, the face each quad lies on (triangles `2q` and `2q + 1`
    /// are quad `q`'s), each vertex's grid corner, and the sub-cells per cell: what a
    /// local update ([`super::update`]) needs. Empty for a render mesh.
    pub(crate) quads: Vec<Quad>,
    pub(crate) corners: Vec<IVec3>,
    pub(crate) resolution: i32,
    /// Per vertex, where placing it on the cut put it: its rest, but for a vertex
    /// [`keep_pieces_whole`] put back at its corner. Empty (read as `rest`: a save
    /// from before it was kept), or one per vertex. Saved, so that a resumed run judges
    /// crushed pieces as the run it continues does.
    #[serde(default)]
    pub(crate) placed: Vec<Vec3>,
    /// Per triangle, what placing its vertices on the cut changed of the volume it
    /// spans with the origin (at `placed` less at its grid corners; 0 at its corners):
    /// [`keep_pieces_whole`]'s terms, kept with the triangles so that a local update
    /// works out only its fresh triangles', and judges a piece as a full extraction
    /// does (one put back is still crushed, and fresh vertices at its corners go back
    /// too). Shorter than `triangles` where not yet worked out.
    #[serde(skip)]
    pub(crate) volume_change: Vec<f64>,
}

/// One particle carrying a vertex.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Binding {
    /// The particle.
    pub particle: u32,
    /// Its share of the vertex.
    pub weight: f32,
    /// The vertex's rest position less the particle's, in the lattice frame.
    pub offset: Vec3,
}

impl SurfaceTopology {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    /// The bindings of vertex `v`.
    pub fn bindings_of(&self, v: usize) -> &[Binding] {
        &self.bindings[self.binding_start[v] as usize..self.binding_start[v + 1] as usize]
    }

    /// What is wrong with a topology read from elsewhere (a save) for a body of
    /// `particles` particles: lengths that disagree, an index out of range, a value that
    /// is not finite; `None` when nothing is.
    pub fn fault(&self, particles: usize) -> Option<&'static str> {
        let vertices = self.rest.len();
        let starts = &self.binding_start;
        if starts.len() != vertices + 1
            || starts.first() != Some(&0)
            || starts.windows(2).any(|w| w[0] > w[1])
            || starts.last().map(|s| *s as usize) != Some(self.bindings.len())
        {
            return Some("its vertices' bindings do not add up");
        }
        if self
            .triangles
            .iter()
            .flatten()
            .any(|v| *v as usize >= vertices)
            || self.triangle_piece.len() != self.triangles.len()
        {
            return Some("a triangle names a vertex it does not have");
        }
        let lattice_faces = !self.quads.is_empty();
        if lattice_faces
            && (self.quads.len() * 2 != self.triangles.len()
                || self.corners.len() != vertices
                || !(1..=2).contains(&self.resolution))
        {
            return Some("its faces do not match its triangles");
        }
        let bound = |p: u32| (p as usize) < particles;
        if !self
            .bindings
            .iter()
            .all(|b| bound(b.particle) && b.weight.is_finite() && b.offset.is_finite())
            || !self.particles.iter().all(|p| bound(*p))
            || !self.particles.windows(2).all(|w| w[0] < w[1])
            || !self.quads.iter().all(|q| bound(q.owner) && q.direction < 6)
        {
            return Some("a binding names a particle the body does not have");
        }
        if !self.rest.iter().chain(&self.placed).all(|x| x.is_finite()) {
            return Some("a vertex rests at a non-finite place");
        }
        if !self.placed.is_empty() && self.placed.len() != vertices {
            return Some("its vertices' placements do not match its vertices");
        }
        None
    }
}

/// The face of the lattice a quad of the surface lies on: between a sub-cell in lattice
/// cell `cell` and one in lattice cell `across` (the same cell for the face between two
/// halves of a split particle).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LatticeFace {
    /// The cell of the solid side.
    pub cell: IVec3,
    /// The cell on the other side.
    pub across: IVec3,
}

/// What a surface takes per face of the lattice, in bytes: two triangles (indices,
/// pieces, normals scratch, the vertex–triangle table: 2 × 44), about one vertex (rest,
/// position and normal: 36; four bindings: 80; its slot, frame and rotation as a
/// carrier: ~80) and the face itself (~16).
pub const BYTES_PER_FACE: u64 = 300;

/// Faces of the boundary of `lattice`'s live cells, each cell one (the surface's quads
/// before any particle is split; a split body draws each cell as 2×2×2 octants, and
/// each of these faces as four).
pub fn face_count(lattice: &Lattice) -> u64 {
    lattice
        .live_particles()
        .map(|p| 6 - lattice.neighbours(p).count() as u64)
        .sum()
}

/// The quads a face is drawn as once a particle of its body is split: its cells are
/// drawn as 2×2×2 octants.
pub const QUADS_PER_SPLIT_FACE: u64 = 4;

/// The quads each face of `lattice`'s surface is drawn as: four once a particle of it is
/// split (its cells then drawn as 2×2×2 octants), else one.
pub fn quads_per_face(lattice: &Lattice) -> u64 {
    if lattice.live_particles().any(|p| lattice.is_split_half(p)) {
        QUADS_PER_SPLIT_FACE
    } else {
        1
    }
}

/// The surface of `lattice` (see the module docs).
pub fn extract(lattice: &Lattice) -> SurfaceTopology {
    extract_with_faces(lattice).0
}

/// [`extract`], with the lattice face of each quad: triangles `2q` and `2q + 1` lie on
/// face `q`.
pub fn extract_with_faces(lattice: &Lattice) -> (SurfaceTopology, Vec<LatticeFace>) {
    let owners = CellOwners::new(lattice);
    // (runs of particles in parallel, joined in order: the quads of the live particles
    // that are not enclosed, by particle, each's sub-cells in order)
    let runs: Vec<Vec<Quad>> = (0..lattice.len().div_ceil(PARTICLES_PER_TASK))
        .into_par_iter()
        .map(|run| {
            let first = run * PARTICLES_PER_TASK;
            let particles = first as u32..(first + PARTICLES_PER_TASK).min(lattice.len()) as u32;
            let mut quads = Vec::new();
            for p in particles.filter(|&p| lattice.is_live(p) && !owners.is_enclosed(p)) {
                for s in owners.owned_by(p) {
                    push_faces(&owners, s, p, &mut quads);
                }
            }
            quads
        })
        .collect();
    // (every list of a surface is made with room: the local updates that follow edit
    // it where it lies, see `make_room`)
    let mut quads = Vec::new();
    make_room(&mut quads, runs.iter().map(Vec::len).sum());
    for run in runs {
        quads.extend_from_slice(&run);
    }
    let classes = vertex_classes(&owners, &quads);
    let class_of = &classes.class_of;
    let mut topology = SurfaceTopology {
        binding_start: vec![0],
        ..SurfaceTopology::default()
    };
    let all: Vec<&[u32]> = (0..classes.len()).map(|c| classes.slots(c)).collect();
    add_vertices(&owners, &quads, &all, &mut topology);
    make_room(&mut topology.triangles, 2 * quads.len());
    (topology.triangles).par_extend(
        (class_of.par_chunks_exact(4))
            .with_min_len(4096)
            .flat_map_iter(|v| quad_triangles([v[0], v[1], v[2], v[3]])),
    );
    // the vertices of cut faces rest on the cut (the cut faces found in parallel)
    let cut_faces: Vec<usize> = (0..quads.len())
        .into_par_iter()
        .with_min_len(4096)
        .filter(|&q| is_cut_face(&owners, &quads[q]))
        .collect();
    let mut on_cut = vec![false; classes.len()];
    for q in cut_faces {
        for k in 0..4 {
            on_cut[class_of[q * 4 + k] as usize] = true;
        }
    }
    let on_cut: Vec<u32> = (0..classes.len() as u32)
        .filter(|&v| on_cut[v as usize])
        .collect();
    place_on_cut(&owners, &mut topology, &on_cut);
    topology.quads = quads;
    topology.resolution = owners.resolution();
    let faces = (topology.quads.iter())
        .map(|q| LatticeFace {
            cell: owners.cell_of(q.cell),
            across: owners.cell_of(q.cell + NEIGHBOUR_OFFSETS[q.direction as usize]),
        })
        .collect();
    finish(lattice, &mut topology);
    (topology, faces)
}

/// Appends the quads of sub-cell `s`, owned by `p`: its faces toward sub-cells it is
/// not joined to.
pub(super) fn push_faces(owners: &CellOwners, s: IVec3, p: u32, quads: &mut Vec<Quad>) {
    for (d, offset) in NEIGHBOUR_OFFSETS.iter().enumerate() {
        if !owners
            .owner(s + *offset)
            .is_some_and(|q| owners.joined(s, p, d, q))
        {
            quads.push(Quad {
                cell: s,
                direction: d as u8,
                owner: p,
            });
        }
    }
}

/// Appends a vertex for each of `classes` in order — each the quad corner slots of one
/// vertex (corner `k` of quad `q` is slot `4q + k`), all at one grid corner — with its
/// bindings; the vertices are worked out in parallel.
pub(super) fn add_vertices(
    owners: &CellOwners,
    quads: &[Quad],
    classes: &[&[u32]],
    topology: &mut SurfaceTopology,
) {
    let scale = owners.lattice().spacing() / owners.resolution() as f32;
    // (each task fills flat lists of its own, appended in order: no vertex's bindings
    // are moved about on their own)
    let made: Vec<MadeVertices> = classes
        .par_chunks(VERTICES_PER_TASK)
        .map(|classes| {
            let mut made = MadeVertices::default();
            for members in classes {
                let (q, k) = (members[0] / 4, members[0] % 4);
                let quad = &quads[q as usize];
                let corner = face_corners(quad.cell, quad.direction)[k as usize];
                let rest = corner.as_vec3() * scale;
                // the sub-cells of the quads, as octants around the corner
                let mut cells = 0u8;
                for s in members.iter() {
                    let o = quads[(s / 4) as usize].cell - (corner - IVec3::ONE);
                    cells |= 1 << (o.x + 2 * o.y + 4 * o.z);
                }
                bind(owners, corner, rest, cells, &mut made.bindings);
                made.corners.push(corner);
                made.rest.push(rest);
                made.ends.push(made.bindings.len() as u32);
            }
            made
        })
        .collect();
    // (room for them all at once: grown a task at a time, the lists are copied over and
    // over)
    let vertices: usize = made.iter().map(|m| m.rest.len()).sum();
    let bindings: usize = made.iter().map(|m| m.bindings.len()).sum();
    make_room(&mut topology.rest, vertices);
    make_room(&mut topology.placed, vertices);
    make_room(&mut topology.corners, vertices);
    make_room(&mut topology.binding_start, vertices);
    make_room(&mut topology.bindings, bindings);
    for made in made {
        let base = topology.bindings.len() as u32;
        topology.rest.extend_from_slice(&made.rest);
        topology.placed.extend_from_slice(&made.rest);
        topology.corners.extend_from_slice(&made.corners);
        topology.bindings.extend_from_slice(&made.bindings);
        (topology.binding_start).extend(made.ends.iter().map(|end| base + end));
    }
}

/// Particles per parallel task of the quads of [`extract_with_faces`].
const PARTICLES_PER_TASK: usize = 4096;

/// Vertices per parallel task of [`add_vertices`].
const VERTICES_PER_TASK: usize = 512;

/// One task's vertices: their grid corners, rest places and bindings (vertex `i`'s end
/// at `ends[i]`).
#[derive(Default)]
struct MadeVertices {
    corners: Vec<IVec3>,
    rest: Vec<Vec3>,
    bindings: Vec<Binding>,
    ends: Vec<u32>,
}

/// Appends the two triangles of a quad with corner vertices `v` (counter-clockwise).
pub(super) fn push_quad(topology: &mut SurfaceTopology, v: [u32; 4]) {
    topology.triangles.extend(quad_triangles(v));
}

/// The two triangles of a quad with corner vertices `v` (counter-clockwise), which
/// meet along the diagonal from its first corner.
fn quad_triangles(v: [u32; 4]) -> [[u32; 3]; 2] {
    [[v[0], v[1], v[2]], [v[0], v[2], v[3]]]
}

/// Numbers the triangles by piece, from their quads' owners, puts back pieces that
/// placing vertices on cuts turned inside out ([`keep_pieces_whole`]), and lists the
/// particles the vertices are bound to.
pub(super) fn finish(lattice: &Lattice, topology: &mut SurfaceTopology) {
    let piece = &lattice.pieces().label;
    topology.triangle_piece = topology
        .quads
        .iter()
        .flat_map(|quad| [piece[quad.owner as usize]; 2])
        .collect();
    keep_pieces_whole(lattice, topology);
    // (marks over the lattice's particles: a pass, not a sort of every binding)
    let mut bound = vec![false; lattice.len()];
    for b in &topology.bindings {
        bound[b.particle as usize] = true;
    }
    topology.particles = (0..lattice.len() as u32)
        .filter(|&p| bound[p as usize])
        .collect();
}

/// Puts back at their grid corners the vertices of every piece that placing vertices on
/// the cut crushed or turned inside out — its volume at rest under half what its cells'
/// faces enclose: a sliver between two cuts through one cell, whose two faces' corners
/// are shared — and every vertex at those corners, so that the faces on both sides of
/// a cut still rest on each other: the cell-face surface there, as before any crossing.
///
/// Only triangles with a placed vertex change a piece's volume; the volume its cells'
/// faces enclose is its particles' cells (a split half, half a cell).
fn keep_pieces_whole(lattice: &Lattice, topology: &mut SurfaceTopology) {
    let scale = lattice.spacing() / topology.resolution.max(1) as f32;
    work_out_volume_changes(topology, scale);
    let pieces = lattice.pieces();
    // what placing took from (or gave to) each piece
    let mut change = vec![0.0f64; pieces.count];
    for (&c, &piece) in topology.volume_change.iter().zip(&topology.triangle_piece) {
        if c != 0.0 {
            change[piece as usize] += c;
        }
    }
    // (no piece can lose half of even one sub-cell: none is crushed)
    let sub_cell = (scale as f64).powi(3);
    if change.iter().all(|c| *c > -0.5 * sub_cell) {
        return;
    }
    let mut cells = vec![0.0f64; pieces.count];
    let cell = (lattice.spacing() as f64).powi(3);
    for p in lattice.live_particles() {
        let share = if lattice.is_split_half(p) { 0.5 } else { 1.0 };
        cells[pieces.label[p as usize] as usize] += share * cell;
    }
    let crushed: Vec<bool> = (change.iter().zip(&cells))
        .map(|(change, cells)| cells + change < 0.5 * cells)
        .collect();
    if !crushed.contains(&true) {
        return;
    }
    let mut corners: rustc_hash::FxHashSet<IVec3> = Default::default();
    for (tri, &piece) in topology.triangles.iter().zip(&topology.triangle_piece) {
        if crushed[piece as usize] {
            corners.extend(tri.iter().map(|&v| topology.corners[v as usize]));
        }
    }
    let grid = |t: &SurfaceTopology, v: usize| t.corners[v].as_vec3() * scale;
    for v in 0..topology.vertex_count() {
        let x = grid(topology, v);
        if topology.rest[v] != x && corners.contains(&topology.corners[v]) {
            rest_vertex_at(lattice, topology, v, x);
        }
    }
}

/// Where placement put each vertex: `placed`, or `rest` for a topology that kept no
/// placements (a save from before they were kept, or a smoothed surface).
pub(super) fn placements<'a>(placed: &'a [Vec3], rest: &'a [Vec3]) -> &'a [Vec3] {
    if placed.len() == rest.len() {
        placed
    } else {
        rest
    }
}

/// Works out [`SurfaceTopology::volume_change`] for the triangles past those it holds,
/// the grid's corners `scale` apart.
pub(super) fn work_out_volume_changes(topology: &mut SurfaceTopology, scale: f32) {
    let SurfaceTopology {
        rest,
        placed,
        corners,
        triangles,
        volume_change,
        ..
    } = topology;
    let at = placements(placed, rest);
    let known = volume_change.len().min(triangles.len());
    volume_change.truncate(known);
    make_room(volume_change, triangles.len() - known);
    let grid = |v: u32| corners[v as usize].as_vec3() * scale;
    let volume = |x: [Vec3; 3]| x[0].as_dvec3().dot(x[1].as_dvec3().cross(x[2].as_dvec3())) / 6.0;
    volume_change.par_extend(triangles[known..].par_iter().with_min_len(4096).map(|tri| {
        if tri.iter().any(|&v| at[v as usize] != grid(v)) {
            volume(tri.map(|v| at[v as usize])) - volume(tri.map(grid))
        } else {
            0.0
        }
    }));
}

/// Appends to `out` the bindings of the vertex at grid corner `w` (resting at `rest`)
/// whose quads belong to the solid sub-cells `cells` (a bit per octant around `w`,
/// numbered like [`octant`]): the owners of those sub-cells and of every solid sub-cell
/// around `w` joined to them through faces at `w`, one share per sub-cell.
fn bind(owners: &CellOwners, w: IVec3, rest: Vec3, cells: u8, out: &mut Vec<Binding>) {
    // the eight sub-cells around `w`, numbered like `octant`
    let mut around = [w; 8];
    let mut own = [None; 8];
    for k in 0..8 {
        around[k] += octant(k as u32) - IVec3::ONE;
        own[k] = owners.owner(around[k]);
    }
    // the twelve faces at `w`, as the pairs of octants they join (when they do)
    let mut faces = [(0u8, 0u8); 12];
    let mut n = 0;
    for k in 0..8u32 {
        for axis in 0..3 {
            let j = k | 1 << axis;
            if j == k {
                continue;
            }
            if let (Some(p), Some(q)) = (own[k as usize], own[j as usize])
                && owners.joined(around[k as usize], p, 2 * axis + 1, q)
            {
                faces[n] = (1 << k, 1 << j);
                n += 1;
            }
        }
    }
    // spread across them until nothing changes
    let mut reached = cells;
    loop {
        let before = reached;
        for &(a, b) in &faces[..n] {
            if reached & (a | b) != 0 {
                reached |= a | b;
            }
        }
        if reached == before {
            break;
        }
    }
    let count = (0..8)
        .filter(|&k| reached >> k & 1 != 0 && own[k].is_some())
        .count();
    let weight = 1.0 / count as f32;
    let first = out.len();
    for p in (0..8)
        .filter(|&k| reached >> k & 1 != 0)
        .filter_map(|k| own[k])
    {
        match out[first..].iter_mut().find(|b| b.particle == p) {
            Some(b) => b.weight += weight,
            None => out.push(Binding {
                particle: p,
                weight,
                offset: rest - owners.lattice().rest_position(p),
            }),
        }
    }
}

/// Places the vertices `vertices` (ascending) of `topology` on the cut
/// ([`cut_vertex_position`]) where their boxes hold a crossing, their bindings' offsets
/// following: each corner solved once (the vertices of a cut's two sides share it), the
/// corners in parallel.
pub(super) fn place_on_cut(owners: &CellOwners, topology: &mut SurfaceTopology, vertices: &[u32]) {
    if vertices.is_empty() {
        return;
    }
    let corner = |v: u32| topology.corners[v as usize];
    let (lo, hi) = (vertices.iter()).fold((IVec3::MAX, IVec3::MIN), |(lo, hi), &v| {
        (lo.min(corner(v)), hi.max(corner(v)))
    });
    // the vertices by corner (a corner's place in the box of them, which fits a word)
    let dims = (hi - lo + IVec3::ONE).as_u64vec3();
    let mut by_corner: Vec<(u64, u32)> = (vertices.iter())
        .map(|&v| {
            let d = (corner(v) - lo).as_u64vec3();
            ((d.z * dims.y + d.y) * dims.x + d.x, v)
        })
        .collect();
    crate::util::radix::sort_by_key_radix(&mut by_corner);
    let firsts: Vec<usize> = (0..by_corner.len())
        .filter(|&i| i == 0 || by_corner[i - 1].0 != by_corner[i].0)
        .collect();
    let placed: Vec<Option<Vec3>> = firsts
        .par_iter()
        .with_min_len(256)
        .map(|&i| cut_vertex_position(owners, corner(by_corner[i].1)))
        .collect();
    for (k, &first) in firsts.iter().enumerate() {
        let Some(x) = placed[k] else { continue };
        let end = firsts.get(k + 1).copied().unwrap_or(by_corner.len());
        for &(_, v) in &by_corner[first..end] {
            rest_vertex_at(owners.lattice(), topology, v as usize, x);
            topology.placed[v as usize] = x;
        }
    }
}

/// Rests vertex `v` at `x`, its bindings' offsets following.
fn rest_vertex_at(lattice: &Lattice, topology: &mut SurfaceTopology, v: usize, x: Vec3) {
    topology.rest[v] = x;
    let range = topology.binding_start[v] as usize..topology.binding_start[v + 1] as usize;
    for b in &mut topology.bindings[range] {
        b.offset = x - lattice.rest_position(b.particle);
    }
}
