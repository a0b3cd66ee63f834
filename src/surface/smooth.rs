//! Rounding a lattice surface's voxel staircase, in rest space, once per topology
//! change: Taubin's λ|μ smoothing (Taubin 1995, "A signal processing approach to fair
//! surface design") of the vertices' rest positions over the mesh's edges. Each pass
//! pulls every vertex toward the mean of its neighbours by λ, then pushes it away by
//! |μ| > λ: the staircase's steps (short wavelengths) die out while the shape's own
//! curvature (long ones) passes, so a voxelised sphere comes out round without
//! shrinking the way repeated averaging would. A vertex moves at most half a cell from
//! its corner, so it stays among the particles it is bound to; the bindings' offsets
//! are taken again from the new rest positions, so the particles carry the rounded
//! surface exactly as they carried the staircase.

use super::extract::SurfaceTopology;
use crate::body::lattice::Lattice;
use glam::Vec3;

/// λ|μ passes.
const PASSES: u32 = 20;
/// The pull toward the neighbours' mean.
const LAMBDA: f32 = 0.5;
/// The push back (Taubin's pass-band frequency 0.1: 1/λ + 1/μ = 0.1).
const MU: f32 = -0.53;

/// Smooths `topology`'s rest positions (see the module docs) and rebinds its vertices;
/// triangles, pieces and binding weights are unchanged.
pub fn smooth(lattice: &Lattice, topology: &mut SurfaceTopology) {
    let n = topology.vertex_count();
    // each vertex's neighbours over the triangles' edges (every edge of a closed mesh
    // lies in two triangles: count it once per direction)
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for t in &topology.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    let corners = topology.rest.clone();
    let reach = 0.5 * lattice.spacing();
    let mut at = corners.clone();
    let mut next = at.clone();
    for _ in 0..PASSES {
        for factor in [LAMBDA, MU] {
            for (v, list) in neighbours.iter().enumerate() {
                next[v] = if list.is_empty() {
                    at[v]
                } else {
                    let mean =
                        list.iter().map(|&u| at[u as usize]).sum::<Vec3>() / list.len() as f32;
                    at[v] + factor * (mean - at[v])
                };
            }
            std::mem::swap(&mut at, &mut next);
        }
    }
    // (the places move: the placements and volume terms worked out for them go)
    topology.placed.clear();
    topology.volume_change.clear();
    for (v, (x, corner)) in at.iter().zip(&corners).enumerate() {
        let rest = *corner + (*x - *corner).clamp_length_max(reach);
        topology.rest[v] = rest;
        let range = topology.binding_start[v] as usize..topology.binding_start[v + 1] as usize;
        for b in &mut topology.bindings[range] {
            b.offset = rest - lattice.rest_position(b.particle);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use crate::surface::extract::extract;

    #[test]
    fn vertices_move_at_most_half_a_cell_and_stay_bound_where_they_now_rest() {
        let l = Shape::Sphere { radius: 0.45 }.voxelise(0.1).unwrap();
        let staircase = extract(&l);
        let mut rounded = staircase.clone();
        smooth(&l, &mut rounded);
        let moved: Vec<f32> = staircase
            .rest
            .iter()
            .zip(&rounded.rest)
            .map(|(a, b)| a.distance(*b))
            .collect();
        assert!(moved.iter().all(|d| *d <= 0.05 + 1e-6));
        assert!(moved.iter().any(|d| *d > 0.02), "the steps are rounded off");
        for v in 0..rounded.vertex_count() {
            for b in rounded.bindings_of(v) {
                let at = l.rest_position(b.particle) + b.offset;
                assert!(at.distance(rounded.rest[v]) < 1e-5);
            }
        }
        assert_eq!(staircase.triangles, rounded.triangles);
    }
}
