//! Conservative culling of contact pairs (SPEC §6.2; Yuksel et al. 2012): the pairs a
//! substep needs are taken from a list of candidates kept across substeps, and the
//! cell search of [`super::contact_pairs`] runs again only when something may have come
//! close that the list does not hold.
//!
//! **Why it is exact.** Each particle keeps a reference position, and the candidates
//! are every pair whose balls at their reference positions are closer than the
//! substep's pair distance (radii plus the margin `PAIR_MARGIN`) plus a
//! *skin*. While each of two particles is within half the skin of its reference, they
//! are closer now than the pair distance only if their references are closer than the
//! pair distance plus the skin: every pair a substep needs is a candidate. So each
//! substep, the particles that have moved half the skin from their references (a
//! non-finite position counts as moved) take their current positions as references,
//! their candidates are dropped and searched again against every particle's reference
//! (in a grid of the references); the candidates are then filtered by the
//! pair distance at the current positions, with the one test the search itself ends
//! with (`within`). Searching against references, not current positions, is what
//! keeps the list exact when references are taken at different times. When most
//! particles moved, the whole list is built afresh.
//!
//! **Why it does not change a result.** The pairs come out sorted by their two contact
//! indices, whichever way they were found, and the culling setting only says how often
//! the list is rebuilt (off: every substep): so a run is bit for bit the same with
//! culling on and off, and for any thread count.

use super::contact_grid::CellGrid;
use super::contact_pairs::{ContactGroup, ContactParticles, PAIR_MARGIN, within};
use glam::Vec3A;
use rayon::prelude::*;

/// The skin, in units of the largest radius: how much farther apart than the pair
/// distance a candidate may be. A wider skin lets particles move farther before their
/// pairs are searched again and makes each substep filter more candidates. Bodies
/// settling in a pile drift slowly and long (at one radius a fifth of their particles
/// left the skin every substep), and want it wide; the faces of a cut that rest against
/// each other want it narrow (at two radii a face particle's candidates take in the
/// particles two cells along the other face: twice as many as at one and a half).
pub const SKIN: f32 = 1.5;

/// Candidates per parallel task of the filter.
const PER_TASK: usize = 4096;

/// When more than this share of the particles moved, the list is built afresh rather
/// than updated where they moved.
const REBUILD_SHARE: f32 = 0.5;

/// The candidate pairs of the contact particles, kept across substeps.
#[derive(Clone, Debug, Default)]
pub struct ContactList {
    /// Whether the list is kept across substeps (the simulation's `culling` setting);
    /// off, it is built afresh every substep.
    culling: bool,
    /// Candidate pairs `(a << 32) | b`, `a < b` (contact indices), ascending.
    candidates: Vec<u64>,
    /// Each contact particle's reference position; empty: no list.
    reference: Vec<Vec3A>,
    /// The references in cells.
    grid: CellGrid,
    /// How far a particle may move from its reference before its pairs are searched
    /// again.
    half_skin: f32,
    /// Full builds and local updates since the particles last changed.
    updates: (u64, u64),
}

impl ContactList {
    /// Turns culling on or off.
    pub fn set_culling(&mut self, culling: bool) {
        self.culling = culling;
    }

    /// Forgets the list (the particles changed).
    pub fn clear(&mut self) {
        self.candidates.clear();
        self.reference.clear();
        self.grid = CellGrid::default();
        self.updates = (0, 0);
    }

    /// How often the list was built in full, and how often updated where particles
    /// moved, since the particles last changed.
    pub fn updates(&self) -> (u64, u64) {
        self.updates
    }

    /// Every pair of `particles` that may touch (in `groups`) and whose balls at
    /// `positions` are closer than their radii plus the margin, each once as `(a, b)`
    /// with `a < b`, ascending; `max_radius` is the largest radius.
    pub fn pairs(
        &mut self,
        particles: &ContactParticles,
        groups: &[ContactGroup],
        max_radius: f32,
        positions: &[Vec3A],
    ) -> Vec<(u32, u32)> {
        let margin = PAIR_MARGIN * max_radius;
        let skin = SKIN * max_radius;
        let listed = self.culling && self.reference.len() == particles.len();
        let moved = if listed {
            self.moved(particles, positions)
        } else {
            Vec::new()
        };
        if !listed || moved.len() as f32 > REBUILD_SHARE * particles.len() as f32 {
            let extra = margin + skin;
            self.build(
                particles,
                groups,
                2.0 * max_radius + extra,
                extra,
                positions,
            );
            // a little under half, so that rounding in the distances cannot lose a
            // pair that closed by exactly the skin
            self.half_skin = 0.5 * skin * (1.0 - 1e-3);
        } else if !moved.is_empty() {
            self.update(particles, groups, &moved, margin + skin, positions);
        }
        let (dense, radius) = (&particles.dense, &particles.radius);
        self.candidates
            .par_iter()
            .with_min_len(PER_TASK)
            .filter_map(|&key| {
                let (a, b) = ((key >> 32) as usize, key as u32 as usize);
                let reach = radius[a] + radius[b] + margin;
                let (xa, xb) = (positions[dense[a] as usize], positions[dense[b] as usize]);
                within(xa, xb, reach).then_some((a as u32, b as u32))
            })
            .collect()
    }

    /// The particles (ascending) that have moved half the skin from their references.
    fn moved(&self, particles: &ContactParticles, positions: &[Vec3A]) -> Vec<u32> {
        let limit = self.half_skin * self.half_skin;
        particles
            .dense
            .par_iter()
            .zip(&self.reference)
            .enumerate()
            .with_min_len(PER_TASK)
            .filter(|(_, (d, x))| {
                let moved = (positions[**d as usize] - **x).length_squared();
                moved.is_nan() || moved > limit
            })
            .map(|(k, _)| k as u32)
            .collect()
    }

    /// Builds the list afresh: every particle's reference is where it is now; the
    /// candidates are the pairs closer than their radii plus `extra`, found in cells of
    /// side `cell` (the largest such distance).
    fn build(
        &mut self,
        particles: &ContactParticles,
        groups: &[ContactGroup],
        cell: f32,
        extra: f32,
        positions: &[Vec3A],
    ) {
        self.reference.clear();
        self.reference
            .extend(particles.dense.iter().map(|d| positions[*d as usize]));
        self.grid = CellGrid::new(&self.reference, particles.kin(groups), cell);
        let found = particles.close_pairs(groups, &self.grid, &self.reference, extra);
        self.candidates.clear();
        self.candidates
            .extend(found.iter().flatten().map(|&(a, b)| pair_key(a, b)));
        self.candidates.par_sort_unstable();
        self.updates.0 += 1;
    }

    /// Takes the `moved` particles' positions as their references and searches their
    /// pairs again (those closer than their radii plus `extra`).
    fn update(
        &mut self,
        particles: &ContactParticles,
        groups: &[ContactGroup],
        moved: &[u32],
        extra: f32,
        positions: &[Vec3A],
    ) {
        let mut flagged = vec![false; particles.len()];
        for &k in moved {
            flagged[k as usize] = true;
            self.reference[k as usize] = positions[particles.dense[k as usize] as usize];
        }
        let entries = self.grid.update(moved, &flagged, &self.reference);
        self.candidates
            .retain(|key| !flagged[(key >> 32) as usize] && !flagged[*key as u32 as usize]);
        let (reference, grid, radius) = (&self.reference, &self.grid, &particles.radius);
        let mut found: Vec<u64> = entries
            .par_chunks(256)
            .flat_map_iter(|chunk| {
                let mut near = Vec::new();
                grid.around_each(chunk, |k, j| {
                    let x = reference[k as usize];
                    // a pair of two moved particles is found from its lower one
                    let once = !flagged[j as usize] || k < j;
                    if once
                        && j != k
                        && within(
                            x,
                            reference[j as usize],
                            radius[k as usize] + radius[j as usize] + extra,
                        )
                        && particles.may_pair(groups, k as usize, j as usize)
                    {
                        near.push(pair_key(k, j));
                    }
                });
                near
            })
            .collect();
        found.par_sort_unstable();
        self.candidates = merge(&self.candidates, &found);
        self.updates.1 += 1;
    }
}

/// A pair's key in the candidate list: the lower index in the high half.
fn pair_key(a: u32, b: u32) -> u64 {
    (a.min(b) as u64) << 32 | a.max(b) as u64
}

/// The union of two ascending, disjoint lists, ascending.
fn merge(a: &[u64], b: &[u64]) -> Vec<u64> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let mut b = b.iter().copied().peekable();
    for &x in a {
        while let Some(y) = b.next_if(|y| *y < x) {
            out.push(y);
        }
        out.push(x);
    }
    out.extend(b);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::terms::contact_pairs::ContactBall;
    use glam::IVec3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `n` particles of radius 0.05 in three groups (the first with self-contact), at
    /// random points of a 1 m box, each at a lattice coordinate far from the others'.
    fn particles(
        n: usize,
        rng: &mut ChaCha8Rng,
    ) -> (ContactParticles, Vec<ContactGroup>, Vec<Vec3A>) {
        let mut p = ContactParticles::default();
        let mut positions = Vec::new();
        for i in 0..n {
            p.push(ContactBall {
                dense: i as u32,
                group: (i % 3) as u32,
                body: i as u32,
                coord: IVec3::new(3 * i as i32, 0, 0),
                rest: Vec3A::ZERO,
                radius: 0.05,
            });
            positions.push(Vec3A::new(rng.random(), rng.random(), rng.random()));
        }
        let group = |self_contact| ContactGroup {
            self_contact,
            static_friction: 0.0,
            dynamic_friction: 0.0,
        };
        (p, vec![group(true), group(false), group(false)], positions)
    }

    #[test]
    fn a_kept_list_gives_exactly_the_pairs_of_a_fresh_search_as_particles_move() {
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (p, groups, mut positions) = particles(3000, &mut rng);
        let (mut kept, mut fresh) = (ContactList::default(), ContactList::default());
        kept.set_culling(true);
        let mut total = 0;
        for substep in 0..60 {
            // most particles drift a little, a few jump, one diverges for a while
            for x in positions.iter_mut() {
                let step = if rng.random_bool(0.02) { 0.2 } else { 0.004 };
                *x += Vec3A::new(rng.random(), rng.random(), rng.random()) * step - step / 2.0;
            }
            positions[7] = if (20..25).contains(&substep) {
                Vec3A::splat(f32::NAN)
            } else {
                Vec3A::splat(0.5)
            };
            let expected = fresh.pairs(&p, &groups, 0.05, &positions);
            assert_eq!(
                kept.pairs(&p, &groups, 0.05, &positions),
                expected,
                "substep {substep}"
            );
            total += expected.len();
        }
        let (built, updated) = kept.updates();
        assert!(total > 10_000, "{total} pairs");
        assert!(
            built < 10 && updated > 40,
            "built {built}, updated {updated}"
        );
        assert_eq!(
            fresh.updates(),
            (60, 0),
            "without culling, a fresh list every substep"
        );
    }

    #[test]
    fn resting_particles_keep_their_list() {
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        let (p, groups, positions) = particles(500, &mut rng);
        let mut list = ContactList::default();
        list.set_culling(true);
        let first = list.pairs(&p, &groups, 0.05, &positions);
        for _ in 0..10 {
            assert_eq!(list.pairs(&p, &groups, 0.05, &positions), first);
        }
        assert_eq!(list.updates(), (1, 0));
        // the pairs come out sorted, each once, lower index first
        assert!(!first.is_empty() && first.windows(2).all(|w| w[0] < w[1]));
        assert!(first.iter().all(|(a, b)| a < b));
    }

    /// Every pair of `p` that may pair and is within reach at `positions`, by brute
    /// force, ascending.
    fn brute_pairs(
        p: &ContactParticles,
        groups: &[ContactGroup],
        positions: &[Vec3A],
    ) -> Vec<(u32, u32)> {
        let margin = PAIR_MARGIN * 0.05;
        let mut out = Vec::new();
        for a in 0..p.len() {
            for b in a + 1..p.len() {
                let reach = p.radius[a] + p.radius[b] + margin;
                if p.may_pair(groups, a, b) && within(positions[a], positions[b], reach) {
                    out.push((a as u32, b as u32));
                }
            }
        }
        out
    }

    #[test]
    fn bodies_in_blobs_give_exactly_the_pairs_of_a_brute_force_search() {
        // eight groups, each a blob of particles around its own centre, the blobs
        // overlapping their neighbours'; groups 0 and 5 with self-contact. Inside a
        // blob most cells hold one group, which the search passes over unless the group
        // may pair with itself
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let (mut p, mut groups, mut positions) = particles(2400, &mut rng);
        for (k, x) in positions.iter_mut().enumerate() {
            let g = k % 8;
            p.group[k] = g as u32;
            let centre = Vec3A::new((g % 4) as f32 * 0.3, (g / 4) as f32 * 0.3, 0.0);
            *x = centre + (*x - 0.5) * 0.4;
        }
        groups = (0..8)
            .map(|g| ContactGroup {
                self_contact: g == 0 || g == 5,
                ..groups[1]
            })
            .collect();
        let mut list = ContactList::default();
        list.set_culling(true);
        let (mut total, mut within_groups) = (0, 0);
        for substep in 0..30 {
            for x in positions.iter_mut() {
                *x += Vec3A::new(rng.random(), rng.random(), rng.random()) * 0.01 - 0.005;
            }
            let expected = brute_pairs(&p, &groups, &positions);
            assert_eq!(
                list.pairs(&p, &groups, 0.05, &positions),
                expected,
                "substep {substep}"
            );
            total += expected.len();
            within_groups += expected
                .iter()
                .filter(|(a, b)| p.group[*a as usize] == p.group[*b as usize])
                .count();
        }
        let (built, updated) = list.updates();
        assert!(
            built >= 1 && updated > 10,
            "built {built}, updated {updated}"
        );
        assert!(within_groups > 1000, "{within_groups} pairs within a group");
        assert!(
            total > 2 * within_groups,
            "{total} pairs, {within_groups} within a group"
        );
    }
}
