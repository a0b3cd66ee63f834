//! What a body takes of its memory budget ([`crate::config::SimConfig::memory_budget_gb`]),
//! estimated alike when it is spawned and before a cut splits its particles: its
//! particles at [`BYTES_PER_PARTICLE`] each, its surface at [`BYTES_PER_FACE`] per quad.

use crate::body::lattice::Lattice;
use crate::body::shape::BYTES_PER_PARTICLE;
use crate::cut::particle_split::SplitPlan;
use crate::surface::extract::{BYTES_PER_FACE, QUADS_PER_SPLIT_FACE, face_count, quads_per_face};

/// Bytes of `particles` particles.
pub fn particle_bytes(particles: u64) -> u64 {
    particles * BYTES_PER_PARTICLE
}

/// Bytes of a surface of `quads` quads.
pub fn surface_bytes(quads: u64) -> u64 {
    quads * BYTES_PER_FACE
}

/// About what the body of `lattice` takes once `plan` is carried out: its particles,
/// the new halves among them, and its surface — the lattice's faces and two more per
/// edge the plan separates, drawn as four quads each once a particle of the body is
/// split (the first split redraws the whole surface so).
pub fn bytes_after_split(lattice: &Lattice, plan: &SplitPlan) -> u64 {
    // (the plan's first split draws the whole surface as a split body's)
    let quads_per_face = if plan.splits.is_empty() {
        quads_per_face(lattice)
    } else {
        QUADS_PER_SPLIT_FACE
    };
    let separated = (plan.sever.len() + plan.splits.len()) as u64;
    let faces = face_count(lattice) + 2 * separated;
    particle_bytes(lattice.len() as u64 + plan.splits.len() as u64)
        + surface_bytes(faces * quads_per_face)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::lattice::Lattice;
    use glam::IVec3;

    #[test]
    fn a_split_counts_its_new_halves_and_four_quads_per_face() {
        // a 4×4×4 block: 64 particles, 96 faces
        let coords: Vec<IVec3> = (0..64)
            .map(|i| IVec3::new(i % 4, (i / 4) % 4, i / 16))
            .collect();
        let lattice = Lattice::from_coords(1.0, coords).unwrap();
        assert_eq!(face_count(&lattice), 96);
        let none = SplitPlan::default();
        assert_eq!(
            bytes_after_split(&lattice, &none),
            64 * BYTES_PER_PARTICLE + 96 * BYTES_PER_FACE
        );
        // one edge severed: two faces more
        let sever = SplitPlan {
            splits: Vec::new(),
            sever: vec![(0, 1)],
        };
        assert_eq!(
            bytes_after_split(&lattice, &sever),
            64 * BYTES_PER_PARTICLE + 98 * BYTES_PER_FACE
        );
        // one particle split, its new half taking one edge: a particle and two faces
        // more, and the whole surface drawn four quads a face
        let p = 0;
        let d = (0..6)
            .find(|&d| lattice.link(p, d) != crate::body::lattice::NO_PARTICLE)
            .unwrap();
        let mut moves = [false; 6];
        moves[d] = true;
        let plane = crate::cut::tool::BladePlane {
            normal: glam::Vec3::X,
            offset: 0.1,
        };
        let split = SplitPlan {
            splits: vec![(p, moves, plane)],
            sever: Vec::new(),
        };
        assert_eq!(
            bytes_after_split(&lattice, &split),
            65 * BYTES_PER_PARTICLE + 4 * 98 * BYTES_PER_FACE
        );
        // and the edges severed instead are those it would have handed to the new half
        assert_eq!(
            split.severing_only(&lattice).sever,
            [(0, lattice.link(p, d))]
        );
    }
}
