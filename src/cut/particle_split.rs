//! Splitting particles in two along a blade (the notes' better option to deleting the
//! particles a blade passes through): where the blade passes through a particle's cell,
//! a new particle at the same lattice coordinate takes the edges the blade crossed, the
//! old one keeps the rest, and each gets half the mass (the caller's part). The cut face
//! is clean and no mass is lost.
//!
//! The blade separates exactly the edges a `sever` blade severs
//! ([`crate::cut::tool_sweep::ToolSweep::separates`]); a split hands some of them to a new
//! half instead of severing them. A new half is linked only to the far side, so the
//! pieces are the ones the blade's swept surface separates, each with the slivers of the
//! cells it cut through.

use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use crate::cut::tool::BladePlane;
use glam::Vec3;

/// How far beyond the blade's plane the halves of a split particle lie at least,
/// together, in lattice spacings (half of it each side).
pub const SPLIT_GAP: f32 = 0.1;

/// What a split blade does to one body: particles to split, each with the directions
/// of the edges its new half takes, and edges to sever.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplitPlan {
    /// `(particle, the lattice directions its new half takes, the blade's plane)`,
    /// ascending by particle; the plane is oriented so that the particle's kept half
    /// lies on its positive side.
    pub splits: Vec<(u32, [bool; 6], BladePlane)>,
    /// Separated edges no split takes, `(a, b)` with `a < b`, ascending.
    pub sever: Vec<(u32, u32)>,
}

impl SplitPlan {
    /// Makes the plans of several split blades (appended one after another) one: the
    /// first plan for a particle splits it, and the edges a later one would have given
    /// its new half are severed instead (they are separated all the same); everything
    /// sorted, without repeats.
    pub fn merge_tools(&mut self, lattice: &Lattice) {
        self.splits.sort_by_key(|(p, ..)| *p);
        let mut first: Vec<(u32, [bool; 6], BladePlane)> = Vec::with_capacity(self.splits.len());
        for split in self.splits.drain(..) {
            if first.last().is_some_and(|f| f.0 == split.0) {
                let (p, moves, _) = split;
                self.sever.extend(moved_edges(lattice, p, moves));
            } else {
                first.push(split);
            }
        }
        self.splits = first;
        self.sever.sort_unstable();
        self.sever.dedup();
    }

    /// The plan with no split: every edge it separates severed, those it hands to new
    /// halves too (sorted, without repeats). It leaves the pieces the plan makes less
    /// the new halves, each split particle where its kept half would be.
    pub fn severing_only(&self, lattice: &Lattice) -> SplitPlan {
        let mut sever = self.sever.clone();
        for &(p, moves, _) in &self.splits {
            sever.extend(moved_edges(lattice, p, moves));
        }
        sever.sort_unstable();
        sever.dedup();
        SplitPlan {
            splits: Vec::new(),
            sever,
        }
    }
}

/// The edges from `p` in the directions `moves` marks (those its new half would take),
/// as `(a, b)` with `a < b`.
fn moved_edges(lattice: &Lattice, p: u32, moves: [bool; 6]) -> impl Iterator<Item = (u32, u32)> {
    (0..6)
        .filter(move |&d| moves[d])
        .map(move |d| lattice.link(p, d))
        .filter(|&q| q != NO_PARTICLE)
        .map(move |q| (p.min(q), p.max(q)))
}

/// Plans what a split blade whose plane is `plane` does to a body, reading only:
/// `separated` are the body's edges the blade's sweep crosses (`(a, b)`, `a < b`), and
/// each is either handed to a new half or severed.
///
/// An edge goes to a new half of its end nearer the plane when the plane passes within
/// a quarter cell of that end (through the middle half of its cell), and when both
/// halves of that end would rest on their own sides of the plane, at least
/// [`SPLIT_GAP`]` / 2` cells from it: the new half a quarter of the way toward the
/// edges it takes, the kept one a quarter of the way away (their rest places, see
/// [`Lattice::split`], measured on the body as it is, see [`split_positions`]). Then a
/// half never rests across the plane, and the blade, still passing, finds nothing to
/// cut again. Every other separated edge is severed, as a `sever` blade severs it.
///
/// Where the plane passes through the near end's centre (within rounding), the end
/// belongs to the plane's positive side: its edges to that side stay whole, and its new
/// half takes all its edges to the other side.
///
/// A half of an earlier split keeps the edges along its own side (the way it rests from
/// its cell's centre) even when the blade crosses them: the blade then passes through
/// the sliver of the cell the half is, which it cannot part from its edges (severing
/// them would leave the sliver alone, and splitting it again would leave its last
/// edges).
pub fn plan_splits(
    lattice: &Lattice,
    separated: &[(u32, u32)],
    position: impl Fn(u32) -> Vec3,
    plane: BladePlane,
) -> SplitPlan {
    let h = lattice.spacing();
    // a particle's side of the plane; one on it (within rounding, as a layer the blade
    // passes through the centres of) belongs to the positive side, all alike
    let on_plane = |d: f32| d.abs() <= 1e-3 * h;
    let side = |d: f32| d > 0.0 || on_plane(d);
    let mut plan = SplitPlan::default();
    // the near ends the plane passes within a quarter cell of, each with the direction
    // of a separated edge to its other side (none where only rounding finds the edge
    // crossed: the far end lies on the near end's side)
    let mut through: Vec<(u32, Option<usize>)> = Vec::new();
    for &(a, b) in separated {
        let (da, db) = (plane.distance(position(a)), plane.distance(position(b)));
        let (near, far, d_near, d_far) = if da.abs() <= db.abs() {
            (a, b, da, db)
        } else {
            (b, a, db, da)
        };
        match (0..6).find(|&d| lattice.link(near, d) == far) {
            Some(d) if d_near.abs() < 0.25 * h => {
                through.push((near, (side(d_near) != side(d_far)).then_some(d)));
            }
            _ => plan.sever.push((a, b)),
        }
    }
    through.sort_unstable();
    for run in through.chunk_by(|x, y| x.0 == y.0) {
        let p = run[0].0;
        let x = position(p);
        let mut moves = [false; 6];
        for d in run.iter().filter_map(|(_, d)| *d) {
            moves[d] = true;
        }
        // through its centre, the blade crosses every edge to the negative side, though
        // rounding finds some of them not crossed at all
        if on_plane(plane.distance(x)) {
            for (d, q) in lattice.links(p).into_iter().enumerate() {
                if q != NO_PARTICLE && !side(plane.distance(position(q))) {
                    moves[d] = true;
                }
            }
        }
        // a half keeps the edges along its own side
        let shift = lattice.split_shift(p);
        for (d, offset) in NEIGHBOUR_OFFSETS.iter().enumerate() {
            moves[d] &= offset.as_vec3().dot(shift) <= 0.0;
        }
        if !moves.contains(&true) {
            continue;
        }
        let taken: Vec<usize> = (0..6).filter(|&d| moves[d]).collect();
        let toward = taken
            .iter()
            .map(|&d| position(lattice.link(p, d)) - x)
            .sum::<Vec3>()
            / taken.len() as f32;
        // the kept half's side is the one away from the edges it gives
        let plane = if plane.distance(x + toward) < plane.distance(x) {
            plane
        } else {
            plane.flipped()
        };
        let room = 0.5 * SPLIT_GAP * h;
        let fits =
            plane.distance(x - 0.25 * toward) >= room && plane.distance(x + 0.25 * toward) <= -room;
        if fits {
            plan.splits.push((p, moves, plane));
        } else {
            plan.sever.extend(taken.iter().map(|&d| {
                let q = lattice.link(p, d);
                (p.min(q), p.max(q))
            }));
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
/// positive side the particle keeps), given `toward`, the mean of the vectors from `x`
/// to the neighbours the new half took.
///
/// Each half goes to its rest place ([`Lattice::split`]: a quarter of the way toward
/// the edges it holds, measured on the body as it is, so a turned or stretched body is
/// followed): the new half `x + toward / 4`, the kept one `x − toward / 4`. Then no
/// edge or cluster is strained by the split and the pieces stay where they were, as a
/// sever leaves them (put elsewhere, shape matching pushes them apart, and a rigid body
/// cut through its middle flew apart at metres per second). A half its rest place
/// would leave on the wrong side of the plane, or within `gap / 2` of it, is moved
/// along the normal to `gap / 2` on its own side, so the halves never coincide and lie
/// on their sides.
pub fn split_positions(x: Vec3, toward: Vec3, plane: &BladePlane, gap: f32) -> (Vec3, Vec3) {
    let onto_side = |y: Vec3, sign: f32| {
        let d = sign * plane.distance(y);
        y + sign * (0.5 * gap - d).max(0.0) * plane.normal
    };
    (
        onto_side(x - 0.25 * toward, 1.0),
        onto_side(x + 0.25 * toward, -1.0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    /// A 6×2×2 bar of unit cells, its rest positions, and the edges a blade across
    /// x = `at` separates (the edges whose ends lie on either side).
    fn bar(at: f32) -> (Lattice, BladePlane, Vec<Vec3>, Vec<(u32, u32)>) {
        let lattice = Shape::cuboid(UVec3::new(6, 2, 2)).voxelise(1.0).unwrap();
        let plane = BladePlane {
            normal: Vec3::X,
            offset: at,
        };
        let rest: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|p| lattice.rest_position(p))
            .collect();
        let separated = crossing(&lattice, &plane, &rest);
        (lattice, plane, rest, separated)
    }

    fn crossing(lattice: &Lattice, plane: &BladePlane, at: &[Vec3]) -> Vec<(u32, u32)> {
        let mut edges: Vec<(u32, u32)> = lattice
            .edges()
            .into_iter()
            .filter(|&(a, b)| plane.distance(at[a as usize]) * plane.distance(at[b as usize]) < 0.0)
            .collect();
        edges.sort_unstable();
        edges
    }

    #[test]
    fn a_blade_through_a_layer_splits_it_and_parts_the_bar_without_losing_particles() {
        // the plane passes a tenth of a cell from the layer at x = 0.5
        let (mut lattice, plane, rest, separated) = bar(0.4);
        assert_eq!(separated.len(), 4);
        let before = lattice.live_count();
        let plan = plan_splits(&lattice, &separated, |p| rest[p as usize], plane);
        assert!(plan.sever.is_empty(), "{plan:?}");
        let (pairs, severed) = apply_splits(&mut lattice, &plan);
        assert_eq!(pairs.len(), 4, "each particle of the layer splits");
        assert!(severed.is_empty());
        assert_eq!(lattice.live_count(), before + 4);
        assert_eq!(lattice.piece_count(), 2);
        for (old, new) in pairs {
            assert_eq!(lattice.coord(new), lattice.coord(old));
            // the new halves took the crossed edges, to the −x side
            assert!(lattice.neighbours(old).all(|q| lattice.coord(q).x >= 0));
            assert!(lattice.neighbours(new).all(|q| lattice.coord(q).x < 0));
            // at rest, each half goes to its rest place
            let x = rest[old as usize];
            let toward = rest[lattice.link(new, 0) as usize] - x;
            let (kept, y) = split_positions(x, toward, &plane, SPLIT_GAP);
            assert!(kept.distance(lattice.rest_position(old)) < 1e-6, "{kept}");
            assert!(y.distance(lattice.rest_position(new)) < 1e-6, "{y}");
        }
    }

    #[test]
    fn a_blade_between_layers_or_where_a_half_would_rest_across_it_severs() {
        // midway between the layers at −0.5 and 0.5: neither cell is passed through
        // its middle half; 0.22 from the layer at 0.5: its new halves would rest at
        // 0.25, beyond the plane at 0.28 by less than half the gap
        for at in [0.0, 0.28] {
            let (lattice, plane, rest, separated) = bar(at);
            let plan = plan_splits(&lattice, &separated, |p| rest[p as usize], plane);
            assert!(plan.splits.is_empty(), "{at}: {plan:?}");
            assert_eq!(plan.sever, separated, "{at}");
        }
    }

    #[test]
    fn each_half_goes_to_its_rest_place_on_its_own_side() {
        let plane = BladePlane {
            normal: Vec3::new(0.6, 0.8, 0.0),
            offset: 1.0,
        };
        let toward = -0.1 * Vec3::X;
        for d in [-0.3f32, -0.02, 0.0, 0.02, 0.3] {
            let x = Vec3::new(1.0, 0.5, -2.0) + d * plane.normal;
            let (kept, new) = split_positions(x, toward, &plane, 0.05);
            let (rest_kept, rest_new) = (x - 0.25 * toward, x + 0.25 * toward);
            assert!(plane.distance(kept) >= 0.025 - 1e-6, "{d}: {kept}");
            assert!(plane.distance(new) <= -0.025 + 1e-6, "{d}: {new}");
            // moved off its rest place only along the normal, and only when it must
            for (y, rest, sign) in [(kept, rest_kept, 1.0), (new, rest_new, -1.0)] {
                assert!((y - rest).cross(plane.normal).length() < 1e-6, "{d}");
                if sign * plane.distance(rest) >= 0.025 {
                    assert_eq!(y, rest, "{d}");
                }
            }
        }
    }

    #[test]
    fn a_half_the_blade_crosses_again_keeps_the_edges_of_its_side() {
        let (mut lattice, plane, rest, separated) = bar(0.4);
        let plan = plan_splits(&lattice, &separated, |p| rest[p as usize], plane);
        let (pairs, _) = apply_splits(&mut lattice, &plan);
        // the blade still passes; the halves drift across it (the kept ones to 0.38,
        // beside their +x edges; the new ones to 0.45, beside their −x edges)
        let mut at: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|p| lattice.rest_position(p))
            .collect();
        for &(old, new) in &pairs {
            at[old as usize].x = 0.38;
            at[new as usize].x = 0.45;
        }
        let again = crossing(&lattice, &plane, &at);
        assert_eq!(again.len(), 8, "every half's edge across the plane");
        let plan = plan_splits(&lattice, &again, |p| at[p as usize], plane);
        assert_eq!(plan, SplitPlan::default(), "nothing cut again");
    }

    #[test]
    fn merged_plans_split_a_particle_once_and_sever_the_rest() {
        let (lattice, plane, rest, separated) = bar(0.4);
        let mut plan = plan_splits(&lattice, &separated, |p| rest[p as usize], plane);
        let first = plan.clone();
        // a second blade wanting the same particles' +x edges
        let second: Vec<(u32, [bool; 6], BladePlane)> = first
            .splits
            .iter()
            .map(|&(p, _, plane)| (p, [false, true, false, false, false, false], plane))
            .collect();
        plan.splits.extend(second);
        plan.merge_tools(&lattice);
        assert_eq!(plan.splits, first.splits);
        let expected: Vec<(u32, u32)> = first
            .splits
            .iter()
            .map(|&(p, ..)| (p, lattice.link(p, 1)))
            .collect();
        assert_eq!(plan.sever, expected);
    }
}
