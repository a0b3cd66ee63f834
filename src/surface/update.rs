//! Bringing a lattice surface up to date after a cut without extracting it again: only
//! the quads and vertices near the particles the cut touched are rebuilt, and spliced
//! into the rest, which keeps its vertices and triangles (renumbered).
//!
//! What a cut can change is local, and local in sub-cells. The owners of a cell's
//! sub-cells are dealt among its own particles, and a face is joined by its two owners'
//! link, so with `C` the sub-cells of the touched particles' cells:
//! - quads change only on faces of `C`'s sub-cells;
//! - a vertex's class and bindings depend on the sub-cells around its corner and,
//!   through the pinch rule of [`super::fans`], around the six corners next to it; its
//!   place on a cut on the cells within half a cell of it. So vertices change only at
//!   corners of the sub-cells of `C ⊕ 1` (the sub-cells within one of `C`, counting
//!   diagonals): those corners are rebuilt;
//! - the quads of `C ⊕ 3` are extracted afresh: every quad around a rebuilt corner and
//!   around its neighbours lies in it, so its classes there are exactly those a full
//!   extraction finds; a fresh quad's corners that are not rebuilt keep the vertex the
//!   same quad had before (such a quad is unchanged).
//!
//! Counted in sub-cells, not cells, the region of a body drawn in octants is half as
//! wide around the cut: about a third of the sub-cells along a cut's line (8² of them
//! across it per sub-cell along it, against 7² cells of 8), a fifth around one touched
//! cell (8³ against 7³ cells of 8).
//!
//! The pieces are numbered again over the whole body, as a full extraction numbers
//! them. A change of resolution (a body's first split particle) needs a full
//! extraction; so does a surface that is not a lattice's.

use super::cells::{CellOwners, face_corners, octant};
use super::extract::{SurfaceTopology, add_vertices, finish, place_on_cut, push_faces, push_quad};
use super::fans::{Quad, vertex_classes};
use super::placement::is_cut_face;
use crate::body::lattice::Lattice;
use crate::util::bits::set_bits;
use crate::util::room::make_room;
use glam::IVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use std::ops::Range;

/// The margin of the region extracted afresh around the touched sub-cells (`C ⊕ 3`).
const REGION_MARGIN: i32 = 3;

/// The surface of `lattice` after a change that touched only the particles `touched`
/// (removed, split — both halves —, or with links severed or made), from `old`, its
/// surface before, which it edits where it lies; `None` when only a full extraction
/// will do (see the module docs).
pub fn update(lattice: &Lattice, old: SurfaceTopology, touched: &[u32]) -> Option<SurfaceTopology> {
    let cells = touched.iter().map(|&p| lattice.coord(p));
    let (lo, hi) = cells.clone().fold((IVec3::MAX, IVec3::MIN), |(lo, hi), c| {
        (lo.min(c), hi.max(c))
    });
    // (the owners looked up around the region, fast; a cell beyond it and one more is
    // never asked for, but would be answered right)
    let margin = IVec3::splat(REGION_MARGIN + 1);
    let owners = CellOwners::looked_up_in(lattice, lo - margin, hi + margin);
    let res = owners.resolution();
    if old.quads.is_empty() || res != old.resolution {
        return None;
    }
    if lo.cmpgt(hi).any() {
        return Some(old);
    }
    // the touched cells' sub-cells: every one of a cell whose particles were touched
    let sub_cells = cells
        .flat_map(|c| (0..(res * res * res) as u32).map(move |k| c * res + octant(k) * (res - 1)));
    let (sub_lo, sub_hi) = (lo * res, hi * res + IVec3::splat(res - 1));
    let changed = CellSet::around(sub_cells, sub_lo, sub_hi, REGION_MARGIN);
    let near = changed.dilated(1);
    // C ⊕ 3
    let region = near.dilated(REGION_MARGIN - 1);
    let in_region = |s: IVec3| region.contains(s);
    // (the corners of the sub-cells of `near` are the sub-cells of a set grown by one
    // forward)
    let corners_near = near.forward();
    let rebuilt = |w: IVec3| corners_near.contains(w);
    // the fresh quads and their classes; beside them, what stays of the old surface:
    // the old quads inside the region are replaced, the old vertices at rebuilt corners
    // go, the others are renumbered in order
    let ((quads, classes), (old_quad, (mut topology, renumbered))) = rayon::join(
        || {
            let quads = region_quads(&owners, &region);
            let classes = vertex_classes(&owners, &quads);
            (quads, classes)
        },
        || {
            // (the replaced quads' corners, read before the kept part moves over them)
            let old_quad: FxHashMap<(IVec3, u8), [u32; 4]> = (old.quads.iter().enumerate())
                .filter(|(_, q)| in_region(q.cell))
                .map(|(i, q)| ((q.cell, q.direction), quad_corners(&old, i)))
                .collect();
            (old_quad, kept_outside(old, &rebuilt, &in_region))
        },
    );
    let class_of = &classes.class_of;
    // the fresh quads' corners: a new vertex for each class at a rebuilt corner (made
    // in parallel, numbered in order of first use), the kept one elsewhere
    let mut vertex_of_class = vec![u32::MAX; classes.len()];
    let mut made: Vec<&[u32]> = Vec::new();
    let first_new = topology.rest.len() as u32;
    // (a mark per new vertex, numbered from `first_new`: at most one per class)
    let mut on_cut = vec![false; classes.len()];
    let mut fresh = Vec::with_capacity(quads.len());
    for (q, quad) in quads.iter().enumerate() {
        let corners = face_corners(quad.cell, quad.direction);
        let cut_face = is_cut_face(&owners, quad);
        let mut was = None;
        let mut v = [0u32; 4];
        for k in 0..4 {
            let class = class_of[4 * q + k] as usize;
            v[k] = if rebuilt(corners[k]) {
                if vertex_of_class[class] == u32::MAX {
                    vertex_of_class[class] = first_new + made.len() as u32;
                    made.push(classes.slots(class));
                }
                if cut_face {
                    on_cut[(vertex_of_class[class] - first_new) as usize] = true;
                }
                vertex_of_class[class]
            } else {
                // an unchanged quad at a corner nothing changed around
                let was = match was {
                    Some(was) => was,
                    None => *was.insert(*old_quad.get(&(quad.cell, quad.direction))?),
                };
                let kept = renumbered[was[k] as usize];
                if kept == u32::MAX {
                    return None;
                }
                kept
            };
        }
        fresh.push(v);
    }
    add_vertices(&owners, &quads, &made, &mut topology);
    make_room(&mut topology.quads, quads.len());
    make_room(&mut topology.triangles, 2 * quads.len());
    for (quad, v) in quads.iter().zip(fresh) {
        topology.quads.push(*quad);
        push_quad(&mut topology, v);
    }
    // the rebuilt vertices of cut faces rest on the cut
    let on_cut: Vec<u32> = (on_cut.iter().enumerate())
        .filter(|(_, on)| **on)
        .map(|(v, _)| first_new + v as u32)
        .collect();
    place_on_cut(&owners, &mut topology, &on_cut);
    finish(lattice, &mut topology);
    Some(topology)
}

/// The fresh quads of the sub-cells of `region`, layer by layer along z, each in order
/// of y, then x: the layers found in parallel.
fn region_quads(owners: &CellOwners, region: &CellSet) -> Vec<Quad> {
    let layers: Vec<Vec<Quad>> = (0..region.dims.z)
        .into_par_iter()
        .map(|z| {
            let mut quads = Vec::new();
            for s in region.cells_in_layer(z) {
                // (an enclosed particle's sub-cells have no face)
                if let Some(p) = owners.owner(s).filter(|&p| !owners.is_enclosed(p)) {
                    push_faces(owners, s, p, &mut quads);
                }
            }
            quads
        })
        .collect();
    layers.concat()
}

/// The four corner vertices of quad `q` of `topology` (its two triangles share the
/// first and third).
fn quad_corners(topology: &SurfaceTopology, q: usize) -> [u32; 4] {
    let [a, b, c] = topology.triangles[2 * q];
    [a, b, c, topology.triangles[2 * q + 1][2]]
}

/// What stays of the `old` surface: its quads outside the region (`in_region` of a
/// cell says), and its vertices except those at `rebuilt` corners, renumbered in order;
/// with each old vertex's new number (`u32::MAX` for one that goes).
///
/// Most of the surface stays, in runs between the few vertices and quads that go: each
/// run is moved back whole within its list, which is edited where it lies (a surface's
/// lists have room for the faces a cut adds, see [`make_room`]).
fn kept_outside(
    mut topology: SurfaceTopology,
    rebuilt: &impl Fn(IVec3) -> bool,
    in_region: &impl Fn(IVec3) -> bool,
) -> (SurfaceTopology, Vec<u32>) {
    let mut renumbered = vec![u32::MAX; topology.vertex_count()];
    let mut kept = 0u32;
    for (v, &corner) in topology.corners.iter().enumerate() {
        if !rebuilt(corner) {
            renumbered[v] = kept;
            kept += 1;
        }
    }
    // (a surface without placements sits at rest, as `placements` reads it: made a list
    // whose kept runs can move)
    if topology.placed.len() != topology.rest.len() {
        topology.placed = topology.rest.clone();
    }
    let t = &mut topology;
    let vertices: Vec<Range<usize>> = runs(&renumbered, |n| n != u32::MAX).collect();
    let binding_runs: Vec<Range<usize>> = (vertices.iter())
        .map(|run| t.binding_start[run.start] as usize..t.binding_start[run.end] as usize)
        .collect();
    // each kept vertex's bindings start where they did, less what went before them
    // (written over the list as it is read: a kept vertex's new place is at or before
    // its old one)
    let mut at = 1;
    let mut bindings_at = 0;
    for (run, bindings) in vertices.iter().zip(&binding_runs) {
        let back = bindings.start as u32 - bindings_at;
        for v in run.start + 1..=run.end {
            t.binding_start[at] = t.binding_start[v] - back;
            at += 1;
        }
        bindings_at += bindings.len() as u32;
    }
    t.binding_start.truncate(at);
    keep_runs(&mut t.rest, &vertices);
    keep_runs(&mut t.placed, &vertices);
    keep_runs(&mut t.corners, &vertices);
    keep_runs(&mut t.bindings, &binding_runs);
    let outside: Vec<bool> = t.quads.iter().map(|q| !in_region(q.cell)).collect();
    let quads: Vec<Range<usize>> = runs(&outside, |o| o).collect();
    let triangles: Vec<Range<usize>> = quads.iter().map(|q| 2 * q.start..2 * q.end).collect();
    // (a kept triangle's vertices keep their places, and so its volume term)
    if t.volume_change.len() == t.triangles.len() {
        keep_runs(&mut t.volume_change, &triangles);
    } else {
        t.volume_change.clear();
    }
    keep_runs(&mut t.quads, &quads);
    keep_runs(&mut t.triangles, &triangles);
    for triangle in &mut t.triangles {
        *triangle = triangle.map(|v| renumbered[v as usize]);
    }
    (topology, renumbered)
}

/// Keeps the `runs` of `list` (ascending and apart), in order, each moved back over
/// what went before it: the list is edited where it lies, and what is added to it later
/// takes the room it has ([`make_room`]).
fn keep_runs<T: Copy>(list: &mut Vec<T>, runs: &[Range<usize>]) {
    let mut at = 0;
    for run in runs {
        list.copy_within(run.clone(), at);
        at += run.len();
    }
    list.truncate(at);
}

/// The maximal runs of consecutive indices of `items` that `keep` holds for.
fn runs<'a, T: Copy>(
    items: &'a [T],
    keep: impl Fn(T) -> bool + 'a,
) -> impl Iterator<Item = Range<usize>> + 'a {
    let mut at = 0;
    std::iter::from_fn(move || {
        let start = at + items[at..].iter().position(|&x| keep(x))?;
        let len = items[start..].iter().position(|&x| !keep(x));
        at = len.map_or(items.len(), |l| start + l);
        Some(start..at)
    })
}

/// A set of sub-cells: a bit per sub-cell of a box, rows along x packed in words (so that
/// dilating the set is a few word operations per row).
struct CellSet {
    min: IVec3,
    dims: IVec3,
    /// Words per row along x.
    row: usize,
    bits: Vec<u64>,
}

impl CellSet {
    /// `cells`, which lie from `lo` to `hi` (inclusive), in a box with room for
    /// `margin` cells around them.
    fn around(cells: impl Iterator<Item = IVec3>, lo: IVec3, hi: IVec3, margin: i32) -> Self {
        let min = lo - IVec3::splat(margin);
        let dims = hi - lo + IVec3::splat(2 * margin + 1);
        let row = (dims.x as usize).div_ceil(64);
        let mut set = Self {
            min,
            dims,
            row,
            bits: vec![0; row * (dims.y * dims.z) as usize],
        };
        for c in cells {
            let (w, bit) = set.index(c).expect("inside its own box");
            set.bits[w] |= bit;
        }
        set
    }

    /// The word and bit of cell `c`.
    fn index(&self, c: IVec3) -> Option<(usize, u64)> {
        let d = c - self.min;
        if d.cmplt(IVec3::ZERO).any() || d.cmpge(self.dims).any() {
            return None;
        }
        let row = (d.z * self.dims.y + d.y) as usize;
        Some((row * self.row + d.x as usize / 64, 1 << (d.x % 64)))
    }

    fn contains(&self, c: IVec3) -> bool {
        self.index(c)
            .is_some_and(|(w, bit)| self.bits[w] & bit != 0)
    }

    /// The cells within `r` of these (counting diagonals; the box must have room): a
    /// sweep along each axis in turn.
    fn dilated(&self, r: i32) -> Self {
        let r = r as usize;
        let rows = (self.dims.y * self.dims.z) as usize;
        let n = self.row;
        // along x: each row ORed with itself shifted up to r bits either way
        let mut bits = self.bits.clone();
        for y in 0..rows {
            let from = &self.bits[y * n..(y + 1) * n];
            for s in 1..=r {
                for w in 0..n {
                    let up = from[w] << s | if w > 0 { from[w - 1] >> (64 - s) } else { 0 };
                    let down = from[w] >> s
                        | if w + 1 < n {
                            from[w + 1] << (64 - s)
                        } else {
                            0
                        };
                    bits[y * n + w] |= up | down;
                }
            }
        }
        // along y, then z: each row ORed with the rows within r of it
        let (ny, nz) = (self.dims.y as usize, self.dims.z as usize);
        for (stride, count) in [(1, ny), (ny, nz)] {
            let from = bits.clone();
            for y in 0..rows {
                let at = y / stride % count;
                let lo = at.saturating_sub(r);
                let hi = (at + r).min(count - 1);
                for k in lo..=hi {
                    let other = y - at * stride + k * stride;
                    for w in 0..n {
                        bits[y * n + w] |= from[other * n + w];
                    }
                }
            }
        }
        // (bits past the box's end of each row stay clear: the last word is masked)
        let tail = self.dims.x as usize % 64;
        if tail != 0 {
            for y in 0..rows {
                bits[y * n + n - 1] &= (1u64 << tail) - 1;
            }
        }
        Self {
            min: self.min,
            dims: self.dims,
            row: n,
            bits,
        }
    }

    /// The cells `c + o` of every cell `c` of these and `o` in `{0, 1}³` (the box must
    /// have room): the corners of these cells, as the cells they start.
    fn forward(&self) -> Self {
        let n = self.row;
        let rows = (self.dims.y * self.dims.z) as usize;
        let mut bits = self.bits.clone();
        for y in 0..rows {
            for w in (0..n).rev() {
                let carry = if w > 0 {
                    self.bits[y * n + w - 1] >> 63
                } else {
                    0
                };
                bits[y * n + w] |= self.bits[y * n + w] << 1 | carry;
            }
        }
        let ny = self.dims.y as usize;
        for stride in [1, ny] {
            let from = bits.clone();
            for y in 0..rows {
                let at = y / stride
                    % if stride == 1 {
                        ny
                    } else {
                        self.dims.z as usize
                    };
                if at > 0 {
                    for w in 0..n {
                        bits[y * n + w] |= from[(y - stride) * n + w];
                    }
                }
            }
        }
        Self {
            min: self.min,
            dims: self.dims,
            row: n,
            bits,
        }
    }

    /// The cells of the `z`-th layer of the box along z, in order of y, then x.
    fn cells_in_layer(&self, z: i32) -> impl Iterator<Item = IVec3> + '_ {
        // (a row is `row` words: bit `b` is x = b mod 64·row of row b / 64·row)
        let (bits_per_row, ny) = (64 * self.row, self.dims.y as usize);
        let layer = bits_per_row * ny;
        let words = &self.bits[z as usize * layer / 64..(z as usize + 1) * layer / 64];
        set_bits(words).map(move |b| {
            let (y, x) = (b / bits_per_row, b % bits_per_row);
            self.min + IVec3::new(x as i32, y as i32, z)
        })
    }
}

#[cfg(test)]
mod tests;
