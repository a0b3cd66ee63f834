//! Carving: what a sphere or capsule in `sever` mode does. Every particle that has been
//! inside the tool at some time is *carved*, for good; the edges between carved and
//! uncarved particles are severed, and those between two carved particles are kept —
//! linked again where an earlier frame severed them. So the body loses the boundary of
//! everything the tool ever swept: one plug, whether the tool crossed it in one frame or
//! in sixty (cutting the boundary of each frame's sweep alone left a chain of plugs).

use crate::body::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use crate::cut::particle_split::Pairs;

/// Carves the live particles `inside` (inside a carving tool this frame). Returns the
/// edges severed (carved to uncarved) and the edges linked again (between carved
/// particles, severed by an earlier carve), each `(a, b)` with `a < b`.
///
/// A half of a split particle is carved only where it holds on to the rest of what is
/// carved (linked, or linkable, to a carved particle): its twin across the split holds
/// the edges on the other side, so a half inside the tool whose own edges all lead out
/// of it would come away alone — a single particle between the tool and the split — and
/// stays with the material its edges hold instead.
pub fn carve(lattice: &mut Lattice, inside: &[u32]) -> (Pairs, Pairs) {
    let carving =
        |lattice: &Lattice, q: u32| lattice.is_carved(q) || inside.binary_search(&q).is_ok();
    let holds_on = |lattice: &Lattice, p: u32| {
        NEIGHBOUR_OFFSETS
            .iter()
            .enumerate()
            .any(|(d, offset)| match lattice.link(p, d) {
                NO_PARTICLE => lattice
                    .at(lattice.coord(p) + *offset)
                    .is_some_and(|q| carving(lattice, q) && lattice.link(q, d ^ 1) == NO_PARTICLE),
                q => carving(lattice, q),
            })
    };
    let taken: Vec<u32> = inside
        .iter()
        .copied()
        .filter(|&p| lattice.is_live(p) && !lattice.is_carved(p))
        .filter(|&p| !lattice.is_split_half(p) || holds_on(lattice, p))
        .collect();
    let newly: Vec<u32> = taken.into_iter().filter(|&p| lattice.carve(p)).collect();
    let (mut severed, mut relinked) = (Vec::new(), Vec::new());
    for &c in &newly {
        for (d, offset) in NEIGHBOUR_OFFSETS.iter().enumerate() {
            let q = lattice.link(c, d);
            if q != NO_PARTICLE {
                if !lattice.is_carved(q) && lattice.sever(c, q) {
                    severed.push((c.min(q), c.max(q)));
                }
            } else if let Some(q) = lattice.at(lattice.coord(c) + *offset)
                && lattice.is_carved(q)
                && lattice.relink(c, q)
            {
                relinked.push((c.min(q), c.max(q)));
            }
        }
    }
    (severed, relinked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::{IVec3, UVec3};

    /// The particles of a 10-cell bar whose x lies in `range`.
    fn cells(lattice: &Lattice, range: std::ops::Range<i32>) -> Vec<u32> {
        lattice
            .live_particles()
            .filter(|&p| range.contains(&lattice.coord(p).x) && lattice.coord(p).y == 0)
            .collect()
    }

    #[test]
    fn carving_in_steps_cuts_what_carving_at_once_cuts() {
        let bar = Shape::cuboid(UVec3::new(10, 3, 3)).voxelise(1.0).unwrap();
        // a slot along x through the middle row, carved at once or cell by cell
        let mut once = bar.clone();
        let all = cells(&once, -3..3);
        let (severed, relinked) = carve(&mut once, &all);
        assert!(relinked.is_empty() && !severed.is_empty());
        let mut steps = bar.clone();
        let mut relinks = 0;
        for x in -3..3 {
            let slice = cells(&steps, x..x + 1);
            relinks += carve(&mut steps, &slice).1.len();
        }
        assert_eq!(steps.edges(), once.edges());
        assert_eq!(
            relinks,
            5 * 3,
            "each step links the slot back to the last one"
        );
        assert_eq!(once.piece_count(), 2, "the slot is one plug");
        // carving the same particles again changes nothing
        assert_eq!(carve(&mut once, &all), (Vec::new(), Vec::new()));
        assert!(once.is_carved(all[0]) && !once.is_carved(once.at(IVec3::new(4, 1, 1)).unwrap()));
    }
}
