//! The contact constraint kind: every particle is a ball, and balls of different bodies,
//! of different pieces of one body, or of one piece folded onto itself do not overlap.
//! Position-based, with Coulomb friction (Macklin et al. 2014, "Unified particle
//! physics for real-time applications", §6–7).
//!
//! Who takes part and how pairs are found: [`super::contact_pairs`]; how the pairs are
//! kept across substeps: [`super::contact_list`].
//!
//! **Projection (every iteration).** Jacobi-style, reading only positions: each pair,
//! once, computes the correction along its normal (the overlap) and against its slip
//! (friction), divided by the larger number of touching pairs of its two particles
//! (counted in the previous iteration, over a relaxation factor), and splits it by
//! inverse mass; then each particle sums its pairs' moves in a fixed order, and the sums
//! are applied. So the result does not depend on the thread count, and each pair's
//! pushes on its two particles are equal and opposite — momentum is kept even where
//! overlaps persist (an average per particle would not keep it, and a persistent overlap
//! would then accelerate the bodies).

use super::contact_list::ContactList;
use super::contact_pairs::{ContactBall, ContactGroup, ContactParticles};
use crate::body::lattice::Lattice;
use crate::config::Material;
use crate::solver::disjoint::Disjoint;
use crate::solver::term::{NO_DENSE, ParticleState, Substep, Term, TermExtent, Topology};
use glam::{Vec3A, Vec4};
use rayon::prelude::*;

/// Particles with pairs per parallel task of the projection.
const OWNERS_PER_TASK: usize = 512;

/// Pairs per parallel task of the projection.
const PAIRS_PER_TASK: usize = 512;

/// Over-relaxation of the pair corrections (as in Macklin et al. 2014, §4.2.2): a pair's
/// correction is divided by the larger load of its particles over this factor (at least
/// by 1), so that particles in a few contacts converge in fewer iterations.
pub const RELAXATION: f32 = 2.0;

/// The radius of particle `i`'s ball: the material's contact radius; for a half of a
/// split particle, less how far it rests from its cell's centre (see
/// [`Lattice::split`]), so that its ball lies inside the ball of the particle it was
/// split from (and no smaller than a quarter of it). Then a split overlaps no ball
/// that the particle did not overlap: nothing pushes the pieces apart, and a half at
/// the bottom of a block on the ground rests on it with its ball, as the particle did.
/// Halves of one cell rest closer to each other than their balls reach; contacts
/// between particles of one body stop at their rest distance
/// ([`super::contact_pairs::ContactParticles`]).
pub fn ball_radius(material: &Material, lattice: &Lattice, i: u32) -> f32 {
    let radius = material.contact_radius_at(lattice.spacing());
    let shift = lattice.split_shift(i).length() * lattice.spacing();
    (radius - shift).max(0.25 * radius)
}

/// A pair as the projection reads it: everything it needs in one place.
#[derive(Clone, Copy, Debug, Default)]
struct Pair {
    /// Contact indices of the two particles, `a < b`.
    a: u32,
    b: u32,
    /// Their dense particle indices.
    dense_a: u32,
    dense_b: u32,
    /// Sum of the two radii.
    reach: f32,
    /// Mean static and dynamic friction of the two groups.
    static_friction: f32,
    dynamic_friction: f32,
    /// Where its moves of `a` and of `b` go in [`Contacts::moves`].
    slots: [u32; 2],
}

/// The contact kind: its particles, its groups, and this substep's pairs.
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    /// Whether particles collide at all (the simulation's `contacts` setting).
    enabled: bool,
    particles: ContactParticles,
    groups: Vec<ContactGroup>,
    /// Largest radius.
    max_radius: f32,
    /// The candidate pairs kept across substeps.
    list: ContactList,
    /// This substep's pairs, each once, ascending by their contact indices.
    pairs: Vec<Pair>,
    /// The particles in pairs (contact indices, ascending): `owners[o]`'s pairs' moves
    /// of it are `moves[starts[o]..starts[o + 1]]`, in the order of the pairs.
    owners: Vec<u32>,
    starts: Vec<u32>,
    /// The current iteration's move of each pair's two particles, grouped by particle
    /// (each pair's [`Pair::slots`]): `xyz` the move (zero when apart), `w` 1 where the
    /// pair touched (moved either particle), else 0. So each particle sums its moves in
    /// sequence.
    moves: Vec<Vec4>,
    /// Per contact particle, how many of its pairs touched in the last iteration (its
    /// pair count before the first): a pair's correction is divided by the larger load
    /// of its two particles, so that both sides move by equal and opposite amounts
    /// (momentum kept, pair by pair) while a particle in many contacts does not
    /// overshoot.
    load: Vec<u32>,
}

impl Contacts {
    /// Replaces the taking-part particles and the groups they name.
    pub fn set(&mut self, particles: ContactParticles, groups: Vec<ContactGroup>) {
        self.max_radius = particles.radius.iter().copied().fold(0.0, f32::max);
        self.particles = particles;
        self.groups = groups;
        self.list.clear();
        self.pairs.clear();
        self.owners.clear();
        self.starts.clear();
        self.moves.clear();
    }

    /// Turns conservative culling of the pairs on or off (the simulation's `culling`
    /// setting; the pairs are the same either way, see [`super::contact_list`]).
    pub fn set_culling(&mut self, culling: bool) {
        self.list.set_culling(culling);
    }

    /// Turns contacts on or off (the simulation's `contacts` setting); returns whether
    /// that changed anything (the particles are then chosen again at the next topology
    /// change).
    pub fn set_enabled(&mut self, enabled: bool) -> bool {
        std::mem::replace(&mut self.enabled, enabled) != enabled
    }

    /// The surface particles of `change`'s bodies, each labelled with its piece (a group
    /// per piece of each body), in dense order within each body.
    fn surface(change: &Topology) -> (ContactParticles, Vec<ContactGroup>) {
        let (mut particles, mut groups) = (ContactParticles::default(), Vec::new());
        for (b, body) in change.bodies.iter().enumerate() {
            let (lattice, material) = (body.lattice, body.material);
            let group = ContactGroup {
                self_contact: material.self_contact,
                static_friction: material.static_friction,
                dynamic_friction: material.dynamic_friction,
            };
            let first_group = groups.len() as u32;
            // labels only where the body is in more than one piece
            let labels = (body.pieces > 1).then(|| lattice.pieces());
            let pieces = labels.map_or(1, |l| l.count).max(1);
            groups.extend(std::iter::repeat_n(group, pieces));
            let mut taking_part: Vec<(u32, u32)> = lattice
                .live_particles()
                .filter(|i| lattice.is_surface(*i))
                .filter_map(|i| {
                    let d = *body.dense.get(i as usize)?;
                    (d != NO_DENSE).then_some((d, i))
                })
                .collect();
            taking_part.sort_unstable();
            for (d, i) in taking_part {
                let piece = labels.map_or(0, |l| l.label[i as usize]);
                particles.push(ContactBall {
                    dense: d,
                    group: first_group + piece,
                    body: b as u32,
                    coord: lattice.coord(i),
                    rest: lattice.rest_position(i).into(),
                    radius: ball_radius(material, lattice, i),
                });
            }
        }
        (particles, groups)
    }

    /// Number of pairs found in the current substep (each pair counted from both sides).
    pub fn pair_count(&self) -> usize {
        2 * self.pairs.len()
    }

    /// Number of taking-part particles.
    pub fn particle_count(&self) -> usize {
        self.particles.len()
    }

    /// Finds this substep's pairs from `positions` (see the module docs).
    fn find_pairs(&mut self, positions: &[Vec3A]) {
        let found = self
            .list
            .pairs(&self.particles, &self.groups, self.max_radius, positions);
        let p = &self.particles;
        // then listed under both their particles (a counting sort: the pairs of a
        // particle keep the pairs' order, fixed for any thread count)
        let n = p.len();
        self.pairs.clear();
        self.pairs.extend(found.iter().map(|&(a, b)| {
            let (ga, gb) = (
                self.groups[p.group[a as usize] as usize],
                self.groups[p.group[b as usize] as usize],
            );
            Pair {
                a,
                b,
                dense_a: p.dense[a as usize],
                dense_b: p.dense[b as usize],
                reach: p.reach(a as usize, b as usize),
                static_friction: 0.5 * (ga.static_friction + gb.static_friction),
                dynamic_friction: 0.5 * (ga.dynamic_friction + gb.dynamic_friction),
                slots: [0; 2],
            }
        }));
        // each particle's pair count is also its load before the first iteration
        self.load.clear();
        self.load.resize(n, 0);
        for pair in &self.pairs {
            self.load[pair.a as usize] += 1;
            self.load[pair.b as usize] += 1;
        }
        self.owners.clear();
        self.starts.clear();
        self.starts.push(0);
        let mut slot = vec![0u32; n];
        let mut total = 0u32;
        for (k, c) in self.load.iter().enumerate() {
            if *c > 0 {
                slot[k] = total;
                total += c;
                self.owners.push(k as u32);
                self.starts.push(total);
            }
        }
        for pair in &mut self.pairs {
            for (side, owner) in [pair.a, pair.b].into_iter().enumerate() {
                let at = &mut slot[owner as usize];
                pair.slots[side] = *at;
                *at += 1;
            }
        }
        self.moves.resize(total as usize, Vec4::ZERO);
    }
}

impl Term for Contacts {
    fn name(&self) -> &'static str {
        "contacts"
    }

    fn is_empty(&self) -> bool {
        self.particles.is_empty()
    }

    /// The taking-part particles and the pairs found in the last substep (each counted
    /// from both sides).
    fn extent(&self) -> TermExtent {
        TermExtent {
            particles: self.particle_count(),
            constraints: self.pair_count(),
        }
    }

    /// Takes the surface particles of every body again, each labelled with its piece —
    /// none when no pair can form: a lone piece without self-contact meets nothing.
    fn topology(&mut self, change: &Topology) {
        let lone = match change.bodies {
            [body] => body.pieces <= 1 && !body.material.self_contact,
            _ => false,
        };
        let (particles, groups) = if self.enabled && !lone {
            Self::surface(change)
        } else {
            Default::default()
        };
        self.set(particles, groups);
    }

    fn begin_substep(&mut self, _step: &Substep, state: &mut ParticleState) {
        self.find_pairs(state.positions);
    }

    fn project(&mut self, _step: &Substep, state: &mut ParticleState) {
        if self.pairs.is_empty() {
            return;
        }
        let (positions, previous, inv_mass) = (&*state.positions, state.previous, state.inv_mass);
        let load = &self.load;
        // each pair once: its moves of a and of b, equal and opposite up to the shares,
        // each into its particle's slot (a pair's two slots are its own)
        let slots = Disjoint::new(&mut self.moves);
        self.pairs
            .par_iter()
            .with_min_len(PAIRS_PER_TASK)
            .for_each(|pair| {
                let moves = pair_moves(pair, positions, previous, inv_mass, load);
                let touched = if moves == [Vec3A::ZERO; 2] { 0.0 } else { 1.0 };
                for (slot, step) in pair.slots.into_iter().zip(moves) {
                    // SAFETY: each slot is one pair's for one particle (a counting sort
                    // in `find_pairs`), in bounds of the moves.
                    unsafe { slots.write(slot as usize, step.extend(touched)) };
                }
            });
        // then each particle sums its moves and takes the sum: a task reads only the
        // moves, and owners are distinct contact particles of distinct dense indices,
        // so no two tasks write one entry
        let (starts, moves) = (&self.starts, &self.moves);
        let dense = &self.particles.dense;
        let shifts = state.disjoint_shifts();
        let load = Disjoint::new(&mut self.load);
        self.owners
            .par_iter()
            .enumerate()
            .with_min_len(OWNERS_PER_TASK)
            .for_each(|(o, &a)| {
                let sum = moves[starts[o] as usize..starts[o + 1] as usize]
                    .iter()
                    .fold(Vec4::ZERO, |sum, m| sum + *m);
                let step = Vec3A::from_vec4(sum);
                // SAFETY: `a` is this task's own owner (see above), in bounds of the
                // contact arrays, and its dense index is in bounds of the particles'.
                unsafe {
                    load.write(a as usize, sum.w as u32);
                    if step != Vec3A::ZERO {
                        shifts.shift(dense[a as usize] as usize, step);
                    }
                }
            });
    }
}

/// A pair's moves of its particles `a` and `b` in one iteration: its overlap at
/// `positions` undone along its normal and its slip since `previous` against friction,
/// shared by inverse mass and divided by the larger `load` of the two (over
/// [`RELAXATION`]); zero when apart or both pinned.
#[inline]
fn pair_moves(
    pair: &Pair,
    positions: &[Vec3A],
    previous: &[Vec3A],
    inv_mass: &[f32],
    load: &[u32],
) -> [Vec3A; 2] {
    let (da, db) = (pair.dense_a as usize, pair.dense_b as usize);
    let apart = positions[da] - positions[db];
    let distance_squared = apart.length_squared();
    let (wa, wb) = (inv_mass[da], inv_mass[db]);
    if distance_squared >= pair.reach * pair.reach || wa + wb == 0.0 {
        return [Vec3A::ZERO; 2];
    }
    let distance = distance_squared.sqrt();
    // coincident centres: a (the lower contact index) goes up, b down
    let normal = if distance > 0.0 {
        apart / distance
    } else {
        Vec3A::Y
    };
    let depth = pair.reach - distance;
    let mut step = normal * depth;
    // friction against the slip of a relative to b in this substep
    let slip = (positions[da] - previous[da]) - (positions[db] - previous[db]);
    let tangential = slip - normal * slip.dot(normal);
    let length = tangential.length();
    if length <= pair.static_friction * depth {
        step -= tangential;
    } else {
        step -= tangential * (pair.dynamic_friction * depth / length).min(1.0);
    }
    let divide = (load[pair.a as usize].max(load[pair.b as usize]) as f32 / RELAXATION).max(1.0);
    let scale = 1.0 / ((wa + wb) * divide);
    [step * (wa * scale), step * (-wb * scale)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solver::testing::step;
    use glam::IVec3;

    const FREE: ContactGroup = ContactGroup {
        self_contact: true,
        static_friction: 0.0,
        dynamic_friction: 0.0,
    };

    /// A ball of radius 0.05 alone in its body.
    fn ball(dense: u32, group: u32, coord: IVec3) -> ContactBall {
        ContactBall {
            dense,
            group,
            body: dense,
            coord,
            rest: Vec3A::ZERO,
            radius: 0.05,
        }
    }

    /// Contacts over `positions`, particle `i` in group `groups[i]` at lattice coordinate
    /// `coords[i]`, all of radius 0.05.
    fn contacts(groups: &[u32], coords: &[IVec3]) -> Contacts {
        let mut particles = ContactParticles::default();
        for (i, (g, c)) in groups.iter().zip(coords).enumerate() {
            particles.push(ball(i as u32, *g, *c));
        }
        let count = groups.iter().max().map_or(0, |g| *g as usize + 1);
        let mut c = Contacts::default();
        c.set(particles, vec![FREE; count]);
        c
    }

    fn solve(c: &mut Contacts, positions: &mut [Vec3A], iterations: usize) -> Vec<Vec3A> {
        let previous = positions.to_vec();
        let inv_mass = vec![1.0; positions.len()];
        let mut corrections = vec![Vec3A::ZERO; positions.len()];
        let mut state = ParticleState {
            positions,
            previous: &previous,
            inv_mass: &inv_mass,
            corrections: &mut corrections,
            orientations: &mut vec![glam::Quat::IDENTITY; previous.len()],
            spins: &vec![Vec3A::ZERO; previous.len()],
        };
        c.begin_substep(&step(1), &mut state);
        for _ in 0..iterations {
            c.project(&step(1), &mut state);
        }
        corrections
    }

    /// All pairs closer than `reach` that may pair, by brute force.
    fn brute_pairs(c: &Contacts, positions: &[Vec3A], reach: f32) -> Vec<(u32, u32)> {
        let n = positions.len();
        let mut out = vec![];
        for a in 0..n {
            for b in 0..n {
                if c.particles.may_pair(&c.groups, a, b)
                    && (positions[a] - positions[b]).length() < reach
                {
                    out.push((a as u32, b as u32));
                }
            }
        }
        out
    }

    #[test]
    fn the_sorted_cells_find_exactly_the_pairs_of_a_brute_force_search() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let n = 3000;
        let positions: Vec<Vec3A> = (0..n)
            .map(|_| {
                Vec3A::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-1.0..1.0),
                )
            })
            .collect();
        let groups: Vec<u32> = (0..n).map(|i| (i % 3) as u32).collect();
        let coords: Vec<IVec3> = positions.iter().map(|p| (*p * 10.0).as_ivec3()).collect();
        let mut c = contacts(&groups, &coords);
        c.find_pairs(&positions);
        let mut found = vec![];
        for pair in &c.pairs {
            found.push((pair.a, pair.b));
            found.push((pair.b, pair.a));
        }
        found.sort_unstable();
        // radii 0.05 and the margin half a radius
        let expected = brute_pairs(&c, &positions, 0.125);
        assert!(expected.len() > 1000, "{}", expected.len());
        let missing: Vec<_> = expected
            .iter()
            .filter(|p| found.binary_search(p).is_err())
            .collect();
        let extra: Vec<_> = found
            .iter()
            .filter(|p| expected.binary_search(p).is_err())
            .collect();
        assert!(
            missing.is_empty() && extra.is_empty(),
            "missing {missing:?}, extra {extra:?}"
        );
    }

    #[test]
    fn overlapping_balls_of_two_groups_end_apart_with_momentum_kept() {
        // two stacks of balls pushed 40 % into each other along x
        let mut positions = vec![];
        let (mut groups, mut coords) = (vec![], vec![]);
        for (g, x0) in [(0u32, 0.0f32), (1, 0.06)] {
            for j in 0..4 {
                positions.push(Vec3A::new(x0, j as f32 * 0.1, 0.0));
                groups.push(g);
                coords.push(IVec3::new(0, j, 0));
            }
        }
        let mut c = contacts(&groups, &coords);
        let before: Vec3A = positions.iter().sum();
        solve(&mut c, &mut positions, 20);
        let after: Vec3A = positions.iter().sum();
        assert!(
            (after - before).length() < 1e-5,
            "momentum {before} → {after}"
        );
        for j in 0..4 {
            let gap = (positions[j] - positions[4 + j]).length();
            assert!(gap > 0.099, "pair {j}: {gap}");
        }
    }

    #[test]
    fn neighbours_in_one_piece_are_not_pairs_but_a_fold_is() {
        // particles 0 and 1 of one piece, lattice neighbours pressed together; 0 and 2
        // far apart in the lattice (a fold) equally close
        let positions = vec![
            Vec3A::ZERO,
            Vec3A::new(0.05, 0.0, 0.0),
            Vec3A::new(0.0, 0.05, 0.0),
        ];
        let coords = [IVec3::ZERO, IVec3::X, IVec3::new(0, 9, 0)];
        let mut c = contacts(&[0, 0, 0], &coords);
        c.find_pairs(&positions);
        assert!(!c.particles.may_pair(&c.groups, 0, 1) && c.particles.may_pair(&c.groups, 0, 2));
        assert_eq!(c.pair_count(), 4, "0–2 and 1–2, from both sides");
        // without self-contact, none
        c.groups[0].self_contact = false;
        c.find_pairs(&positions);
        assert_eq!(c.pair_count(), 0);
    }

    #[test]
    fn static_friction_holds_a_slow_slide_and_dynamic_friction_slows_a_fast_one() {
        // ball 1 comes down onto ball 0 (pinned), ending 0.09 above it and `slide` aside
        let slid = |slide: f32, group: ContactGroup| {
            let mut particles = ContactParticles::default();
            particles.push(ball(0, 0, IVec3::ZERO));
            particles.push(ball(1, 1, IVec3::ZERO));
            let mut c = Contacts::default();
            c.set(particles, vec![group; 2]);
            let previous = [Vec3A::ZERO, Vec3A::new(0.0, 0.1, 0.0)];
            let mut positions = [Vec3A::ZERO, Vec3A::new(slide, 0.09, 0.0)];
            let mut corrections = [Vec3A::ZERO; 2];
            let mut state = ParticleState {
                positions: &mut positions,
                previous: &previous,
                inv_mass: &[0.0, 1.0],
                corrections: &mut corrections,
                orientations: &mut [glam::Quat::IDENTITY; 2],
                spins: &[Vec3A::ZERO; 2],
            };
            c.begin_substep(&step(1), &mut state);
            c.project(&step(1), &mut state);
            assert_eq!(positions[0], Vec3A::ZERO, "a pinned ball never moves");
            positions[1].x
        };
        let grip = ContactGroup {
            self_contact: false,
            static_friction: 1.0,
            dynamic_friction: 0.5,
        };
        // slide 0.005 at depth ≈ 0.0099: inside the static cone, the slide is undone
        // (up to the trace of x that the tilted normal's push leaves)
        let held = slid(0.005, grip);
        assert!(
            held.abs() < 1e-4 && slid(0.005, FREE) > 0.005,
            "static: {held}"
        );
        // slide 0.03 at depth ≈ 0.005: outside the cone, shortened by 0.5 × depth
        let (free, slowed) = (slid(0.03, FREE), slid(0.03, grip));
        let lost = free - slowed;
        assert!(lost > 0.0015 && lost < 0.0035, "dynamic: {free} → {slowed}");
    }

    #[test]
    fn pairs_do_not_depend_on_the_thread_count() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let n = 5000;
        let start: Vec<Vec3A> = (0..n)
            .map(|_| Vec3A::new(rng.random(), rng.random(), rng.random()) * 1.2)
            .collect();
        let groups: Vec<u32> = (0..n).map(|i| (i % 7) as u32).collect();
        let coords: Vec<IVec3> = (0..n).map(|i| IVec3::new(i, 0, 0)).collect();
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            pool.install(|| {
                let mut c = contacts(&groups, &coords);
                let mut positions = start.clone();
                solve(&mut c, &mut positions, 5);
                positions
            })
        };
        let bits = |v: Vec<Vec3A>| -> Vec<[u32; 3]> {
            v.iter().map(|x| x.to_array().map(f32::to_bits)).collect()
        };
        assert_eq!(bits(run(1)), bits(run(2)));
    }
}
