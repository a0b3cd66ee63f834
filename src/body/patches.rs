//! Surface patches and boundary sets of a body's lattice (SPEC §6.1, Yuksel et al.
//! 2012): the sets the shape-keeping constraints act on, found on the lattice's live
//! links so that they follow every cut.
//!
//! - A **patch** is centred on a surface particle (one with a missing link): the surface
//!   particles within `k` rings of it — ring `r` is reached in `r` steps along links
//!   between surface particles — weighted by a tent, `(k + 1 − r)/(k + 1)`. Its rest
//!   normal is the tent-weighted sum of the directions of its members' missing links:
//!   on a voxel surface those point out of the body. Its **frame set** is every live
//!   particle within `k + 1` links of the centre, surface or not, that is not a member:
//!   the surroundings whose rigid fit says how the patch should have moved and turned,
//!   uninfluenced by the patch itself (mostly the body beneath it).
//! - A **boundary set** is the surface particles of one block of `cells³` lattice
//!   cells: a coarse partition of the surface whose centroids relaxation holds.

use super::lattice::{Lattice, NEIGHBOUR_OFFSETS, NO_PARTICLE};
use glam::{IVec3, Vec3};
use std::collections::BTreeMap;

/// Largest number of rings a patch may have.
pub const MAX_RINGS: u32 = 8;

/// One patch, by body-local particle index.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// The centre particle.
    pub centre: u32,
    /// The members (the centre first, then ring by ring) and their tent weights,
    /// normalised to sum to 1.
    pub members: Vec<(u32, f32)>,
    /// The rest normal, a unit vector in the lattice's frame.
    pub normal: Vec3,
    /// The particles whose rigid fit gives the patch its frame (no member among them).
    pub frame: Vec<u32>,
}

/// Marks of visited particles, cleared in O(1) by a new generation.
struct Visits {
    mark: Vec<u32>,
    generation: u32,
}

impl Visits {
    fn new(len: usize) -> Self {
        Self {
            mark: vec![0; len],
            generation: 0,
        }
    }

    fn clear(&mut self) {
        self.generation += 1;
    }

    /// Marks `i`; whether it was unmarked.
    fn visit(&mut self, i: u32) -> bool {
        let mark = &mut self.mark[i as usize];
        std::mem::replace(mark, self.generation) != self.generation
    }

    fn seen(&self, i: u32) -> bool {
        self.mark[i as usize] == self.generation
    }
}

/// The particles reached from `start` in at most `depth` steps along the lattice's
/// links that `admit` lets through, each with its step count, in breadth-first order;
/// they are left marked in `visits`.
fn rings(
    lattice: &Lattice,
    start: u32,
    depth: u32,
    admit: impl Fn(u32) -> bool,
    visits: &mut Visits,
) -> Vec<(u32, u32)> {
    let mut found = vec![(start, 0)];
    visits.clear();
    visits.visit(start);
    let mut next = 0;
    while next < found.len() {
        let (i, ring) = found[next];
        next += 1;
        if ring == depth {
            continue;
        }
        for j in lattice.links(i) {
            if j != NO_PARTICLE && admit(j) && visits.visit(j) {
                found.push((j, ring + 1));
            }
        }
    }
    found
}

/// The outward directions of particle `i`'s missing links, summed (zero inside).
fn open_directions(lattice: &Lattice, i: u32) -> Vec3 {
    lattice
        .links(i)
        .iter()
        .zip(NEIGHBOUR_OFFSETS)
        .filter(|(j, _)| **j == NO_PARTICLE)
        .map(|(_, d)| d.as_vec3())
        .sum()
}

/// The patch of `rings` rings (1 to [`MAX_RINGS`]) around every surface particle of
/// `lattice` whose patch has a normal: where the open directions cancel (a sheet one
/// particle thick, a lone particle) the surface has no side to keep, and there is no
/// patch. Ordered by centre.
pub fn surface_patches(lattice: &Lattice, rings: u32) -> Vec<Patch> {
    let rings = rings.clamp(1, MAX_RINGS);
    let (mut visits, mut members_of) = (Visits::new(lattice.len()), Visits::new(lattice.len()));
    let mut patches = Vec::new();
    for centre in lattice.live_particles() {
        if !lattice.is_surface(centre) {
            continue;
        }
        let reached = self::rings(
            lattice,
            centre,
            rings,
            |j| lattice.is_surface(j),
            &mut members_of,
        );
        let tent = |ring: u32| (rings + 1 - ring) as f32 / (rings + 1) as f32;
        let total: f32 = reached.iter().map(|&(_, r)| tent(r)).sum();
        let members: Vec<(u32, f32)> = reached.iter().map(|&(j, r)| (j, tent(r) / total)).collect();
        let normal: Vec3 = members
            .iter()
            .map(|&(j, w)| open_directions(lattice, j) * w)
            .sum();
        // below a quarter of the centre's own share of one open face: no side to keep
        if normal.length() < 0.25 * members[0].1 {
            continue;
        }
        let frame = self::rings(lattice, centre, rings + 1, |_| true, &mut visits)
            .into_iter()
            .map(|(j, _)| j)
            .filter(|j| !members_of.seen(*j))
            .collect();
        patches.push(Patch {
            centre,
            members,
            normal: normal.normalize(),
            frame,
        });
    }
    patches
}

/// The surface particles of `lattice` in blocks of `cells³` lattice cells (`cells ≥
/// 1`), one set per block that holds any, each sorted, ordered by block.
pub fn boundary_sets(lattice: &Lattice, cells: u32) -> Vec<Vec<u32>> {
    let cells = cells.max(1) as i32;
    let mut blocks: BTreeMap<[i32; 3], Vec<u32>> = BTreeMap::new();
    for i in lattice.live_particles() {
        if lattice.is_surface(i) {
            let block: IVec3 = lattice.coord(i).div_euclid(IVec3::splat(cells));
            blocks.entry(block.to_array()).or_default().push(i);
        }
    }
    blocks.into_values().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cuboid(x: i32, y: i32, z: i32) -> Lattice {
        let coords = (0..z)
            .flat_map(|k| (0..y).flat_map(move |j| (0..x).map(move |i| IVec3::new(i, j, k))))
            .collect();
        Lattice::from_coords(1.0, coords).expect("a block")
    }

    #[test]
    fn a_face_patch_has_tent_rings_and_points_out_of_its_face() {
        let lattice = cuboid(9, 9, 5);
        let patches = surface_patches(&lattice, 2);
        let top = lattice
            .at(IVec3::new(4, 4, 4))
            .expect("the middle of the top face");
        let patch = patches.iter().find(|p| p.centre == top).expect("a patch");
        // a diamond on the face: 1 + 4 + 8 members with weights 3 : 2 : 1
        assert_eq!(patch.members.len(), 13);
        let sum: f32 = patch.members.iter().map(|m| m.1).sum();
        assert!((sum - 1.0).abs() < 1e-6);
        let (centre, first, second) = (patch.members[0].1, patch.members[1].1, patch.members[12].1);
        assert!((centre / second - 3.0).abs() < 1e-5 && (first / second - 2.0).abs() < 1e-5);
        assert!(patch.members.iter().all(|&(j, _)| lattice.coord(j).z == 4));
        assert!(patch.normal.abs_diff_eq(Vec3::Z, 1e-6), "{}", patch.normal);
        // the frame: every other particle within three links, the interior below included
        assert_eq!(patch.frame.len(), (25 - 13) + 13 + 5 + 1);
        assert!(patch.frame.iter().any(|&j| lattice.coord(j).z == 1));
        // a corner's patch points out along the diagonal
        let corner = lattice.at(IVec3::ZERO).expect("a corner");
        let patch = patches
            .iter()
            .find(|p| p.centre == corner)
            .expect("a patch");
        assert!(
            patch.normal.dot(Vec3::splat(-1.0).normalize()) > 0.95,
            "{}",
            patch.normal
        );
        // every surface particle has one, interior particles none
        let surface = lattice
            .live_particles()
            .filter(|&i| lattice.is_surface(i))
            .count();
        assert_eq!(patches.len(), surface);
        assert_eq!(surface, 9 * 9 * 5 - 7 * 7 * 3);
    }

    #[test]
    fn a_sheet_one_particle_thick_has_no_patches_and_a_cut_makes_new_ones() {
        // inside a sheet the two open faces cancel; its rim points out sideways
        let sheet = cuboid(12, 12, 1);
        let patches = surface_patches(&sheet, 2);
        let middle = sheet.at(IVec3::new(6, 6, 0)).expect("the middle");
        assert!(patches.iter().all(|p| p.centre != middle));
        let rim = sheet.at(IVec3::new(0, 6, 0)).expect("the rim");
        let patch = patches
            .iter()
            .find(|p| p.centre == rim)
            .expect("a rim patch");
        assert!(patch.normal.abs_diff_eq(-Vec3::X, 1e-6), "{}", patch.normal);
        let mut lattice = cuboid(6, 6, 6);
        let inside = lattice.at(IVec3::new(2, 3, 3)).expect("inside");
        let before = surface_patches(&lattice, 1);
        assert!(before.iter().all(|p| p.centre != inside));
        // severing the +x edge opens a face on each side
        let beyond = lattice.link(inside, 1);
        lattice.sever(inside, beyond);
        let after = surface_patches(&lattice, 1);
        let patch = after
            .iter()
            .find(|p| p.centre == inside)
            .expect("a new patch");
        assert!(patch.normal.abs_diff_eq(Vec3::X, 1e-6), "{}", patch.normal);
        // the frame does not reach across the cut directly
        let first_ring = patch.frame.iter().filter(|&&j| {
            (lattice.coord(j) - lattice.coord(inside))
                .abs()
                .element_sum()
                == 1
        });
        assert!(first_ring.clone().all(|&j| j != beyond) && first_ring.count() > 0);
    }

    #[test]
    fn boundary_sets_partition_the_surface_by_block() {
        let lattice = cuboid(8, 4, 4);
        let sets = boundary_sets(&lattice, 4);
        assert_eq!(sets.len(), 2);
        let all: usize = sets.iter().map(Vec::len).sum();
        assert_eq!(all, 8 * 4 * 4 - 6 * 2 * 2);
        assert!(sets[0].iter().all(|&i| lattice.coord(i).x < 4));
        assert!(sets[1].iter().all(|&i| lattice.coord(i).x >= 4));
    }
}
