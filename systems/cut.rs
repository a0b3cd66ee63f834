//! Stage cut: removes the detected particles from their bodies, splits the
//! particles a `split` blade passes through (spawning their new halves, halving the
//! masses), severs the detected and torn edges, and reports it all with the cut
//! clusters. Writes particle data only (it reads the particle → clusters index to name
//! the cut clusters).
//!
//! A particle entity despawned from outside (by a game, say) is removed the same way,
//! as if cut: its body's lattice and clusters are rebuilt around the hole, instead of
//! listing a particle that no longer exists.
//!
//! Splits that would take a body past its memory budget are not made: their blades
//! sever instead, and a [`SplitsOverBudget`] says so.

use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::cut::carve::carve;
use crate::cut::particle_split::{Pairs, SPLIT_GAP, apply_splits, split_positions};
use crate::cut::tear::sever_keeping_pieces;
use crate::ecs::budget::bytes_after_split;
use crate::ecs::components::{
    AngularVelocity, Body, BodyLattice, InvMass, Orientation, Particle, ParticleClusters, Position,
    Velocity,
};
use crate::ecs::resources::{
    BodyCut, BodyCutReport, BodySplit, CutList, CutReport, EdgesSevered, ParticlesCut,
    ParticlesSplit, SimSettings, SplitsOverBudget,
};
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use glam::Vec3;
use std::borrow::Cow;

/// Particle data the stage reads, and the positions it moves and masses it halves when
/// it splits particles.
type ParticleState = (
    &'static mut Position,
    &'static Velocity,
    &'static Orientation,
    &'static AngularVelocity,
    &'static mut InvMass,
);

/// Deletes the particles of the `CutList` and any particle despawned from outside,
/// splits the `CutList`'s split particles (or, where that would take a body past its
/// memory budget, severs the edges the split would hand to new halves), and severs its
/// edges.
#[allow(clippy::too_many_arguments)]
pub fn cut(
    settings: Res<SimSettings>,
    mut commands: Commands,
    list: Res<CutList>,
    mut report: ResMut<CutReport>,
    mut bodies: Query<(Entity, &Body, &mut BodyLattice, &ParticleClusters)>,
    mut despawned: RemovedComponents<Particle>,
    mut despawned_here: Local<Vec<Entity>>,
    mut messages: CutMessages,
    mut particles: Query<ParticleState>,
) {
    report.bodies.clear();
    let cuts = with_despawned(&list, &mut despawned, &mut despawned_here, &bodies);
    despawned_here.clear();
    for cut in cuts.iter() {
        let Ok((_, material, mut body, index)) = bodies.get_mut(cut.body) else {
            continue;
        };
        let mut removed = Vec::new();
        let mut cut_clusters = Vec::new();
        for &p in &cut.particles {
            if body.lattice.remove(p) {
                removed.push(p);
                let particle = body.particles[p as usize];
                // (one despawned from outside is gone already)
                if let Ok(mut e) = commands.get_entity(particle) {
                    e.despawn();
                    despawned_here.push(particle);
                }
                cut_clusters.extend_from_slice(index.index.clusters_of(p));
            }
        }
        let (splits, mut severed) =
            match over_budget(cut, &body.lattice, settings.0.memory_budget_bytes()) {
                None => split(&mut commands, &mut body, cut, &mut particles),
                Some(over) => {
                    messages.over_budget.write(over);
                    let plan = cut.splits.severing_only(&body.lattice);
                    apply_splits(&mut body.lattice, &plan)
                }
            };
        for &(p, _) in &splits {
            cut_clusters.extend_from_slice(index.index.clusters_of(p));
        }
        severed.extend(
            cut.edges
                .iter()
                .copied()
                .filter(|&(a, b)| body.lattice.sever(a, b)),
        );
        let (carved, relinked) = carve(&mut body.lattice, &cut.carved);
        severed.extend(carved);
        // (an edge between two carved particles lies inside what the tool swept)
        let lattice = &mut body.lattice;
        severed.extend(cut.grazed.iter().copied().filter(|&(a, b)| {
            !(lattice.is_carved(a) && lattice.is_carved(b)) && lattice.sever(a, b)
        }));
        set_crossings(&mut body, cut, &severed, &splits);
        let min_piece = material.material.tear_min_piece as usize;
        let torn = sever_keeping_pieces(&mut body.lattice, &cut.torn, min_piece);
        for &(a, b) in severed.iter().chain(&torn) {
            // only a cluster holding both ends may fall apart
            let of_b = index.index.clusters_of(b);
            cut_clusters.extend(
                index
                    .index
                    .clusters_of(a)
                    .iter()
                    .filter(|k| of_b.contains(k)),
            );
        }
        if removed.is_empty()
            && severed.is_empty()
            && torn.is_empty()
            && splits.is_empty()
            && relinked.is_empty()
        {
            continue;
        }
        cut_clusters.sort_unstable();
        cut_clusters.dedup();
        let before = body.pieces;
        body.pieces = body.lattice.piece_count();
        let report_body = BodyCutReport {
            body: cut.body,
            removed,
            splits,
            relinked,
            severed: [severed, torn.clone()].concat(),
            cut_clusters,
        };
        messages.announce(&report_body, before, body.pieces, &torn);
        report.bodies.push(report_body);
    }
}

/// What the cut stage tells outside code.
#[derive(SystemParam)]
pub struct CutMessages<'w> {
    particles_cut: MessageWriter<'w, ParticlesCut>,
    edges_severed: MessageWriter<'w, EdgesSevered>,
    particles_split: MessageWriter<'w, ParticlesSplit>,
    body_split: MessageWriter<'w, BodySplit>,
    over_budget: MessageWriter<'w, SplitsOverBudget>,
}

impl CutMessages<'_> {
    /// The messages of one body's cut: its pieces (from `before` to `after`), the
    /// particles removed, the edges severed (the tools' and the `torn`), the particles
    /// split.
    fn announce(&mut self, cut: &BodyCutReport, before: usize, after: usize, torn: &[(u32, u32)]) {
        let body = cut.body;
        if after != before {
            self.body_split.write(BodySplit {
                body,
                pieces_before: before,
                pieces_after: after,
            });
        }
        if !cut.removed.is_empty() {
            self.particles_cut.write(ParticlesCut {
                body,
                particles: cut.removed.clone(),
            });
        }
        if !cut.severed.is_empty() {
            let edges = cut.severed[..cut.severed.len() - torn.len()].to_vec();
            self.edges_severed.write(EdgesSevered {
                body,
                edges,
                torn: torn.to_vec(),
            });
        }
        if !cut.splits.is_empty() {
            self.particles_split.write(ParticlesSplit {
                body,
                pairs: cut.splits.clone(),
            });
        }
    }
}

/// Records where the tools crossed the edges they cut (a torn edge has no crossing),
/// and the edges between split particles' halves.
fn set_crossings(body: &mut BodyLattice, cut: &BodyCut, severed: &[(u32, u32)], splits: &Pairs) {
    for &(a, b) in severed {
        if let Some(c) = cut.crossing(a, b) {
            body.lattice.set_crossing(a, b, c);
        }
    }
    for &(p, moves, _) in &cut.splits.splits {
        for d in (0..6).filter(|&d| moves[d]) {
            // (the pairs follow the plan, ascending by particle)
            let q = (splits.binary_search_by_key(&p, |s| s.0).ok())
                .map_or(NO_PARTICLE, |k| body.lattice.link(splits[k].1, d));
            if let Some(c) = cut.crossing(p, q).filter(|_| q != NO_PARTICLE) {
                body.lattice.set_crossing(p, q, c);
            }
        }
    }
}

/// What splitting `cut`'s split particles would take of the body of `lattice`, when it
/// is more than its `budget` (bytes); `None` when they fit, or there are none. Said
/// as a warning too.
fn over_budget(cut: &BodyCut, lattice: &Lattice, budget: u64) -> Option<SplitsOverBudget> {
    if cut.splits.splits.is_empty() {
        return None;
    }
    let bytes = bytes_after_split(lattice, &cut.splits);
    (bytes > budget).then(|| {
        let particles = cut.splits.splits.len();
        tracing::warn!(
            "splitting {particles} particles of {} would take it to about {:.3} GB, past its memory budget of {:.3} GB: its split blades sever this frame",
            cut.body,
            bytes as f64 / 1e9,
            budget as f64 / 1e9
        );
        SplitsOverBudget {
            body: cut.body,
            particles,
            bytes,
            budget,
        }
    })
}

/// Splits the cut's split particles of `body` ([`split_particles`]): puts each half at
/// its rest place on its side of the blade ([`split_positions`], from the positions
/// before the cut) with the particle's velocity, and halves both masses. Returns the
/// `(particle, new half)` pairs and the edges severed between split particles.
fn split(
    commands: &mut Commands,
    body: &mut BodyLattice,
    cut: &BodyCut,
    particles: &mut Query<ParticleState>,
) -> (Pairs, Pairs) {
    if cut.splits.splits.is_empty() && cut.splits.sever.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let (pairs, severed) = apply_splits(&mut body.lattice, &cut.splits);
    let gap = SPLIT_GAP * body.lattice.spacing();
    // (a half split off this frame has no entity yet: its place is not known)
    let position = |p: u32| {
        let entity = *body.particles.get(p as usize)?;
        particles.get(entity).map(|(x, ..)| x.0).ok()
    };
    let placed: Vec<Option<(Vec3, Vec3)>> = pairs
        .iter()
        .map(|&(old, new)| {
            let plane = cut
                .splits
                .splits
                .binary_search_by_key(&old, |(p, ..)| *p)
                .map(|k| cut.splits.splits[k].2)
                .expect("a split particle has its plane");
            let x = position(old)?;
            let taken: Vec<Vec3> = body
                .lattice
                .neighbours(new)
                .filter_map(&position)
                .map(|y| y - x)
                .collect();
            let toward = taken.iter().sum::<Vec3>() / taken.len().max(1) as f32;
            Some(split_positions(x, toward, &plane, gap))
        })
        .collect();
    let owner = cut.body;
    for (&(old, new), placed) in pairs.iter().zip(placed) {
        let (Some((kept, far)), Ok((mut x, v, q, w, mut inv_mass))) =
            (placed, particles.get_mut(body.particles[old as usize]))
        else {
            continue;
        };
        inv_mass.0 *= 2.0;
        // (moved without velocity: a particle's velocity is its own, not its position's)
        x.0 = kept;
        let entity = commands
            .spawn((
                Particle {
                    body: owner,
                    index: new,
                },
                Position(far),
                Velocity(v.0),
                *q,
                *w,
                InvMass(inv_mass.0),
            ))
            .id();
        debug_assert_eq!(body.particles.len(), new as usize);
        body.particles.push(entity);
    }
    (pairs, severed)
}

/// The `CutList`'s cuts plus, per body, its live particles whose entities were despawned
/// from outside (not by this stage last time, `despawned_here`), by body entity.
fn with_despawned<'a>(
    list: &'a CutList,
    despawned: &mut RemovedComponents<Particle>,
    despawned_here: &mut [Entity],
    bodies: &Query<(Entity, &Body, &mut BodyLattice, &ParticleClusters)>,
) -> Cow<'a, [BodyCut]> {
    despawned_here.sort_unstable();
    let mut outside: Vec<Entity> = despawned
        .read()
        .filter(|e| despawned_here.binary_search(e).is_err())
        .collect();
    if outside.is_empty() {
        return Cow::Borrowed(&list.cuts);
    }
    outside.sort_unstable();
    let mut cuts = list.cuts.clone();
    for (body, _, lattice, _) in bodies.iter() {
        let lost: Vec<u32> = lattice
            .lattice
            .live_particles()
            .filter(|&p| {
                outside
                    .binary_search(&lattice.particles[p as usize])
                    .is_ok()
            })
            .collect();
        if lost.is_empty() {
            continue;
        }
        let cut = BodyCut::entry(&mut cuts, body);
        cut.particles.extend(lost);
        cut.particles.sort_unstable();
        cut.particles.dedup();
    }
    cuts.sort_by_key(|c| c.body);
    Cow::Owned(cuts)
}
