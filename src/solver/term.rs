//! The seam every constraint kind plugs into.
//!
//! A body's energy is a sum of terms; each substep solves one implicit Euler step of it,
//! `min ½|x − s|²_M/dt² + Σ E(x)` with `s` the inertial predictions. Cluster shape
//! matching is the dense SIMD core ([`super::clusters`]); every other kind — attachments,
//! edge distances, contacts, colliders, and whatever comes next — is one module that
//! implements [`Term`], registered by one line in [`super::registry::Terms::builtin`] (or,
//! from outside, [`super::registry::Terms::register`]).
//!
//! ## Compliance, the same for every kind
//!
//! A term is a set of constraints `C(x)`, each with a compliance `α ≥ 0` (its inverse
//! stiffness), storing the energy `E = C(x)² / (2α)`; `α = 0` makes the constraint hard.
//! The units follow `C`: for a distance (an edge, an attachment's spring) `α` is in m/N.
//! Material parameters are given per unit of material (`compliance`, `edge_compliance`:
//! 1/Pa) and each kind turns them into its constraints' `α` on the body's lattice. The
//! schemes take every term into the same implicit step the way XPBD does (Macklin et
//! al. 2016): a constraint's correction is `Δλ = (−C − α̃λ)/(∇C M⁻¹ ∇Cᵀ + α̃)`,
//! `α̃ = α/dt²`, with `λ` accumulated over the substep, so stiffness depends neither on
//! the time step nor on the iteration count.
//!
//! ## How the schemes solve a term
//!
//! Jacobi and Gauss–Seidel run the clusters' pass, then every term's
//! [`Term::project`] in registered order, in each iteration; a term's moves are
//! corrections that also move each particle's inertial target, so that the clusters'
//! next pass does not undo them. Projective dynamics puts every term that gives a
//! [`ProjectiveTerm`] into its global matrix (`w AᵀA` beside the clusters' and the
//! masses') and solves all of them in one linear solve per iteration; the others
//! (contacts, colliders, patches, centroid holds: their constraints change every substep or
//! couple many particles) are projected after it.
//!
//! ## Particles, and how a term names them
//!
//! During a solve a term reads and moves particles by their dense index in the solver's
//! arrays ([`ParticleState`]). Dense indices change when the layout is rebuilt, so a
//! term that keeps particles names them by [`ParticleKey`] (body and body-local index,
//! stable for the body's life) and resolves the keys again in [`Term::topology`], the
//! one routine through which every kind hears that particles were removed, edges
//! severed or particles split, and that the dense indices moved.

use crate::body::groups::ParticleGroups;
use crate::body::lattice::Lattice;
use crate::config::Material;
use crate::solver::disjoint::Disjoint;
use glam::{DVec3, Quat, Vec3A};

/// Stiffness a hard constraint (compliance 0) gets in projective dynamics' global
/// matrix, relative to its particles' mean `m/dt²`. A direct solve could take any
/// stiffness; but contacts and colliders are projected after the global step and push
/// single particles, and a body far stiffer than `m/dt²` answers such a push only
/// through its inertia, so the pushes pile up into velocity. 100 keeps every built-in
/// scene's outcome and lets its bodies come to rest.
pub const STIFFEST: f64 = 100.0;

/// "No particle" among dense indices.
pub const NO_DENSE: u32 = u32::MAX;

/// One substep as every term sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Substep {
    /// The substep's time step, in seconds.
    pub dt: f32,
    /// Iterations in this substep's solve.
    pub iterations: u32,
    /// Where the substep starts and ends within its frame, as fractions from 0 (the
    /// frame's start) to 1 (its end): moving targets are placed by them.
    pub frame_span: [f32; 2],
}

impl Substep {
    /// `α/dt²`: the compliance a constraint of compliance `α` acts with in this substep.
    pub fn scaled(&self, compliance: f32) -> f32 {
        compliance / (self.dt * self.dt)
    }
}

/// The solver's particle arrays as a term sees them during a solve (dense order).
pub struct ParticleState<'a> {
    /// Positions being solved (the predictions at the start of the substep).
    pub positions: &'a mut [Vec3A],
    /// Positions at the start of the substep (friction, swept tests).
    pub previous: &'a [Vec3A],
    /// Inverse masses; 0 holds a particle still (a hard attachment's, or a cut one), and
    /// no term may move it.
    pub inv_mass: &'a [f32],
    /// Each particle's total correction in this substep: a term adds every move it makes
    /// here ([`ParticleState::shift`]); velocities are derived from it (`v += Σ Δp / dt`).
    pub corrections: &'a mut [Vec3A],
    /// Orientations (predicted at the start of the substep); a term that turns particles
    /// sets them here, and angular velocities are derived from the substep's turn.
    pub orientations: &'a mut [Quat],
    /// Angular velocities (rad/s) the orientations were predicted with.
    pub spins: &'a [Vec3A],
}

impl ParticleState<'_> {
    /// Moves particle `i` by `step` and records the move as a correction.
    #[inline]
    pub fn shift(&mut self, i: usize, step: Vec3A) {
        self.positions[i] += step;
        self.corrections[i] += step;
    }

    /// The positions and corrections for a parallel pass whose tasks each own distinct
    /// particles, each shifting its own ([`DisjointShifts::shift`]).
    pub(in crate::solver) fn disjoint_shifts(&mut self) -> DisjointShifts {
        DisjointShifts {
            positions: Disjoint::new(self.positions),
            corrections: Disjoint::new(self.corrections),
        }
    }
}

/// [`ParticleState::shift`] for tasks that own distinct particles.
#[derive(Clone, Copy)]
pub(in crate::solver) struct DisjointShifts {
    positions: Disjoint<Vec3A>,
    corrections: Disjoint<Vec3A>,
}

impl DisjointShifts {
    /// Moves particle `i` by `step` and records the move as a correction.
    ///
    /// # Safety
    /// `i` is in bounds, and no other task reads or writes particle `i` meanwhile.
    #[inline]
    pub(in crate::solver) unsafe fn shift(self, i: usize, step: Vec3A) {
        // SAFETY: the caller's contract
        unsafe {
            self.positions.write(i, self.positions.read(i) + step);
            self.corrections.write(i, self.corrections.read(i) + step);
        }
    }
}

/// A particle named so that the name survives layout rebuilds and cuts: its body's id
/// (the body entity's bits) and its body-local index.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize,
)]
pub struct ParticleKey {
    /// The body.
    pub body: u64,
    /// The particle's index in its body's lattice.
    pub local: u32,
}

/// One body as terms see it after a topology change.
#[derive(Clone, Copy)]
pub struct BodyTopology<'a> {
    /// The body's id (as in [`ParticleKey::body`]).
    pub id: u64,
    /// Its lattice: live particles and their links (the edges).
    pub lattice: &'a Lattice,
    /// The dense index of each body-local particle ([`NO_DENSE`] for none).
    pub dense: &'a [u32],
    /// Its material.
    pub material: &'a Material,
    /// Its explicit groups and per-particle compliances.
    pub groups: &'a ParticleGroups,
    /// Its number of connected pieces.
    pub pieces: usize,
    /// Whether its particles or links changed since the terms last heard (every body
    /// does after a rebuild of the layout).
    pub changed: bool,
}

/// A change of the particles the solver holds: after every rebuild or patch of the
/// layout (a body spawned or despawned, a cut, a tear, a split), every term hears of
/// the bodies as they are now.
pub struct Topology<'a> {
    /// Every body in the layout, by id.
    pub bodies: &'a [BodyTopology<'a>],
    /// Whether the dense indices were laid out afresh (a full rebuild): every dense index
    /// a term kept is stale.
    pub relaid: bool,
}

impl Topology<'_> {
    /// The dense index of the live particle `key`, or `None` when its body is not in the
    /// layout or the particle was cut away.
    pub fn dense(&self, key: ParticleKey) -> Option<u32> {
        let b = self.bodies.binary_search_by_key(&key.body, |b| b.id).ok()?;
        let body = &self.bodies[b];
        let d = *body.dense.get(key.local as usize)?;
        (d != NO_DENSE && body.lattice.is_live(key.local)).then_some(d)
    }

    /// A term's per-body data after this change: the `kept` entry (ordered by body id,
    /// as [`Topology::bodies`]) of every body that did not change, `build` for every body
    /// that did (all of them after a rebuild), none for bodies that are gone.
    pub fn rebuild_bodies<T>(
        &self,
        kept: Vec<T>,
        id: impl Fn(&T) -> u64,
        mut build: impl FnMut(&BodyTopology) -> Option<T>,
    ) -> Vec<T> {
        self.rebuild_bodies_from(kept, id, |body, _| build(body))
    }

    /// [`Topology::rebuild_bodies`], with `build` given the body's entry before the
    /// change (if it had one), for a term that carries state across it.
    pub fn rebuild_bodies_from<T>(
        &self,
        kept: Vec<T>,
        id: impl Fn(&T) -> u64,
        mut build: impl FnMut(&BodyTopology, Option<T>) -> Option<T>,
    ) -> Vec<T> {
        let mut out = Vec::with_capacity(self.bodies.len());
        let mut old = kept.into_iter().peekable();
        for body in self.bodies {
            while old.next_if(|o| id(o) < body.id).is_some() {}
            match old.next_if(|o| id(o) == body.id) {
                Some(entry) if !body.changed && !self.relaid => out.push(entry),
                entry => out.extend(build(body, entry)),
            }
        }
        out
    }
}

/// The unknowns of projective dynamics' global solve: every particle that can move
/// (inverse mass above 0) has a row.
pub struct Unknowns<'a> {
    /// The row of each dense particle ([`NO_DENSE`]: not an unknown).
    pub row_of: &'a [u32],
    /// Inverse masses, by dense particle.
    pub inv_mass: &'a [f32],
}

impl Unknowns<'_> {
    /// The row of dense particle `i`, if it is an unknown.
    #[inline]
    pub fn row(&self, i: u32) -> Option<usize> {
        match self.row_of.get(i as usize) {
            Some(&r) if r != NO_DENSE => Some(r as usize),
            _ => None,
        }
    }

    /// The weight `w = 1/α` a constraint of compliance `α` on particles `particles` takes
    /// in the global matrix; a hard one ([`STIFFEST`] times their mean `m/dt²`).
    pub fn weight(&self, compliance: f32, particles: &[u32], dt: f32) -> f64 {
        self.weight_up_to(compliance, particles, dt, STIFFEST)
    }

    /// [`Unknowns::weight`] with a hard constraint `stiffest` times its particles' mean
    /// `m/dt²` instead of [`STIFFEST`] times.
    pub fn weight_up_to(&self, compliance: f32, particles: &[u32], dt: f32, stiffest: f64) -> f64 {
        if compliance > 0.0 {
            return 1.0 / compliance as f64;
        }
        let (mut sum, mut count) = (0.0f64, 0u32);
        for &i in particles {
            let w = self.inv_mass[i as usize];
            if w > 0.0 {
                sum += 1.0 / w as f64;
                count += 1;
            }
        }
        let mean = sum / count.max(1) as f64;
        stiffest * mean / (dt as f64 * dt as f64)
    }
}

/// A term's projective-dynamics form (Bouaziz et al. 2014): per constraint a weight `w`,
/// a constant linear map `A S` of the positions and a projection `p = proj(A S x)` onto
/// the constraint's manifold, so that its energy is `(w/2)|A S x − p|²`.
pub trait ProjectiveTerm {
    /// A number that changes whenever the term's constant part changes (its constraints,
    /// their particles or weights): the global matrix is factored again then.
    fn version(&self) -> u64;

    /// Adds the term's `Σ w SᵀAᵀA S` over the unknowns to `entries`, lower triangle
    /// (`row ≥ col`), duplicates to be summed. Constraints on particles that are not
    /// unknowns drop those particles' rows and columns (their positions are given).
    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    );

    /// The local step and the right-hand side at once: adds `Σ w SᵀAᵀ(p − A S x)` at the
    /// positions `x` (each constraint's projection taken there), by dense particle, to
    /// `forces`: the force the term's springs exert with the projections held. A term
    /// whose projections are rotations sets the orientations they give particles in
    /// `orientations`.
    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        orientations: &mut [Quat],
        forces: &mut [DVec3],
    );
}

/// What a term holds, as reports count it ([`Term::extent`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TermExtent {
    /// Particles taking part.
    pub particles: usize,
    /// Constraints (edges, pairs found, …; each as the kind counts them).
    pub constraints: usize,
}

/// A kind of constraint: its data, its parameters and its kernel (see the module docs).
pub trait Term: std::any::Any + Send + Sync {
    /// A short name, for profiles and reports.
    fn name(&self) -> &'static str;

    /// Whether the term has nothing to do (the solver then skips it).
    fn is_empty(&self) -> bool;

    /// What the term holds now, for reports (none by default).
    fn extent(&self) -> TermExtent {
        TermExtent::default()
    }

    /// Dense particles the term moves itself and nothing else may (a hard attachment's):
    /// the solver gives them inverse mass 0, and the term places them in
    /// [`Term::begin_substep`].
    fn kinematic(&self) -> &[u32] {
        &[]
    }

    /// Hears of a topology change (see the module docs): resolve particle keys again,
    /// rebuild what is derived from the lattices.
    fn topology(&mut self, _change: &Topology) {}

    /// What a save keeps of the term, encoded by the term: what it carries from frame to
    /// frame (warm starts, plastic rest shapes). `None` (the default) when everything it
    /// holds is taken again from the ECS at the next topology change.
    fn saved_state(&self) -> Option<Vec<u8>> {
        None
    }

    /// Takes up what [`Term::saved_state`] gave, at the next topology change (a loaded
    /// simulation's first, which lays the particles out as they were saved); an error,
    /// naming what is wrong, when it does not decode or does not fit.
    fn resume_state(&mut self, _state: &[u8]) -> Result<(), String> {
        Err("this term keeps no saved state".into())
    }

    /// Called once per substep before the iterations, with the predictions: the place for
    /// work the iterations share (finding contact pairs, placing kinematic particles,
    /// clearing accumulated `λ`).
    fn begin_substep(&mut self, _step: &Substep, _state: &mut ParticleState) {}

    /// Called once per substep after the iterations, with every particle's velocity
    /// and total correction (`v += Σ Δp / dt` follows): the place to bound the speed a
    /// term's particles gain from corrections that are not to become motion.
    fn end_substep(&self, _step: &Substep, _velocities: &[Vec3A], _corrections: &mut [Vec3A]) {}

    /// Projects the term's constraints once (Jacobi and Gauss–Seidel: after the
    /// clusters' pass of every iteration; projective dynamics: after the global step,
    /// for a term without [`Term::projective`]). Deterministic for any thread count.
    fn project(&mut self, step: &Substep, state: &mut ParticleState);

    /// The term's projective-dynamics form, if its constraints' linear part is constant.
    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        None
    }
}
