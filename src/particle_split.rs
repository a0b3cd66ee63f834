//! Splitting particles in two along a blade (the notes' better option to deleting the
//! particles a blade passes through): the old particle keeps the edges on its own side
//! of the blade's plane, a new particle at the same lattice coordinate takes the edges
//! on the far side, and each gets half the mass (the caller's part). The cut face is
//! clean and no mass is lost.

use crate::lattice::{Lattice, NO_PARTICLE};
use crate::tool::BladePlane;
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
/// ascending, each with the blade's plane), reading only: an edge from a candidate goes
/// to its new half when the neighbour lies across the plane (on the other side by more
/// than rounding: a neighbour on the plane, in the candidate's own layer, stays) and the
/// blade's sweep `crosses` the edge; an edge between two candidates across the plane is
/// severed instead (the blade passes between them), and so is every such edge of a
/// candidate the plane passes more than a quarter cell from (near its cell's face, the
/// halves' rest places, a quarter cell either side of the centre, would lie on one side).
/// A candidate without such an edge stays whole: a particle the blade passed once is
/// not split again.
pub fn plan_splits(
    lattice: &Lattice,
    candidates: &[(u32, BladePlane)],
    position: impl Fn(u32) -> Vec3,
    crosses: impl Fn(u32, u32) -> bool,
) -> SplitPlan {
    let tolerance = 1e-3 * lattice.spacing();
    let is_candidate = |q: u32| candidates.binary_search_by_key(&q, |(c, _)| *c).is_ok();
    let mut plan = SplitPlan::default();
    for &(p, plane) in candidates {
        let dp = plane.distance(position(p));
        let side = dp >= 0.0;
        let near_face = dp.abs() >= 0.25 * lattice.spacing();
        let mut moves = [false; 6];
        for (d, q) in lattice.links(p).into_iter().enumerate() {
            if q == NO_PARTICLE {
                continue;
            }
            let dq = plane.distance(position(q));
            if dq.abs() <= tolerance || (dq >= 0.0) == side || !crosses(p, q) {
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

/// Where the far half of a particle at `x` goes: its mirror image across the plane, at
/// least `gap` from the plane on the far side, so that the halves never coincide.
pub fn far_position(x: Vec3, plane: &BladePlane, gap: f32) -> Vec3 {
    let d = plane.distance(x);
    let far = if d >= 0.0 { -d.max(gap) } else { (-d).max(gap) };
    x + (far - d) * plane.normal
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Shape;
    use glam::UVec3;

    #[test]
    fn a_split_layer_parts_a_bar_into_two_pieces_without_losing_particles() {
        let mut lattice = Shape::cuboid(UVec3::new(6, 2, 2), 1.0)
            .voxelise(1.0)
            .unwrap();
        let before = lattice.live_count();
        // a blade across x = 0.4, through the layer of cells whose centres lie at 0.5
        let plane = BladePlane {
            normal: Vec3::X,
            offset: 0.4,
        };
        let layer: Vec<(u32, BladePlane)> = lattice
            .live_particles()
            .filter(|&p| lattice.coord(p).x == 0)
            .map(|p| (p, plane))
            .collect();
        let at = |p: u32| lattice.rest_position(p);
        let rest: Vec<Vec3> = (0..lattice.len() as u32).map(at).collect();
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
            let y = far_position(x, &plane, 0.05);
            assert!(
                (plane.distance(y) + plane.distance(x)).abs() < 1e-6 && plane.distance(y) < 0.0
            );
        }
    }
}
