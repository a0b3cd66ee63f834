//! Binding a point at rest inside a body to the particles around it: the corners of the
//! cell of particle centres it lies in, with trilinear weights, those linked to the
//! heaviest (see [`super::embed`]).

use super::cells::octant;
use super::extract::Binding;
use crate::body::lattice::Lattice;
use glam::{IVec3, Vec3};

/// Appends the bindings of a vertex resting at `at` (see the module docs of [`super::embed`]), among the
/// particles of piece `piece` alone when it is given; `None` when no live particle (of
/// the piece) is near enough.
pub(super) fn bind_vertex(
    lattice: &Lattice,
    at: Vec3,
    piece: Option<u32>,
    bindings: &mut Vec<Binding>,
) -> Option<()> {
    let label = piece.map(|_| &lattice.pieces().label);
    let of_piece = |p: u32| label.is_none_or(|l| Some(l[p as usize]) == piece);
    let h = lattice.spacing();
    // particle k rests at (k + ½)·h: the cell of centres around `at` starts at `base`
    let g = at / h - Vec3::splat(0.5);
    let base = g.floor();
    let f = g - base;
    let base = base.as_ivec3();
    let mut corners: Vec<(u32, f32)> = (0..8)
        .filter_map(|k| {
            let o = octant(k);
            let w = Vec3::select(o.cmpeq(IVec3::ONE), f, Vec3::ONE - f);
            let p = lattice.at(base + o).filter(|&p| of_piece(p))?;
            Some((p, w.x * w.y * w.z))
        })
        .collect();
    if corners.is_empty() {
        // a vertex of a feature thinner than a cell: the nearest particle around
        let nearest = (0..27)
            .filter_map(|k| {
                let c = IVec3::new(k % 3, k / 3 % 3, k / 9) - IVec3::ONE + g.round().as_ivec3();
                lattice.at(c).filter(|&p| of_piece(p))
            })
            .map(|p| (p, lattice.rest_position(p).distance(at)))
            .filter(|&(_, d)| d <= 1.5 * h)
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        corners.push((nearest.0, 1.0));
    }
    // keep the corners linked (within the eight) to the heaviest
    corners.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut kept = vec![corners[0]];
    let mut grew = true;
    while grew {
        grew = false;
        for &(p, w) in &corners {
            if !kept.iter().any(|k| k.0 == p)
                && lattice.neighbours(p).any(|q| kept.iter().any(|k| k.0 == q))
            {
                kept.push((p, w));
                grew = true;
            }
        }
    }
    // a vertex exactly on a face of the cell gives its far corners no weight
    let total: f32 = kept.iter().map(|k| k.1).sum();
    let weight = |w: f32| {
        if total > 0.0 {
            w / total
        } else {
            1.0 / kept.len() as f32
        }
    };
    bindings.extend(kept.iter().map(|&(p, w)| Binding {
        particle: p,
        weight: weight(w),
        offset: at - lattice.rest_position(p),
    }));
    Some(())
}
