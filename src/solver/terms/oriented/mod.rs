//! Oriented particles (SPEC §5; Müller & Chentanez 2011): the elasticity of bodies of
//! the oriented model ([`crate::config::Model::Oriented`]).
//!
//! Every live particle outside the explicit groups centres one implicit group — itself
//! and its live linked neighbours — and every connected piece of an explicit group is a
//! group ([`groups`]). Each iteration fits every group by generalised shape matching
//! ([`fit::fit`]), moves each member toward its goal `c + R r̄ⱼ`, and gives the rotation to
//! the group's centre (implicit) or to all its oriented members (explicit: a rigid
//! part); a particle of inverse mass 0 is neither moved nor turned, so a pinned root
//! holds its orientation too. Groups follow the lattice: a cut or a tear changes the
//! groups of the particles it touched, and the derived tables are built again once per
//! topology change.
//!
//! ## Compliance
//!
//! A group of material compliance `1/E` (the particle's: its material's, or a stiffness
//! region's; an explicit group's own) stores `(κ/2) Σⱼ |xⱼ − gⱼ|²/nⱼ` with
//! `κ = E h³/σ²` (σ² the per-axis spread of its rest offsets, `nⱼ` the number of groups
//! holding member `j`), the cluster model's form ([`crate::config::Material::compliance`]),
//! so one material is about as stiff in both. Each membership is a constraint
//! `C = xⱼ − gⱼ` of compliance `α = nⱼ/κ`, projected XPBD-style with its `λ` accumulated
//! over the substep (the goal held, as shape matching does); compliance 0 puts the
//! members on their goals.
//!
//! ## Schemes
//!
//! Under Jacobi and Gauss–Seidel the groups are swept Gauss–Seidel style, as the note
//! does, colour by colour (the groups of one colour in parallel, deterministically); the
//! solver mode chooses how the clusters are solved, and a body of the oriented model
//! has none. The implicit groups are swept eight at a time, one per SIMD lane
//! ([`batched`]); the explicit ones, few and large, one by one. Under projective dynamics every membership is a term in the global matrix
//! (the `projective` module), its projection the fitted goal.

pub mod batched;
pub mod fit;
pub mod groups;
pub mod plastic;
mod projective;

use crate::solver::disjoint::Disjoint;
use crate::solver::term::{NO_DENSE, ParticleState, ProjectiveTerm, Substep, Term, Topology};
use batched::Targets;
use fit::fit;
use glam::{Quat, Vec3A};
use groups::{BodyGroups, Group, Turns};
use rayon::prelude::*;

/// Groups per parallel task.
const GROUPS_PER_TASK: usize = 256;

/// The oriented-particle term; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Oriented {
    /// By body id.
    bodies: Vec<BodyGroups>,
    /// Changes whenever the groups do (for projective dynamics' matrix).
    version: u64,
    /// Each dense particle's total move by the groups in the current substep; the next
    /// substep starts from its prediction plus [`WARM_START`] of it.
    moved: Vec<Vec3A>,
    /// The time step `moved` was made with (a change drops it).
    moved_dt: f32,
    /// A saved state to take up at the next topology change.
    resumed: Option<SavedGroups>,
}

/// What a saved simulation keeps of the term: its warm start, and the rest shapes of
/// plastic bodies' groups (everything else is taken again from the lattices).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
struct SavedGroups {
    /// Each dense particle's move by the groups in the last substep.
    moved: Vec<Vec3A>,
    /// That substep's time step.
    dt: f32,
    /// The rest positions of every plastic body's memberships, body after body.
    plastic_rest: Vec<Vec3A>,
}

/// How far past its goal a sweep moves each member (successive over-relaxation, below
/// 2 to converge). A group straightens its members against their neighbours' groups,
/// which straighten them back a little: bending settles only by diffusion along a
/// body, slowly with the few sweeps a frame affords, and over-relaxing the sweeps
/// speeds that up severalfold. It leaves the sweeps' fixed point, the solution, as it
/// is, and keeps every group's weighted centroid where the unrelaxed move would.
pub const OVER_RELAXATION: f32 = 1.6;

/// The share of its last substep's move by the groups a particle starts a substep with
/// (under Jacobi and Gauss–Seidel). At a static equilibrium every substep makes the
/// same move, so the iterations start near their solution and a clamped rod holds its
/// shape instead of sagging until unconverged sweeps happen to balance gravity.
pub const WARM_START: f32 = 0.45;

impl Oriented {
    /// Number of groups.
    pub fn group_count(&self) -> usize {
        self.bodies.iter().map(|b| b.groups.len()).sum()
    }

    /// Number of memberships (the sum of the groups' sizes).
    pub fn membership_count(&self) -> usize {
        self.bodies.iter().map(|b| b.members.len()).sum()
    }

    /// Every group of the body `id` as its dense members, in the term's order.
    pub fn groups_of(&self, id: u64) -> Vec<Vec<u32>> {
        self.bodies
            .iter()
            .filter(|b| b.id == id)
            .flat_map(|b| b.groups.iter().map(|g| b.members[b.range(g)].to_vec()))
            .collect()
    }
}

/// The warm start of group `g`'s rotation: the orientation it gave last (its centre's,
/// or its first oriented member's).
fn warm(body: &BodyGroups, g: &Group, orientation: impl Fn(usize) -> Quat) -> Quat {
    match g.turns {
        Turns::Centre(c) if c != NO_DENSE => orientation(c as usize),
        _ => body
            .range(g)
            .find(|&k| body.moment[k] != Vec3A::ZERO)
            .map_or(Quat::IDENTITY, |k| orientation(body.members[k] as usize)),
    }
}

/// The arrays a sweep of explicit groups writes; the groups of one colour write
/// disjoint entries.
#[derive(Clone, Copy)]
struct Sweep<'a> {
    targets: Targets<'a>,
    lambda: Disjoint<Vec3A>,
}

impl Sweep<'_> {
    /// Fits group `g` of `body` and moves and turns its members (see the module docs).
    ///
    /// # Safety
    /// No other task may touch `g`'s members or memberships while this runs.
    unsafe fn project(&self, body: &BodyGroups, g: &Group) {
        let t = &self.targets;
        let range = body.range(g);
        let members = &body.members[range.clone()];
        // SAFETY: the caller's: this task alone touches these entries
        let (position, orientation) = unsafe {
            (
                |d: usize| t.positions.read(d),
                |d: usize| t.orientations.read(d),
            )
        };
        let f = fit(
            members,
            &body.rest[range.clone()],
            &body.moment[range.clone()],
            |d| t.inv_mass[d],
            position,
            orientation,
            warm(body, g, orientation),
        );
        for k in range {
            let d = body.members[k] as usize;
            let w = t.inv_mass[d];
            if w == 0.0 {
                continue;
            }
            let alpha = body.compliance[k] * t.inv_dt2;
            // SAFETY: as above
            unsafe {
                let lambda = self.lambda.read(k);
                let c = t.positions.read(d) - f.goal(body.rest[k]);
                let delta = (-c - lambda * alpha) / (w + alpha) * t.over_relaxation;
                self.lambda.write(k, lambda + delta);
                t.positions.write(d, t.positions.read(d) + delta * w);
                t.corrections.write(d, t.corrections.read(d) + delta * w);
                t.moved.write(d, t.moved.read(d) + delta * w);
                let turns = match g.turns {
                    Turns::Centre(c) => c as usize == d,
                    Turns::All => body.moment[k] != Vec3A::ZERO,
                };
                if turns {
                    t.orientations.write(d, f.rotation);
                }
            }
        }
    }
}

impl Term for Oriented {
    fn name(&self) -> &'static str {
        "oriented"
    }

    fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// The groups' memberships (a particle in two groups counts twice).
    fn extent(&self) -> crate::solver::term::TermExtent {
        crate::solver::term::TermExtent {
            particles: 0,
            constraints: self.membership_count(),
        }
    }

    fn saved_state(&self) -> Option<Vec<u8>> {
        let saved = SavedGroups {
            moved: self.moved.clone(),
            dt: self.moved_dt,
            plastic_rest: self
                .bodies
                .iter()
                .filter(|b| b.plastic.is_some())
                .flat_map(|b| b.rest.iter().copied())
                .collect(),
        };
        postcard::to_stdvec(&saved).ok()
    }

    /// (a warm start whose length does not fit the layout is dropped at the next
    /// substep, as after a change of time step)
    fn resume_state(&mut self, state: &[u8]) -> Result<(), String> {
        let saved: SavedGroups = postcard::from_bytes(state).map_err(|e| e.to_string())?;
        let finite = |v: &[Vec3A]| v.iter().all(|x| x.is_finite());
        if !(finite(&saved.moved) && finite(&saved.plastic_rest) && saved.dt.is_finite()) {
            return Err("a warm start or plastic rest place is not finite".into());
        }
        self.resumed = Some(saved);
        Ok(())
    }

    /// Builds the groups of every body that changed (all, after a rebuild) from its
    /// lattice again; forgets the bodies that are gone.
    fn topology(&mut self, change: &Topology) {
        let kept = std::mem::take(&mut self.bodies);
        self.bodies = change.rebuild_bodies_from(
            kept,
            |b| b.id,
            |body, old| {
                let mut groups = BodyGroups::build(body)?;
                if let Some(old) = old {
                    groups.keep_dents(&old);
                }
                Some(groups)
            },
        );
        self.version += 1;
        // (dense indices and groups changed: the last moves no longer fit, unless they
        // were saved with this very layout)
        let saved = self.resumed.take().unwrap_or_default();
        (self.moved, self.moved_dt) = (saved.moved, saved.dt);
        let mut rest = saved.plastic_rest.into_iter();
        for body in self.bodies.iter_mut().filter(|b| b.plastic.is_some()) {
            for r in &mut body.rest {
                *r = rest.next().unwrap_or(*r);
            }
            body.batches.refresh_rest(&body.rest);
        }
    }

    fn begin_substep(&mut self, step: &Substep, state: &mut ParticleState) {
        for body in &mut self.bodies {
            body.lambda.iter_mut().for_each(|l| *l = Vec3A::ZERO);
            body.batches.begin_substep();
            if plastic::creep(body, state.previous, state.orientations, step.dt) {
                body.batches.refresh_rest(&body.rest);
            }
        }
        let n = state.positions.len();
        if self.moved_dt != step.dt || self.moved.len() != n {
            self.moved_dt = step.dt;
            self.moved.clear();
            self.moved.resize(n, Vec3A::ZERO);
        }
        for body in &self.bodies {
            predict_rigid_parts(body, state, step.dt);
        }
        for (d, moved) in self.moved.iter_mut().enumerate() {
            let carry = *moved * WARM_START;
            *moved = Vec3A::ZERO;
            if state.inv_mass[d] > 0.0 && carry.is_finite() && carry != Vec3A::ZERO {
                state.shift(d, carry);
                *moved = carry;
            }
        }
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        let (positions, corrections, orientations) = (
            Disjoint::new(state.positions),
            Disjoint::new(state.corrections),
            Disjoint::new(state.orientations),
        );
        let targets = Targets {
            positions,
            corrections,
            orientations,
            moved: Disjoint::new(&mut self.moved),
            inv_mass: state.inv_mass,
            inv_dt2: 1.0 / (step.dt * step.dt),
            over_relaxation: OVER_RELAXATION,
        };
        for body in &mut self.bodies {
            let sweep = Sweep {
                targets,
                lambda: Disjoint::new(&mut body.lambda),
            };
            // (the batches' λ is written while the groups are read)
            let mut batches = std::mem::take(&mut body.batches);
            let groups_of = &*body;
            for (c, colour) in groups_of.colours.iter().enumerate() {
                if batches.has_colour(c) {
                    // SAFETY: the groups of one colour share no particle, and the
                    // batches' lanes are groups
                    unsafe { batches.sweep_colour(c, &targets) };
                    continue;
                }
                let groups = &groups_of.groups[colour[0] as usize..colour[1] as usize];
                groups.par_chunks(GROUPS_PER_TASK).for_each(|chunk| {
                    for g in chunk {
                        // SAFETY: the groups of one colour share no particle, and each
                        // group's memberships are its own (see `groups`)
                        unsafe { sweep.project(groups_of, g) };
                    }
                });
            }
            body.batches = batches;
        }
    }

    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        Some(self)
    }
}

/// Moves the predictions of every explicit group's oriented, moving members along the
/// group's rigid motion: turned about the group's weighted centroid by its spin (its
/// members' mean) instead of along straight lines. A straight-line prediction cuts the
/// arc: a part turning by `θ = ω dt` per substep is fitted turned by `atan θ`, so it
/// would lose `θ²/3` of its spin every substep (a wheel at 2 rev/s over a tenth of its
/// spin in ten turns); a particle's orientation, predicted by the exact turn, carries the
/// spin instead. The moves count as corrections, so velocities follow the arc.
fn predict_rigid_parts(body: &BodyGroups, state: &mut ParticleState, dt: f32) {
    for g in body.groups.iter().filter(|g| g.turns == Turns::All) {
        let range = body.range(g);
        let members = &body.members[range.clone()];
        let oriented = || {
            range
                .clone()
                .filter(|&k| body.moment[k] != Vec3A::ZERO)
                .map(|k| body.members[k] as usize)
        };
        let count = oriented().count();
        if count == 0 {
            continue;
        }
        let spin = oriented().map(|d| state.spins[d]).sum::<Vec3A>() / count as f32;
        if spin == Vec3A::ZERO || !spin.is_finite() {
            continue;
        }
        let kinematic = fit::kinematic_weight(members, |d| state.inv_mass[d]);
        let (mut before, mut after, mut total) = (Vec3A::ZERO, Vec3A::ZERO, 0.0f32);
        let origin = (
            state.previous[members[0] as usize],
            state.positions[members[0] as usize],
        );
        for &m in members {
            let m = m as usize;
            let w = fit::weight(state.inv_mass[m], kinematic);
            before += (state.previous[m] - origin.0) * w;
            after += (state.positions[m] - origin.1) * w;
            total += w;
        }
        let (before, after) = (origin.0 + before / total, origin.1 + after / total);
        let turn = Quat::from_scaled_axis((spin * dt).into());
        for d in oriented() {
            if state.inv_mass[d] == 0.0 {
                continue;
            }
            let target = after + turn * (state.previous[d] - before);
            let step = target - state.positions[d];
            state.shift(d, step);
        }
    }
}
