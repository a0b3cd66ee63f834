//! The dense shape-matching kernel: positions and rest positions in
//! contiguous per-particle arrays, cluster members as index ranges with each
//! membership's rest offset and weight beside it, clusters grouped by colour. Built once
//! per topology, then iterated many times.
//!
//! A cluster fit computes, from the current positions, the optimal rotation `R` (Müller
//! 2016, warm-started) and the weighted centroid `c`; member `i`'s goal is
//! `R (x̄ᵢ − x̄_c) + c` with `x̄` rest positions. A cluster stores the elastic energy
//! `(κ/2) Σᵢ wᵢ |xᵢ − gᵢ|²` (compliance `1/κ`, 0 for a rigid cluster), and every scheme
//! solves the same substep problem, `min ½|x − s|²_M/dt² + E(x)` with `s` the
//! predictions (see [`SolverLayout::solve`]); they share the fit and differ in how they
//! move the particles:
//! - **Jacobi** (`jacobi.rs`): every cluster is fitted to the same positions and adds its
//!   pulls `gᵢₖ − pᵢ` to its members' accumulators; each particle then moves to the
//!   inertia-weighted average of its goals and its prediction (the plain average of the
//!   goals when rigid). With matching weights `1/nᵢ` (FastLSM) every cluster's pull has
//!   zero momentum, so the scheme conserves linear momentum.
//! - **Coloured Gauss–Seidel** (`gauss_seidel.rs`): colour after colour, each cluster is
//!   fitted and moves its members at once by their XPBD step (uniform weights when rigid,
//!   so again zero momentum).
//! - **Projective dynamics** (`projective.rs`): Jacobi's cluster pass as the local step,
//!   then one sparse linear solve for every particle as the global step.
//!
//! Clusters of one colour share no particle (see [`colour_clusters`]), which is what
//! makes the parallel writes race-free. Every scheme is deterministic for any number of
//! threads: every sum runs in a fixed order.
//! Per-cluster work is done relative to the cluster's first member so that goals keep
//! full precision far from the origin.

mod batch;
mod colliders;
mod colouring;
mod contacts;
mod gauss_seidel;
mod jacobi;
mod kinds;
mod patch;
mod projective;
mod repair;
mod sweep;
mod template;

pub use colliders::{Colliders, PosedCollider};
pub use colouring::{
    colour_clusters, colour_clusters_by_bits, colour_clusters_by_lists, order_by_colour,
};
pub use contacts::{ContactGroup, ContactParticles, Contacts, SELF_CONTACT_EXCLUSION};
pub use kinds::{ConstraintKind, ConstraintKinds, ParticleState};

use crate::config::SolverMode;
use crate::math::rotation::warm_start;
use glam::{Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Müller iterations per cluster per solver iteration (warm-started, so one suffices
/// where each iteration moves the particles only part of the way).
pub const ROTATION_ITERATIONS: u32 = 1;

/// Müller iterations per cluster per projective-dynamics iteration: its global step
/// takes the rotations at their word, so a rotation that lags holds the whole body
/// back.
pub const PROJECTIVE_ROTATION_ITERATIONS: u32 = 3;

/// Relative size of rounding noise: if a particle's total correction over a solve is at
/// most `ROUNDING_FLOOR × (|p|∞ + |x̄|∞)` (16 ulps of the coordinates that enter it), it
/// is rounding, not physics, and the particle keeps its predicted position. So a body at
/// rest stays exactly at rest instead of creeping. Real corrections are orders of
/// magnitude larger (gravity alone moves a particle 7·10⁻⁴ m per substep at 120 Hz).
pub const ROUNDING_FLOOR: f32 = 16.0 * f32::EPSILON;

/// Colour of a free cluster slot.
const FREE_SLOT: u32 = u32::MAX;

/// Most particles one layout holds: the kernel addresses them by byte offsets
/// (16 bytes per particle) in `u32`.
pub const MAX_SOLVER_PARTICLES: u64 = (u32::MAX as u64 + 1) / batch::PARTICLE_BYTES as u64;

/// Arrays that patches append to are allocated with `1/PATCH_HEADROOM` spare room, so
/// that a cut does not copy them (tens of megabytes on a large body).
const PATCH_HEADROOM: usize = 8;

/// Clusters per parallel task.
const CLUSTERS_PER_TASK: usize = 128;
/// Particles per parallel task.
const PARTICLES_PER_TASK: usize = 2048;

/// Whether `mode` weights a particle `1/nᵢ` in each of its `nᵢ` clusters (Jacobi and
/// projective dynamics, whose particle steps sum over a particle's clusters) rather
/// than 1 (Gauss–Seidel, whose cluster steps need uniform weights to keep momentum).
fn weighted_by_count(mode: SolverMode) -> bool {
    matches!(mode, SolverMode::Jacobi | SolverMode::Projective)
}

/// How much of the clusters' last correction a particle starts its substep with, for
/// a particle whose step pulls it toward its prediction with share `anchor` (see
/// `jacobi::step_coefficients`) in each of `iterations` iterations.
///
/// The warm start makes a static equilibrium exact, but it is also fed back: the carried
/// correction enters the velocity too, and an iteration that removes only a fraction
/// `1 − q` of a stale one (`q = (1 − anchor)^iterations` for the body's slow, bending
/// modes, which the clusters themselves barely correct) turns that feedback into
/// growth. A linear model of one mode (implicit step, iteration keeping `q` of its
/// error, warm start weighted `ρ`) is stable exactly while `q ρ < ½`; the weight keeps
/// [`WARM_START_LOOP_GAIN`] below that. Rigid clusters (`anchor` 0, `q` = 1) still get
/// a little; projective dynamics' global step corrects every mode at once, so it takes
/// the whole correction.
fn warm_start_weight(anchor: f32, iterations: u32, global: bool) -> f32 {
    if global {
        return 1.0;
    }
    if anchor == 0.0 {
        return WARM_START_LOOP_GAIN.min(1.0);
    }
    let kept = (1.0 - anchor).powi(iterations.min(i32::MAX as u32) as i32);
    (WARM_START_LOOP_GAIN / kept).min(1.0)
}

/// Largest `q ρ` the warm start is given (see `warm_start_weight`): nine tenths of
/// the stability bound ½.
pub const WARM_START_LOOP_GAIN: f32 = 0.45;

/// One cluster as given to [`SolverLayout::new`].
#[derive(Clone, Copy, Debug)]
pub struct ClusterSpec<'a> {
    /// Dense particle indices of the members.
    pub members: &'a [u32],
    /// Compliance `1/κ` of the cluster's elastic energy in m/N; 0: rigid (see
    /// [`crate::config::Material::compliance`]).
    pub compliance: f32,
    /// Warm-start rotation.
    pub rotation: Quat,
}

/// Dense arrays for the solver; see the module docs.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SolverLayout {
    /// Particle positions (predicted during a substep).
    pub positions: Vec<Vec3A>,
    /// Positions at the start of the substep.
    pub previous: Vec<Vec3A>,
    /// Positions at the start of the last solve (the predicted positions).
    predicted: Vec<Vec3A>,
    /// Inverse masses (0 = pinned).
    pub inv_mass: Vec<f32>,
    /// Total position correction per particle during the last [`SolverLayout::solve`].
    pub corrections: Vec<Vec3A>,
    /// The clusters' part of each particle's correction in the last solve; the next
    /// solve starts from the prediction plus this (warm start, see [`Self::solve`]).
    carry: Vec<Vec3A>,
    /// The substep time step the carry was made with (a change drops it).
    carry_dt: f32,
    /// Gauss–Seidel: each membership's accumulated correction in this substep (XPBD's
    /// `λ` over the particle's mass), by particle row of the batches × lane.
    membership_carry: Vec<Vec3A>,
    /// Per particle: the mean compliance of its clusters.
    particle_compliance: Vec<f32>,
    /// Whether any cluster is compliant (else the particle pass has no pull toward the
    /// prediction to add).
    compliant: bool,
    /// Whether members are weighted `1/nᵢ` (see [`weighted_by_count`]; also Gauss–Seidel
    /// with a compliant cluster, whose energy must be Jacobi's).
    count_weights: bool,
    /// Per particle: the warm-start weight of the current substep (scratch).
    warm_weight: Vec<f32>,
    /// Jacobi: per particle, the scale of the summed pulls and the pull toward the
    /// prediction in a particle's step (see `jacobi.rs`), for the current substep.
    step_scale: Vec<f32>,
    anchor: Vec<f32>,
    /// Whether the clusters changed since the per-particle and per-cluster coefficients
    /// above were computed.
    coefficients_stale: bool,
    /// Projective dynamics: the factored global matrix (built on first use; not saved:
    /// a loaded layout factors the same matrix again).
    #[serde(skip)]
    global: Option<projective::GlobalSolve>,
    /// Seconds spent building projective dynamics' global factor since the layout was
    /// made (the engine reports its growth over a cut).
    pub factor_seconds: f64,
    /// Warm-start rotation per cluster.
    pub rotations: Vec<Quat>,
    mode: SolverMode,
    /// Rest position per particle.
    rest: Vec<Vec3A>,
    /// `1/nᵢ` per particle (0 for a particle in no cluster).
    inv_count: Vec<f32>,
    /// Jacobi: the sum of the clusters' pulls on each particle in this iteration.
    pulls: Vec<Vec3A>,
    /// Number of clusters each particle is in.
    member_count: Vec<u32>,
    /// Per cluster slot: `[start, end)` of its memberships (empty for a free slot).
    cluster_range: Vec<[u32; 2]>,
    /// Per cluster slot: its colour ([`FREE_SLOT`] for a free slot).
    colour_of: Vec<u32>,
    /// Per particle: bit `c` set when one of its clusters has colour `c` (empty when the
    /// colouring needs more than 64 colours; such a layout is not patched).
    particle_colours: Vec<u64>,
    /// Cluster slots freed by [`SolverLayout::patch`], reused by later additions.
    free_slots: Vec<u32>,
    /// Memberships in the member arrays that belong to no cluster any more.
    garbage: usize,
    member_particle: Vec<u32>,
    /// Per cluster slot: the weighted rest centroid `x̄_c`; member `i`'s rest offset is
    /// `x̄ᵢ − x̄_c`, its matching weight [`SolverLayout::weight`].
    rest_centroid: Vec<Vec3A>,
    offset_bias: Vec<Vec3A>,
    inv_weight_sum: Vec<f32>,
    /// Per cluster slot: compliance (m/N).
    compliance: Vec<f32>,
    /// The clusters in batches of eight, as the kernel reads them (see `batch.rs`).
    batches: batch::Batches,
}

impl SolverLayout {
    /// Builds the layout for particles with the given rest positions and clusters, for
    /// the given scheme. Members must be valid indices into `rest`.
    ///
    /// # Panics
    /// If `rest` holds more than [`MAX_SOLVER_PARTICLES`] particles (spawning refuses
    /// bodies that would take a world past it).
    pub fn new<'a>(
        rest: &[Vec3],
        clusters: impl IntoIterator<Item = ClusterSpec<'a>>,
        mode: SolverMode,
    ) -> Self {
        assert!(
            rest.len() as u64 <= MAX_SOLVER_PARTICLES,
            "{} particles in one solver layout (at most {MAX_SOLVER_PARTICLES})",
            rest.len()
        );
        let clusters: Vec<ClusterSpec<'a>> = clusters.into_iter().collect();
        let n = rest.len();
        let rest: Vec<Vec3A> = rest.iter().map(|r| Vec3A::from(*r)).collect();
        let compliant = clusters.iter().any(|c| c.compliance > 0.0);
        let mut layout = SolverLayout {
            count_weights: weighted_by_count(mode) || compliant,
            positions: rest.clone(),
            previous: rest.clone(),
            corrections: vec![Vec3A::ZERO; n],
            carry: vec![Vec3A::ZERO; n],
            coefficients_stale: true,
            inv_mass: vec![1.0; n],
            pulls: vec![Vec3A::ZERO; n],
            member_count: vec![0; n],
            mode,
            rest,
            ..Default::default()
        };
        let memberships: usize = clusters.iter().map(|c| c.members.len()).sum();
        // headroom for the clusters later patches add: growing the array would copy it
        layout
            .member_particle
            .reserve_exact(memberships + memberships / PATCH_HEADROOM);
        let count = clusters.len();
        layout.cluster_range.reserve_exact(count);
        layout.colour_of.reserve_exact(count);
        layout.compliance.reserve_exact(count);
        layout.rotations.reserve_exact(count);
        layout.offset_bias.reserve_exact(count);
        layout.rest_centroid.reserve_exact(count);
        layout.inv_weight_sum.reserve_exact(count);
        for c in &clusters {
            layout.push_cluster(c, None, 0);
        }
        layout.inv_count = layout
            .member_count
            .iter()
            .map(|c| if *c > 0 { 1.0 / *c as f32 } else { 0.0 })
            .collect();
        for k in 0..clusters.len() {
            layout.fill_constants(k);
        }
        let cluster_start: Vec<u32> = std::iter::once(0)
            .chain(layout.cluster_range.iter().map(|r| r[1]))
            .collect();
        match colour_clusters_by_bits(&cluster_start, &layout.member_particle, n) {
            Some((colours, bits)) => {
                layout.colour_of = colours;
                layout.particle_colours = bits;
            }
            // more than 64 colours: colour by the inverse lists; the layout cannot be
            // patched (no colour bits)
            None => {
                layout.colour_of =
                    colour_clusters_by_lists(&cluster_start, &layout.member_particle, n)
            }
        }
        layout.build_batches();
        layout
    }

    /// Appends cluster `spec` in `slot` (a new slot when `None`) with colour `colour`;
    /// counts its memberships. Its constants are filled later ([`Self::fill_constants`]).
    fn push_cluster(&mut self, spec: &ClusterSpec, slot: Option<usize>, colour: u32) -> usize {
        let start = self.member_particle.len() as u32;
        self.member_particle.extend_from_slice(spec.members);
        for &m in spec.members {
            self.member_count[m as usize] += 1;
        }
        let range = [start, self.member_particle.len() as u32];
        let compliance = spec.compliance;
        // the batched fit expects unit warm starts
        let rotation = warm_start(spec.rotation);
        match slot {
            Some(k) => {
                self.cluster_range[k] = range;
                self.colour_of[k] = colour;
                self.compliance[k] = compliance;
                self.rotations[k] = rotation;
                k
            }
            None => {
                self.cluster_range.push(range);
                self.colour_of.push(colour);
                self.compliance.push(compliance);
                self.rotations.push(rotation);
                self.offset_bias.push(Vec3A::ZERO);
                self.rest_centroid.push(Vec3A::ZERO);
                self.inv_weight_sum.push(0.0);
                self.cluster_range.len() - 1
            }
        }
    }

    /// The matching weight of particle `m` in every cluster: `1/nᵢ` for Jacobi and
    /// projective dynamics (with the current membership counts), 1 for Gauss–Seidel.
    #[inline]
    fn weight(&self, m: u32) -> f32 {
        if self.count_weights {
            self.inv_count[m as usize]
        } else {
            1.0
        }
    }

    /// Computes the weighted rest centroid, offset bias and weight sum of cluster `k`
    /// from the rest positions and (Jacobi) the current membership counts.
    fn fill_constants(&mut self, k: usize) {
        let [start, end] = self.cluster_range[k];
        let members = &self.member_particle[start as usize..end as usize];
        let rest = &self.rest;
        // the weight sum and the weighted position sum in one pass (same order of
        // additions as two; every member's weight is positive, so the sum is too)
        let (mut total, mut weighted) = (0.0f32, Vec3A::ZERO);
        for &m in members {
            let w = self.weight(m);
            total += w;
            weighted += rest[m as usize] * w;
        }
        let centroid = weighted / total;
        // Σ w (x̄ − x̄_c) is zero up to rounding; the fit subtracts its rotated
        // rounding residue so that every cluster's pull has exactly zero momentum.
        let bias: Vec3A = members
            .iter()
            .map(|m| (rest[*m as usize] - centroid) * self.weight(*m))
            .sum();
        self.rest_centroid[k] = centroid;
        self.offset_bias[k] = bias;
        self.inv_weight_sum[k] = 1.0 / total;
    }

    /// Müller iterations per cluster fit under this layout's scheme.
    #[inline(always)]
    fn rotation_iterations(&self) -> u32 {
        if self.mode == SolverMode::Projective {
            PROJECTIVE_ROTATION_ITERATIONS
        } else {
            ROTATION_ITERATIONS
        }
    }

    /// The scheme this layout was built for.
    pub fn mode(&self) -> SolverMode {
        self.mode
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of clusters.
    pub fn cluster_count(&self) -> usize {
        self.colour_of.iter().filter(|c| **c != FREE_SLOT).count()
    }

    /// Number of memberships (sum of cluster sizes).
    pub fn membership_count(&self) -> usize {
        self.member_particle.len() - self.garbage
    }

    /// Number of cluster colours.
    pub fn colour_count(&self) -> usize {
        self.colour_of
            .iter()
            .filter(|c| **c != FREE_SLOT)
            .map(|c| *c as usize + 1)
            .max()
            .unwrap_or(0)
    }

    /// Heap bytes held by the layout's arrays (not projective dynamics' factor, which faer
    /// holds).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of;
        let v3 = size_of::<Vec3A>();
        self.positions.capacity() * v3 * 6
            + self.inv_mass.capacity() * 4 * 2
            + self.batches.heap_bytes()
            + self.rotations.capacity() * size_of::<Quat>()
            + self.cluster_range.capacity() * 8
            + self.colour_of.capacity() * 4
            + self.particle_colours.capacity() * 8
            + (self.member_count.capacity()
                + self.free_slots.capacity()
                + self.member_particle.capacity())
                * 4
            + (self.offset_bias.capacity() + self.rest_centroid.capacity()) * v3
            + self.inv_weight_sum.capacity() * 4 * 2
            // the warm start and the per-particle step coefficients
            + (self.carry.capacity() + self.membership_carry.capacity()) * v3
            + (self.particle_compliance.capacity()
                + self.step_scale.capacity()
                + self.anchor.capacity()
                + self.warm_weight.capacity())
                * 4
    }

    /// One substep's solve: `iterations` iterations, each running the layout's cluster
    /// scheme, then every other constraint kind in `kinds` in their registered order
    /// ([`ConstraintKinds::in_order`]); records the total correction per particle in
    /// [`SolverLayout::corrections`]. `dt` is the substep's time step.
    ///
    /// The positions on entry are the inertial predictions `s`. The clusters solve one
    /// implicit Euler step of their elastic energy, `min ½|x − s|²_M/dt² + E(x)`; a
    /// compliance of 0 makes a cluster a hard constraint. The iteration starts from
    /// `s` plus the clusters' correction of the previous substep (warm start): at a
    /// static equilibrium that is already the solution, so a body at rest holds its
    /// shape whatever the iteration count, instead of sagging until an unconverged
    /// iteration happens to balance gravity.
    pub fn solve(&mut self, iterations: u32, dt: f32, kinds: &mut ConstraintKinds) {
        // Called from outside rayon's pool (a user's thread, an ECS executor), each of
        // the solve's many parallel loops would hand its work to the pool and sleep until
        // it is done; the solve moves onto a pool thread once instead.
        rayon::scope(|_| {
            self.predicted.clone_from(&self.positions);
            self.begin_substep(dt, iterations);
            self.iterate(iterations, dt, kinds);
            self.finish_substep();
        })
    }

    /// The iterations of [`Self::solve`], continuing from the current positions toward
    /// the predictions the last solve was given. With [`Self::restart_from`], a static
    /// solve can be iterated block by block.
    pub(crate) fn iterate(&mut self, iterations: u32, dt: f32, kinds: &mut ConstraintKinds) {
        let (mut kinds, seconds) = kinds.in_order();
        // every kind that has something to do, timed into its entry of `seconds`
        let mut each_kind = |f: &mut dyn FnMut(&mut dyn ConstraintKind)| {
            for (kind, seconds) in kinds.iter_mut().zip(seconds.iter_mut()) {
                if !kind.is_empty() {
                    let start = std::time::Instant::now();
                    f(&mut **kind);
                    *seconds += start.elapsed().as_secs_f64();
                }
            }
        };
        let state = self.particle_state();
        each_kind(&mut |kind| kind.begin_substep(&state));
        for _ in 0..iterations {
            match self.mode {
                SolverMode::Jacobi => {
                    self.accumulate_pulls();
                    self.move_particles_jacobi();
                }
                SolverMode::GaussSeidel => self.sweep_colours(dt),
                SolverMode::Projective => {
                    self.accumulate_pulls();
                    self.global_step(dt);
                }
            }
            let mut state = self.particle_state();
            each_kind(&mut |kind| kind.project(&mut state));
        }
    }

    /// Makes `start` the iterate of the current solve, as if the clusters had moved the
    /// particles there from their predictions (Gauss–Seidel's memberships share each
    /// particle's displacement equally).
    pub(crate) fn restart_from(&mut self, start: &[Vec3A]) {
        self.positions.copy_from_slice(start);
        for ((carry, p), s) in self.carry.iter_mut().zip(start).zip(&self.predicted) {
            *carry = *p - *s;
        }
        let (carry, inv_count) = (&self.carry, &self.inv_count);
        self.membership_carry = self
            .batches
            .membership_particles()
            .map(|m| carry[m as usize] * inv_count[m as usize])
            .collect();
        // (padding slots name a member too, but no step reads or writes theirs)
    }

    /// Ends a solve: the corrections are the kinds' and the clusters' together; rounding
    /// noise is dropped.
    fn finish_substep(&mut self) {
        for (c, carry) in self.corrections.iter_mut().zip(&self.carry) {
            *c += *carry;
        }
        self.drop_rounding_noise();
    }

    /// Brings the coefficients up to date after a change of clusters or time step and
    /// applies the warm start: `p = s + carry` and the corrections cleared.
    fn begin_substep(&mut self, dt: f32, iterations: u32) {
        if self.coefficients_stale {
            self.refresh_coefficients();
        }
        if self.carry_dt != dt {
            self.carry_dt = dt;
            self.forget_carry();
        }
        let inv_dt2 = 1.0 / (dt * dt);
        let n = self.positions.len();
        self.step_scale.resize(n, 0.0);
        self.anchor.resize(n, 0.0);
        let coefficients = self
            .inv_count
            .par_iter()
            .zip(&self.particle_compliance)
            .zip(&self.inv_mass)
            .zip(self.step_scale.par_iter_mut().zip(&mut self.anchor))
            .with_min_len(PARTICLES_PER_TASK);
        coefficients.for_each(
            |(((&inv_count, &compliance), &inv_mass), (scale, anchor))| {
                (*scale, *anchor) = jacobi::step_coefficients(
                    inv_count,
                    compliance * inv_dt2 / inv_mass.max(f32::MIN_POSITIVE),
                    inv_mass,
                );
            },
        );
        let global = self.mode == SolverMode::Projective;
        let weight = |i: usize| {
            let (inv_mass, carry) = (self.inv_mass[i], self.carry[i]);
            // (a pinned particle, or a carry a repaired particle left, starts afresh)
            if inv_mass == 0.0 || !carry.is_finite() {
                0.0
            } else {
                warm_start_weight(self.anchor[i], iterations, global)
            }
        };
        let mut weights = std::mem::take(&mut self.warm_weight);
        weights.resize(n, 0.0);
        weights
            .par_iter_mut()
            .enumerate()
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(i, w)| *w = weight(i));
        // Gauss–Seidel's memberships hold the parts of the carry: scaled alike
        let particles = self.batches.membership_particles();
        for (carry, m) in self.membership_carry.iter_mut().zip(particles) {
            *carry *= weights[m as usize];
        }
        // projective dynamics: a factor built for other masses or another time step
        if self
            .global
            .as_ref()
            .is_some_and(|g| !g.built_for(dt, &self.inv_mass))
        {
            self.global = None;
        }
        self.positions
            .par_iter_mut()
            .zip(self.carry.par_iter_mut())
            .zip(self.corrections.par_iter_mut())
            .zip(weights.par_iter())
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(((p, carry), correction), &weight)| {
                *carry *= weight;
                *p += *carry;
                *correction = Vec3A::ZERO;
            });
        self.warm_weight = weights;
    }

    /// Recomputes each particle's mean cluster compliance from the current clusters;
    /// drops the warm start, which belonged to
    /// other clusters.
    fn refresh_coefficients(&mut self) {
        let n = self.positions.len();
        let mut sum = vec![0.0f32; n];
        for (k, range) in self.cluster_range.iter().enumerate() {
            let members = &self.member_particle[range[0] as usize..range[1] as usize];
            for &m in members {
                sum[m as usize] += self.compliance[k];
            }
        }
        for (s, &inv_count) in sum.iter_mut().zip(&self.inv_count) {
            *s *= inv_count;
        }
        self.compliant = sum.iter().any(|c| *c > 0.0);
        self.particle_compliance = sum;
        self.global = None;
        self.coefficients_stale = false;
        self.forget_carry();
    }

    /// Drops the warm start (after the clusters or the time step changed).
    fn forget_carry(&mut self) {
        self.carry.clear();
        self.carry.resize(self.positions.len(), Vec3A::ZERO);
        self.membership_carry.clear();
    }

    /// The particle arrays as the constraint kinds see them.
    fn particle_state(&mut self) -> ParticleState<'_> {
        ParticleState {
            positions: &mut self.positions,
            previous: &self.previous,
            inv_mass: &self.inv_mass,
            corrections: &mut self.corrections,
        }
    }

    /// Restores the predicted position of every particle whose total correction is below
    /// the rounding floor (see [`ROUNDING_FLOOR`]), and drops its warm start — except
    /// where Gauss–Seidel's memberships hold the warm start's parts: dropping it for one
    /// particle alone would set the two apart, and the memberships would then push the
    /// particle toward a displacement it no longer has.
    fn drop_rounding_noise(&mut self) {
        let (predicted, rest) = (&self.predicted, &self.rest);
        let keep_carry = !self.membership_carry.is_empty();
        self.positions
            .par_iter_mut()
            .zip(self.corrections.par_iter_mut().zip(&mut self.carry))
            .zip(predicted.par_iter().zip(rest))
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|((p, (correction, carry)), (start, rest))| {
                let floor = ROUNDING_FLOOR * (start.abs().max_element() + rest.abs().max_element());
                if correction.abs().max_element() <= floor {
                    *p = *start;
                    *correction = Vec3A::ZERO;
                    if !keep_carry {
                        *carry = Vec3A::ZERO;
                    }
                }
            });
    }

    /// Adds the last solve's corrections to `velocities` (one per particle, as they were
    /// after prediction): `v += Σ Δp / dt`. The layout keeps no velocities: the engine
    /// applies the same rule while it writes the solved state back to its components.
    ///
    /// Deriving velocity from the corrections rather than from `(p − p_prev) / dt` keeps
    /// the rounding of large absolute positions out of the velocities, so momentum is
    /// conserved to the precision of the (small) corrections.
    pub fn update_velocities(&self, velocities: &mut [Vec3A], inv_dt: f32) {
        velocities
            .par_iter_mut()
            .zip(&self.corrections)
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(v, c)| *v += *c * inv_dt);
    }
}

/// Test helper: a substep time step (120 Hz).
#[cfg(test)]
pub(crate) const TEST_DT: f32 = 1.0 / 120.0;

/// Test helper: specs of rigid clusters without rotation for the given member lists.
#[cfg(test)]
fn unit_specs(clusters: &[Vec<u32>]) -> Vec<ClusterSpec<'_>> {
    clusters
        .iter()
        .map(|m| ClusterSpec {
            members: m,
            compliance: 0.0,
            rotation: Quat::IDENTITY,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bar(n: usize) -> (Vec<Vec3>, Vec<Vec<u32>>) {
        let rest: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let clusters = (0..n - 2)
            .map(|i| vec![i as u32, i as u32 + 1, i as u32 + 2])
            .collect();
        (rest, clusters)
    }

    fn perturbed_bar(mode: SolverMode) -> SolverLayout {
        let (rest, clusters) = bar(8);
        let mut l = SolverLayout::new(&rest, unit_specs(&clusters), mode);
        l.positions[3].y += 0.5;
        l.positions[6].z -= 0.3;
        l
    }

    #[test]
    fn colliders_never_move_a_pinned_particle() {
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let mut l = perturbed_bar(mode);
            // the whole bar sinks below the ground; particle 2 is pinned there
            for p in &mut l.positions {
                p.y -= 1.0;
            }
            l.inv_mass[2] = 0.0;
            let pinned = l.positions[2];
            let mut kinds = ConstraintKinds {
                colliders: Colliders::new(
                    Some(crate::config::GroundPlane {
                        height: 0.0,
                        friction: 0.0,
                    }),
                    vec![],
                ),
                ..Default::default()
            };
            l.solve(5, crate::solver::TEST_DT, &mut kinds);
            assert_eq!(l.positions[2], pinned, "{mode:?}");
            assert!(
                l.positions[7].y > -0.5,
                "{mode:?}: the free end is pushed up"
            );
        }
    }

    #[test]
    fn both_schemes_restore_a_perturbed_bar_and_conserve_momentum() {
        for mode in [SolverMode::Jacobi, SolverMode::GaussSeidel] {
            let mut l = perturbed_bar(mode);
            let momentum = |l: &SolverLayout| l.positions.iter().copied().sum::<Vec3A>();
            let before = momentum(&l);
            l.solve(200, crate::solver::TEST_DT, &mut ConstraintKinds::default());
            assert!((momentum(&l) - before).length() < 1e-4, "{mode:?}");
            // straight again (up to a rigid motion): the ends are 7 apart
            let d = (l.positions[7] - l.positions[0]).length();
            assert!((d - 7.0).abs() < 0.05, "{mode:?}: {d}");
            // corrections add up to the total displacement
            let moved: Vec3A = l.corrections.iter().map(|c| c.abs()).sum();
            assert!(moved.max_element() > 0.1, "{mode:?}");
        }
    }

    /// A 6×3×3 block with 2×2×2 clusters at every cell, twisted about its long axis.
    fn twisted_block(mode: SolverMode) -> (Vec<Vec3>, SolverLayout) {
        let index = |x: u32, y: u32, z: u32| x * 9 + y * 3 + z;
        let mut rest = vec![];
        for x in 0..6 {
            for y in 0..3 {
                for z in 0..3 {
                    rest.push(Vec3::new(x as f32, y as f32, z as f32));
                }
            }
        }
        let mut clusters = vec![];
        for x in 0..5 {
            for y in 0..2 {
                for z in 0..2 {
                    let mut c = vec![];
                    for (dx, dy, dz) in (0..8).map(|b| (b & 1, (b >> 1) & 1, b >> 2)) {
                        c.push(index(x + dx, y + dy, z + dz));
                    }
                    clusters.push(c);
                }
            }
        }
        let mut l = SolverLayout::new(&rest, unit_specs(&clusters), mode);
        for (p, r) in l.positions.iter_mut().zip(&rest) {
            let twist = Quat::from_rotation_x(0.15 * r.x);
            *p = Vec3A::from(twist * (*r - Vec3::new(0.0, 1.0, 1.0)));
        }
        (rest, l)
    }

    #[test]
    fn gauss_seidel_converges_faster_than_jacobi_on_a_twisted_block() {
        let error = |mode, iterations| {
            let (rest, mut l) = twisted_block(mode);
            l.solve(
                iterations,
                crate::solver::TEST_DT,
                &mut ConstraintKinds::default(),
            );
            let current: Vec<Vec3> = l.positions.iter().map(|p| Vec3::from(*p)).collect();
            crate::analysis::stats::rigid_fit_error(&rest, &current)
        };
        let start = error(SolverMode::Jacobi, 0);
        for k in [2, 5, 10] {
            let (jacobi, gs) = (
                error(SolverMode::Jacobi, k),
                error(SolverMode::GaussSeidel, k),
            );
            assert!(
                jacobi < start && gs < jacobi,
                "k={k}: start {start} jacobi {jacobi} gs {gs}"
            );
        }
    }
}
