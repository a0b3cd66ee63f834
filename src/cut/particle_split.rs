//! Splitting particles in two along a blade (the notes' better option to deleting the
//! particles a blade passes through): the old particle keeps the edges on its own side
//! of the blade's plane, a new particle at the same lattice coordinate takes the edges
//! on the far side, and each gets half the mass (the caller's part). The cut face is
//! clean and no mass is lost.

use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::cut::tool::BladePlane;
use glam::Vec3;

/// What a split blade does to one body: particles to split, each with the directions
/// of the edges its new half takes, and edges to sever.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitPlan {
    /// `(particle, the lattice directions its new half takes, the blade's plane)`,
    /// ascending by particle.
    pub splits: Vec<(u32, [bool; 6], BladePlane)>,
    /// Edges between two split particles on different sides, `(a, b)` with `a < b`.
    pub sever: Vec<(u32, u32)>,
}

/// Plans the splits of the `candidates` (live particles a split blade passes through,
/// ascending, each with the blade's plane), reading only.
///
/// A particle belongs to the side of the plane where its lattice stencil lies on
/// balance: the sign of the sum of its six neighbours' signed distances, a missing
/// neighbour counted at the particle's own place (and its own place decides when they
/// balance). With all six neighbours at rest, that is the side of its own position; a
/// half whose neighbours all lie on one side belongs there wherever it drifts. The
/// plan's plane for a candidate is oriented so that its side is the positive one.
///
/// An edge from a candidate goes to its new half when the neighbour belongs to the
/// other side (one on the plane, within rounding, as in the candidate's own layer,
/// stays) and the blade's sweep `crosses` the edge; an edge between two candidates on
/// different sides is severed instead (the blade passes between them), and so is every
/// such edge of a candidate the plane passes more than a quarter cell from (near its
/// cell's face, the halves' rest places, a quarter cell either side of the centre, would
/// lie on one side). A candidate without such an edge stays whole.
///
/// Sides by the neighbours make a split final: a half of a particle the blade split,
/// and each of its neighbours, keeps belonging to its side however close to the plane
/// it drifts while the blade still passes (by its own position alone, a particle on the
/// plane would flip sides as the body moves, and each flip would strip its edges to a
/// new half, leaving single particles behind).
pub fn plan_splits(
    lattice: &Lattice,
    candidates: &[(u32, BladePlane)],
    position: impl Fn(u32) -> Vec3,
    crosses: impl Fn(u32, u32) -> bool,
) -> SplitPlan {
    let tolerance = 1e-3 * lattice.spacing();
    // the side of the plane a particle belongs to (see the docs); `None` on the plane,
    // within rounding
    let side = |p: u32, plane: &BladePlane| {
        let own = plane.distance(position(p));
        let balance: f32 = lattice
            .links(p)
            .iter()
            .map(|&q| match q {
                NO_PARTICLE => own,
                q => plane.distance(position(q)),
            })
            .sum();
        [balance, own]
            .into_iter()
            .find(|d| d.abs() > tolerance)
            .map(|d| d > 0.0)
    };
    let is_candidate = |q: u32| candidates.binary_search_by_key(&q, |(c, _)| *c).is_ok();
    let mut plan = SplitPlan::default();
    for &(p, plane) in candidates {
        let dp = plane.distance(position(p));
        let p_side = side(p, &plane).unwrap_or(dp >= 0.0);
        let near_face = dp.abs() >= 0.25 * lattice.spacing();
        let mut moves = [false; 6];
        for (d, q) in lattice.links(p).into_iter().enumerate() {
            if q == NO_PARTICLE
                || side(q, &plane).is_none_or(|q_side| q_side == p_side)
                || !crosses(p, q)
            {
                continue;
            }
            if is_candidate(q) || near_face {
                if p < q || !is_candidate(q) {
                    plan.sever.push((p.min(q), p.max(q)));
                }
            } else {
                moves[d] = true;
            }
        }
        let plane = if p_side { plane } else { plane.flipped() };
        if moves.iter().any(|m| *m) {
            plan.splits.push((p, moves, plane));
        }
    }
    plan.sever.sort_unstable();
    plan.sever.dedup();
    plan
}

/// Pairs of body-local particle indices: edges, or (particle, its new half).
pub type Pairs = Vec<(u32, u32)>;

/// Carries out a [`SplitPlan`]: severs its edges, then splits its particles. Returns the
/// `(particle, new particle)` pairs and the severed edges.
pub fn apply_splits(lattice: &mut Lattice, plan: &SplitPlan) -> (Pairs, Pairs) {
    let severed: Vec<(u32, u32)> = plan
        .sever
        .iter()
        .copied()
        .filter(|&(a, b)| lattice.sever(a, b))
        .collect();
    let pairs = plan
        .splits
        .iter()
        .filter_map(|&(p, moves, _)| lattice.split(p, moves).map(|new| (p, new)))
        .collect();
    (pairs, severed)
}

/// Where the halves of a particle at `x` go, `(kept, new)`, for a plan's plane (whose
/// positive side the particle keeps): the kept half on the positive side (mirrored
/// across the plane when the particle lies on the other), the new half at its mirror
/// image, at least `gap` beyond the plane, so that the halves never coincide.
pub fn split_positions(x: Vec3, plane: &BladePlane, gap: f32) -> (Vec3, Vec3) {
    let d = plane.distance(x);
    let kept = x - (d - d.abs()) * plane.normal;
    let new = kept - (d.abs() + d.abs().max(gap)) * plane.normal;
    (kept, new)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    /// A 6×2×2 bar, a blade across x = 0.4 (through the layer of cells whose centres lie
    /// at 0.5), that layer as candidates, and the rest positions.
    fn bar_and_layer() -> (Lattice, BladePlane, Vec<(u32, BladePlane)>, Vec<Vec3>) {
        let lattice = Shape::cuboid(UVec3::new(6, 2, 2)).voxelise(1.0).unwrap();
        let plane = BladePlane {
            normal: Vec3::X,
            offset: 0.4,
        };
        let layer = lattice
            .live_particles()
            .filter(|&p| lattice.coord(p).x == 0)
            .map(|p| (p, plane))
            .collect();
        let rest = (0..lattice.len() as u32)
            .map(|p| lattice.rest_position(p))
            .collect();
        (lattice, plane, layer, rest)
    }

    #[test]
    fn a_split_layer_parts_a_bar_into_two_pieces_without_losing_particles() {
        let (mut lattice, plane, layer, rest) = bar_and_layer();
        let before = lattice.live_count();
        let plan = plan_splits(&lattice, &layer, |p| rest[p as usize], |_, _| true);
        // an edge the blade does not cross stays
        assert!(
            plan_splits(&lattice, &layer, |p| rest[p as usize], |_, _| false)
                .splits
                .is_empty()
        );
        let (pairs, severed) = apply_splits(&mut lattice, &plan);
        assert_eq!(pairs.len(), 4, "each particle of the layer splits");
        assert!(
            severed.is_empty(),
            "the layer lies on one side: nothing between"
        );
        assert_eq!(lattice.live_count(), before + 4);
        assert_eq!(lattice.piece_count(), 2);
        // the old halves keep the edges on their own (positive) side
        for (old, new) in pairs {
            assert_eq!(lattice.coord(new), lattice.coord(old));
            assert!(lattice.neighbours(old).all(|q| lattice.coord(q).x >= 0));
            assert!(lattice.neighbours(new).all(|q| lattice.coord(q).x <= 0));
            let x = rest[old as usize];
            let (kept, y) = split_positions(x, &plane, 0.05);
            assert_eq!(kept, x, "on its own side already");
            assert!(
                (plane.distance(y) + plane.distance(x)).abs() < 1e-6 && plane.distance(y) < 0.0
            );
        }
    }

    #[test]
    fn the_halves_go_to_their_sides_of_the_plane() {
        let plane = BladePlane {
            normal: Vec3::new(0.6, 0.8, 0.0),
            offset: 1.0,
        };
        for d in [-0.3f32, -0.02, 0.0, 0.02, 0.3] {
            let x = Vec3::new(1.0, 0.5, -2.0) + d * plane.normal;
            let (kept, new) = split_positions(x, &plane, 0.05);
            // the kept half on the positive side, mirrored there when it was not
            assert!((plane.distance(kept) - d.abs()).abs() < 1e-5, "{d}: {kept}");
            assert!(
                (plane.distance(new) + d.abs().max(0.05)).abs() < 1e-5,
                "{d}: {new}"
            );
            // both along the normal through x
            assert!((kept - x).cross(plane.normal).length() < 1e-5);
            assert!((new - x).cross(plane.normal).length() < 1e-5);
        }
    }

    #[test]
    fn a_half_that_drifts_across_the_plane_is_not_split_again() {
        let (mut lattice, plane, layer, rest) = bar_and_layer();
        let plan = plan_splits(&lattice, &layer, |p| rest[p as usize], |_, _| true);
        let (pairs, _) = apply_splits(&mut lattice, &plan);
        assert_eq!(pairs.len(), 4);
        // the blade still passes; the halves drift: the kept ones just across the plane
        // (by their own position on the far side, with all their edges on the near one)
        let mut position: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|p| lattice.rest_position(p))
            .collect();
        let mut halves = Vec::new();
        for &(old, new) in &pairs {
            position[old as usize].x = 0.38;
            position[new as usize].x = 0.3;
            halves.extend([(old, plane), (new, plane)]);
        }
        halves.sort_unstable_by_key(|(p, _)| *p);
        let again = plan_splits(&lattice, &halves, |p| position[p as usize], |_, _| true);
        assert_eq!(again, SplitPlan::default(), "no half splits again");
        assert_eq!(lattice.piece_count(), 2);
    }
}
