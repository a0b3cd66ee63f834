//! Who carries a surface, laid out once per topology so that the per-frame update
//! ([`super::deform`]) reads short dense arrays instead of the whole body.
//!
//! The *carriers* are the particles the surface's vertices are bound to; each needs its
//! own position and its linked neighbours' to find its frame. Those particles are
//! numbered by *slot*: the carriers first, in the order of
//! [`SurfaceTopology::particles`], then their other linked neighbours. The stage
//! gathers their positions into slot order once a frame; everything after reads slots.

use super::extract::SurfaceTopology;
use crate::body::lattice::Lattice;
use crate::math::lanes::{LANES, Vec3x8};
use crate::util::grouping::group_by_key;
use crate::util::room::emptied_with_room;
use glam::{Quat, Vec3A};
use rayon::prelude::*;
use wide::f32x8;

/// The slots of a surface's carriers and of what they read (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct CarryLayout {
    /// The particle of each slot: the carriers, then their other linked neighbours.
    pub read: Vec<u32>,
    /// The carriers eight at a time, with what their frames read.
    pub(super) batches: Vec<FrameBatch>,
    /// Number of carriers.
    carriers: usize,
    /// Per binding of the topology, the slot of its particle (a carrier).
    pub(super) binding_slots: Vec<u32>,
    /// Per vertex `v`, the triangles around it are
    /// `vertex_triangles[triangle_start[v]..triangle_start[v + 1]]`.
    pub(super) triangle_start: Vec<u32>,
    pub(super) vertex_triangles: Vec<u32>,
}

/// Eight carriers (lane `l` is carrier `8b + l` of batch `b`; a short last batch
/// repeats its last carrier) and their spokes.
#[derive(Clone, Debug)]
pub(super) struct FrameBatch {
    /// Each lane's slot.
    pub(super) own: [u32; LANES],
    /// Spoke `k` of each lane: the slot of a linked neighbour, or the lane's own slot (a
    /// zero spoke, which adds nothing to its frame).
    pub(super) links: [[u32; LANES]; 6],
    /// The rest vectors of the spokes, in the lattice frame.
    pub(super) spokes: [Vec3x8; 6],
}

/// Every particle's slot (`u32::MAX` for one not read), by a table over the lattice
/// (its particles' count, not the surface's, but one pass instead of a search per
/// binding and per spoke), and the particle of each slot: the `carriers`' marked first,
/// then their other linked neighbours', which a pass in particle order numbers
/// ascending after the carriers.
fn slots(lattice: &Lattice, carriers: &[u32]) -> (Vec<u32>, Vec<u32>) {
    let mut slot_of = vec![u32::MAX; lattice.len()];
    for (s, &p) in carriers.iter().enumerate() {
        slot_of[p as usize] = s as u32;
    }
    const LINKED: u32 = u32::MAX - 1;
    for &p in carriers {
        for q in lattice.neighbours(p) {
            if slot_of[q as usize] == u32::MAX {
                slot_of[q as usize] = LINKED;
            }
        }
    }
    let mut read = carriers.to_vec();
    for (q, slot) in (0u32..).zip(slot_of.iter_mut()) {
        if *slot == LINKED {
            *slot = read.len() as u32;
            read.push(q);
        }
    }
    (slot_of, read)
}

/// The lists of a retired layout, which a new layout of the same body is written into
/// ([`CarryLayout::take_lists`]): a cut's new layout then reuses pages the process holds
/// instead of first-touching fresh ones.
#[derive(Debug, Default)]
pub struct SpareLists {
    batches: Vec<FrameBatch>,
    binding_slots: Vec<u32>,
}

impl CarryLayout {
    /// The layout of `topology`, extracted from `lattice`.
    pub fn new(lattice: &Lattice, topology: &SurfaceTopology) -> Self {
        Self::new_into(lattice, topology, SpareLists::default())
    }

    /// [`CarryLayout::new`], written into `spare`'s lists (new ones with room to spare
    /// where they are short, see [`emptied_with_room`]).
    pub fn new_into(lattice: &Lattice, topology: &SurfaceTopology, spare: SpareLists) -> Self {
        let carriers = &topology.particles;
        // (the triangles around each vertex need only the triangles: grouped beside
        // the slots' passes over the lattice, which are serial)
        let ((slot_of, read), (triangle_start, vertex_triangles)) = rayon::join(
            || slots(lattice, carriers),
            || {
                // (the triangles' corners as one flat list: corner `i` is of triangle
                // `i / 3`)
                let corners = topology.triangles.as_flattened();
                group_by_key(topology.vertex_count(), || {
                    (corners.iter().enumerate()).map(|(i, &v)| (v, (i / 3) as u32))
                })
            },
        );
        let rest = |p: u32| Vec3A::from(lattice.rest_position(p));
        let mut batches = emptied_with_room(spare.batches, carriers.len().div_ceil(LANES));
        let mut binding_slots = emptied_with_room(spare.binding_slots, topology.bindings.len());
        (0..carriers.len().div_ceil(LANES))
            .into_par_iter()
            .with_min_len(256)
            .map(|b| {
                let start = b * LANES;
                let last = (start + LANES).min(carriers.len()) - 1;
                let own: [u32; LANES] = std::array::from_fn(|l| (start + l).min(last) as u32);
                let mut links = [own; 6];
                let mut spokes = [[Vec3A::ZERO; LANES]; 6];
                for (l, &c) in own.iter().enumerate() {
                    let p = carriers[c as usize];
                    for (k, q) in lattice.neighbours(p).enumerate() {
                        links[k][l] = slot_of[q as usize];
                        spokes[k][l] = rest(q) - rest(p);
                    }
                }
                FrameBatch {
                    own,
                    links,
                    spokes: spokes.map(|s| Vec3x8::<f32x8>::from_lanes(s).store()),
                }
            })
            .collect_into_vec(&mut batches);
        (topology.bindings.par_iter())
            .with_min_len(4096)
            .map(|b| slot_of[b.particle as usize])
            .collect_into_vec(&mut binding_slots);
        Self {
            read,
            batches,
            carriers: carriers.len(),
            binding_slots,
            triangle_start,
            vertex_triangles,
        }
    }

    /// Hands over the lists a new layout of the body is written into
    /// ([`CarryLayout::new_into`]). What [`CarryLayout::carry_frames`] and
    /// [`CarryLayout::carry_positions`] read of this layout, as the new one's `old`, stays:
    /// its slots; nothing else may read it afterwards.
    pub fn take_lists(&mut self) -> SpareLists {
        SpareLists {
            batches: std::mem::take(&mut self.batches),
            binding_slots: std::mem::take(&mut self.binding_slots),
        }
    }

    /// Number of carriers (the first slots).
    pub fn carrier_count(&self) -> usize {
        self.carriers
    }

    /// The slot of particle `p`, if the layout reads it.
    pub fn slot_of(&self, p: u32) -> Option<usize> {
        let (carriers, extra) = self.read.split_at(self.carriers);
        carriers
            .binary_search(&p)
            .ok()
            .or_else(|| extra.binary_search(&p).ok().map(|s| self.carriers + s))
    }

    /// The frames of this layout's carriers, kept from `old` (the frames `old_frames` of
    /// an earlier layout of the same body) where a carrier was one before, else taken
    /// from a linked neighbour that was, else the identity: a particle a cut brings to
    /// the surface, or a split's new half, starts turned with the body around it.
    pub fn carry_frames(
        &self,
        lattice: &Lattice,
        old: &CarryLayout,
        old_frames: &[Quat],
    ) -> Vec<Quat> {
        let mut was = vec![u32::MAX; lattice.len()];
        for (s, &p) in old.read[..old.carriers.min(old_frames.len())]
            .iter()
            .enumerate()
        {
            if let Some(w) = was.get_mut(p as usize) {
                *w = s as u32;
            }
        }
        let frame_of = |p: u32| match was.get(p as usize) {
            Some(&s) if s != u32::MAX => Some(old_frames[s as usize]),
            _ => None,
        };
        self.read[..self.carriers]
            .iter()
            .map(|&p| {
                frame_of(p)
                    .or_else(|| lattice.neighbours(p).find_map(frame_of))
                    .unwrap_or(Quat::IDENTITY)
            })
            .collect()
    }

    /// Per slot, the position `old_positions` (one per slot of `old`) held for its
    /// particle, or zero for a particle `old` did not read: so that a particle whose
    /// entity is gone (removed by a cut, while a render mesh's unused vertex is still
    /// bound to it) stays where it was last seen.
    pub fn carry_positions(&self, old: &CarryLayout, old_positions: &[Vec3A]) -> Vec<Vec3A> {
        let particles = (old.read.iter().chain(&self.read))
            .map(|&p| p as usize + 1)
            .max()
            .unwrap_or(0);
        let mut was = vec![u32::MAX; particles];
        for (s, &p) in old.read[..old.read.len().min(old_positions.len())]
            .iter()
            .enumerate()
        {
            was[p as usize] = s as u32;
        }
        self.read
            .iter()
            .map(|&p| match was[p as usize] {
                u32::MAX => Vec3A::ZERO,
                s => old_positions[s as usize],
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use crate::surface::extract::extract;
    use glam::UVec3;

    #[test]
    fn slots_hold_the_carriers_first_then_their_links_and_batches_pad_with_the_last() {
        let mut l = Shape::cuboid(UVec3::new(5, 4, 3)).voxelise(0.5).unwrap();
        l.remove(7);
        l.sever(20, 21);
        let t = extract(&l);
        let layout = CarryLayout::new(&l, &t);
        let n = layout.carrier_count();
        assert_eq!(layout.read[..n], t.particles[..]);
        assert_eq!(layout.batches.len(), n.div_ceil(LANES));
        for (b, batch) in layout.batches.iter().enumerate() {
            for l_ in 0..LANES {
                let c = batch.own[l_] as usize;
                assert_eq!(c, (b * LANES + l_).min(n - 1), "lane {l_} of batch {b}");
                let p = layout.read[c];
                let mut linked: Vec<u32> = (0..6)
                    .map(|k| batch.links[k][l_] as usize)
                    .filter(|&s| s != c)
                    .map(|s| layout.read[s])
                    .collect();
                linked.sort_unstable();
                let mut expected: Vec<u32> = l.neighbours(p).collect();
                expected.sort_unstable();
                assert_eq!(linked, expected, "links of particle {p}");
                for k in 0..6 {
                    let q = layout.read[batch.links[k][l_] as usize];
                    let spoke = Vec3x8::<f32x8>::load(&batch.spokes[k]).lane(l_);
                    let expected = Vec3A::from(l.rest_position(q) - l.rest_position(p));
                    assert!((spoke - expected).length() < 1e-6);
                }
            }
        }
        for (b, &s) in t.bindings.iter().zip(&layout.binding_slots) {
            assert_eq!(layout.read[s as usize], b.particle);
        }
        // every slot past the carriers is a linked neighbour of one, read once
        let mut extra = layout.read[n..].to_vec();
        extra.dedup();
        assert_eq!(extra.len(), layout.read.len() - n);
        for q in extra {
            assert!(
                l.neighbours(q)
                    .any(|p| t.particles.binary_search(&p).is_ok())
            );
        }
    }

    /// A layout written into a retired layout's lists, whether they have room for it or
    /// not, is the layout made afresh; the retired layout still carries frames over.
    #[test]
    fn a_layout_written_into_spare_lists_is_the_layout_made_afresh() {
        let small = Shape::cuboid(UVec3::new(3, 3, 3)).voxelise(0.5).unwrap();
        let mut big = Shape::cuboid(UVec3::new(7, 5, 4)).voxelise(0.5).unwrap();
        big.sever(20, 21);
        let (st, bt) = (extract(&small), extract(&big));
        for (l, t, mut retired) in [
            (&big, &bt, CarryLayout::new(&small, &st)),
            (&small, &st, CarryLayout::new(&big, &bt)),
        ] {
            let frames = vec![Quat::from_rotation_x(0.2); retired.carrier_count()];
            let carried = CarryLayout::new(l, t).carry_frames(l, &retired, &frames);
            let spare = retired.take_lists();
            let into = CarryLayout::new_into(l, t, spare);
            assert_eq!(format!("{into:?}"), format!("{:?}", CarryLayout::new(l, t)));
            assert_eq!(into.carry_frames(l, &retired, &frames), carried);
        }
    }

    #[test]
    fn a_new_carrier_takes_the_frame_of_a_linked_old_one() {
        let mut l = Shape::cuboid(UVec3::new(6, 6, 6)).voxelise(0.5).unwrap();
        let before = CarryLayout::new(&l, &extract(&l));
        let turn = Quat::from_rotation_y(0.3);
        let frames = vec![turn; before.carrier_count()];
        // removing a surface particle brings the one under it to the surface; one of
        // its neighbours (at x = 0) was on the surface already
        let top = l.at(glam::IVec3::new(1, 2, 5) + l.coord(0)).unwrap();
        let under = l.at(glam::IVec3::new(1, 2, 4) + l.coord(0)).unwrap();
        assert!(
            before.read[..before.carrier_count()]
                .binary_search(&under)
                .is_err()
        );
        l.remove(top);
        let after = CarryLayout::new(&l, &extract(&l));
        let carried = after.carry_frames(&l, &before, &frames);
        let slot = after.read[..after.carrier_count()]
            .binary_search(&under)
            .unwrap();
        assert_eq!(carried[slot], turn);
        assert!(carried.iter().all(|q| *q == turn));
    }
}
