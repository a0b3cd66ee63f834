//! The cluster term: shape matching over overlapping clusters (Müller et al. 2005), the
//! dense core of the solver. Cluster members are index ranges into one member array,
//! each membership's rest offset and weight beside it (or in a shared template), the
//! clusters in batches of eight that the SIMD kernel fits at once ([`super::batches`],
//! [`super::fit`]), coloured so that clusters of one colour share no particle
//! ([`super::colouring`]). Built once per topology, patched after a cut
//! ([`super::patch`]), then iterated many times by the schemes
//! ([`crate::solver::schemes`]).
//!
//! A cluster fit computes, from the current positions, the optimal rotation `R` (Müller
//! 2016, warm-started) and the weighted centroid `c`; member `i`'s goal is
//! `R (x̄ᵢ − x̄_c) + c` with `x̄` rest positions. A cluster stores the elastic energy
//! `(κ/2) Σᵢ wᵢ |xᵢ − gᵢ|²` with compliance `1/κ` (0: rigid); fits are done relative to
//! the cluster's first member so that goals keep full precision far from the origin.
//!
//! The term also owns the clusters' warm start: their part of each particle's
//! correction in the last substep (`carry`), with which the next substep starts, so
//! that a body at rest holds its shape whatever the iteration count.

use super::colouring::{colour_clusters_by_bits, colour_clusters_by_lists};
use super::plastic::{PlasticCluster, PlasticSpec};
use super::rows::PARTICLE_BYTES;
use crate::config::SolverMode;
use crate::math::rotation::warm_start;
use crate::solver::term::Substep;
use glam::{Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Müller iterations per cluster per solver iteration (warm-started, so one suffices
/// where each iteration moves the particles only part of the way).
pub const ROTATION_ITERATIONS: u32 = 1;

/// Müller iterations per cluster per projective-dynamics iteration: its global step
/// takes the rotations at their word, so a rotation that lags holds the whole body
/// back.
pub const PROJECTIVE_ROTATION_ITERATIONS: u32 = 3;

/// Colour of a free cluster slot.
pub(in crate::solver) const FREE_SLOT: u32 = u32::MAX;

/// Most particles one layout holds: the kernel addresses them by byte offsets
/// (16 bytes per particle) in `u32`.
pub const MAX_SOLVER_PARTICLES: u64 = (u32::MAX as u64 + 1) / PARTICLE_BYTES as u64;

/// Arrays that patches append to are allocated with `1/PATCH_HEADROOM` spare room, so
/// that a cut does not copy them (tens of megabytes on a large body).
pub(in crate::solver) const PATCH_HEADROOM: usize = 8;

/// Clusters per parallel task.
pub(in crate::solver) const CLUSTERS_PER_TASK: usize = 128;

/// Particles per parallel task.
use crate::solver::particles::PARTICLES_PER_TASK;

/// Whether `mode` weights a particle `1/nᵢ` in each of its `nᵢ` clusters (Jacobi and
/// projective dynamics, whose particle steps sum over a particle's clusters) rather
/// than 1 (Gauss–Seidel, whose cluster steps need uniform weights to keep momentum).
pub(in crate::solver) fn weighted_by_count(mode: SolverMode) -> bool {
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

/// The compliance standing in for a rigid cluster's (0) in the Jacobi and projective
/// pull passes' per-cluster weights (stiffness `1/compliance`): 2⁻⁵⁰ ≈ 8.9e-16 1/Pa, so
/// far below any material's (steel's is about 5e-12) that next to a rigid cluster a
/// compliant one weighs nothing; a power of two, so that rigid clusters' weighted pulls
/// and steps round exactly as unweighted ones.
pub const RIGID_COMPLIANCE: f32 = 1.0 / (1u64 << 50) as f32;

/// The weight of a cluster of `compliance` in its members' Jacobi steps: its stiffness
/// `κ = 1/compliance` (see [`step_coefficients`]).
#[inline]
pub(in crate::solver) fn pull_weight(compliance: f32) -> f32 {
    1.0 / compliance.max(RIGID_COMPLIANCE)
}

/// A particle's step coefficients `(σ, a)` in the clusters' Jacobi pass: its step is
/// `σ Σₖ κₖ (gₖ − p) + a (s + k − p)` (see [`crate::solver::schemes::jacobi`]), each
/// cluster's pull weighted by its stiffness `κₖ` ([`pull_weight`]).
///
/// Setting the gradient of the substep's objective to zero for particle `i` alone,
/// with its clusters' goals held, gives `(mᵢ/dt²)(pᵢ − sᵢ) + Σₖ κₖ wᵢ (pᵢ − gᵢₖ) = 0`
/// (wᵢ = 1/nᵢ); with `K = Σₖ κₖ` (`stiffness`) and `I = mᵢ/dt²` (`inertia`) the step is
/// `σ = 1/(K + nᵢ I)`, `a = nᵢ I σ`. Clusters of one compliance `c` give the
/// unweighted average of their goals pulled toward the prediction by `a = Ic/(1 + Ic)`;
/// clusters of different compliances share a particle by stiffness, so a soft region
/// bends where a stiff one holds; next to a rigid cluster a compliant one weighs nothing
/// and `a` is 0 to rounding. A particle of inverse mass 0, or one in no cluster, does
/// not move.
#[inline]
pub(in crate::solver) fn step_coefficients(
    inv_count: f32,
    stiffness: f32,
    inertia: f32,
    inv_mass: f32,
) -> (f32, f32) {
    if inv_mass == 0.0 || inv_count == 0.0 || stiffness.is_nan() || stiffness <= 0.0 {
        return (0.0, 0.0);
    }
    let held = inertia / inv_count;
    let scale = 1.0 / (stiffness + held);
    (scale, held * scale)
}

/// One cluster as given to [`ClusterTerm::new`].
#[derive(Clone, Copy, Debug)]
pub struct ClusterSpec<'a> {
    /// Dense particle indices of the members.
    pub members: &'a [u32],
    /// Compliance `1/κ` of the cluster's elastic energy in m/N; 0: rigid (see
    /// [`crate::config::Material::compliance`]).
    pub compliance: f32,
    /// Warm-start rotation.
    pub rotation: Quat,
    /// Plasticity ([`super::plastic`]); `None`: elastic.
    pub plastic: Option<PlasticSpec<'a>>,
}

/// The cluster term; see the module docs. Fields are the solver's (the schemes' kernels
/// read them); outside it, use the methods.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ClusterTerm {
    /// The clusters' part of each particle's correction in the last solve; the next
    /// solve starts from the prediction plus this (the warm start).
    pub(in crate::solver) carry: Vec<Vec3A>,
    /// The substep time step the carry was made with (a change drops it).
    pub(in crate::solver) carry_dt: f32,
    /// Counts the times the carry was dropped: a scheme's state that holds parts of it
    /// (Gauss–Seidel's per membership) is dropped with it.
    pub(in crate::solver) carry_epoch: u64,
    /// Per particle: the summed stiffness of its clusters ([`pull_weight`]), or their
    /// count when they all share one compliance.
    pub(in crate::solver) particle_stiffness: Vec<f32>,
    /// The compliance every live cluster shares, if they do: then the pulls go
    /// unweighted, each counting 1 (the stiffness of every cluster divides out of the
    /// step, and the inertia is taken relative to it).
    pub(in crate::solver) shared_compliance: Option<f32>,
    /// Whether any cluster is compliant (else the particle pass has no pull toward the
    /// prediction to add).
    pub(in crate::solver) compliant: bool,
    /// Whether members are weighted `1/nᵢ` (see [`weighted_by_count`]; also Gauss–Seidel
    /// with a compliant cluster, whose energy must be Jacobi's).
    pub(in crate::solver) count_weights: bool,
    /// Per particle: the warm-start weight of the current substep.
    pub(in crate::solver) warm_weight: Vec<f32>,
    /// Per particle: the scale of the summed pulls and the pull toward the prediction in
    /// its Jacobi step ([`step_coefficients`]), for the current substep.
    pub(in crate::solver) step_scale: Vec<f32>,
    pub(in crate::solver) anchor: Vec<f32>,
    /// Whether the clusters changed since the per-particle coefficients were computed.
    pub(in crate::solver) coefficients_stale: bool,
    /// Warm-start rotation per cluster slot.
    pub(in crate::solver) rotations: Vec<Quat>,
    /// Per cluster slot: its rotation when the last substep began ([`super::spin`]).
    pub(in crate::solver) substep_start: Vec<Quat>,
    /// Whether the next substep has no last turn to carry, so fits every cluster's turn
    /// afresh ([`super::spin`]).
    pub(in crate::solver) turns_forgotten: bool,
    /// The scheme the weights and batches were made for.
    pub(in crate::solver) mode: SolverMode,
    /// Rest position per particle.
    pub(in crate::solver) rest: Vec<Vec3A>,
    /// `1/nᵢ` per particle (0 for a particle in no cluster).
    pub(in crate::solver) inv_count: Vec<f32>,
    /// Number of clusters each particle is in.
    pub(in crate::solver) member_count: Vec<u32>,
    /// The cluster slots of each particle, ascending: particle `i`'s are
    /// `particle_slots[slot_starts[i]..slot_starts[i + 1]]`. Rebuilt with the
    /// coefficients, so that a per-particle pass can visit its clusters in slot order
    /// ([`ClusterTerm::blend_orientations`]).
    pub(in crate::solver) slot_starts: Vec<u32>,
    pub(in crate::solver) particle_slots: Vec<u32>,
    /// Per cluster slot: `[start, end)` of its memberships (empty for a free slot).
    pub(in crate::solver) cluster_range: Vec<[u32; 2]>,
    /// Per cluster slot: its colour ([`FREE_SLOT`] for a free slot).
    pub(in crate::solver) colour_of: Vec<u32>,
    /// Per particle: bit `c` set when one of its clusters has colour `c` (empty when the
    /// colouring needs more than 64 colours; such a layout is not patched).
    pub(in crate::solver) particle_colours: Vec<u64>,
    /// Cluster slots freed by patches, reused by later additions.
    pub(in crate::solver) free_slots: Vec<u32>,
    /// Memberships in the member arrays that belong to no cluster any more.
    pub(in crate::solver) garbage: usize,
    /// The member particles of every cluster slot (`cluster_range` into it).
    pub(in crate::solver) member_particle: Vec<u32>,
    /// Per cluster slot: the weighted rest centroid `x̄_c`; member `i`'s rest offset is
    /// `x̄ᵢ − x̄_c`, its matching weight [`ClusterTerm::weight`].
    pub(in crate::solver) rest_centroid: Vec<Vec3A>,
    /// Per cluster slot: `Σ w q`, the rounding residue of the weighted rest offsets.
    pub(in crate::solver) offset_bias: Vec<Vec3A>,
    /// Per cluster slot: `1 / Σ w`.
    pub(in crate::solver) inv_weight_sum: Vec<f32>,
    /// Per cluster slot: compliance (m/N).
    pub(in crate::solver) compliance: Vec<f32>,
    /// The clusters in batches of eight, as the kernel reads them.
    pub(in crate::solver) batches: super::rows::Batches,
    /// Per cluster slot: its plasticity, `None` for an elastic cluster (empty, or
    /// shorter than the slots, when the later slots are elastic).
    pub(in crate::solver) plastic: Vec<Option<PlasticCluster>>,
}

impl ClusterTerm {
    /// Builds the term for particles with the given rest positions and clusters, for
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
            "{} particles in one solver term (at most {MAX_SOLVER_PARTICLES})",
            rest.len()
        );
        let clusters: Vec<ClusterSpec<'a>> = clusters.into_iter().collect();
        let n = rest.len();
        let rest: Vec<Vec3A> = rest.iter().map(|r| Vec3A::from(*r)).collect();
        let compliant = clusters.iter().any(|c| c.compliance > 0.0);
        let mut term = ClusterTerm {
            count_weights: weighted_by_count(mode) || compliant,
            carry: vec![Vec3A::ZERO; n],
            coefficients_stale: true,
            member_count: vec![0; n],
            mode,
            rest,
            ..Default::default()
        };
        let memberships: usize = clusters.iter().map(|c| c.members.len()).sum();
        // headroom for the clusters later patches add: growing the array would copy it
        term.member_particle
            .reserve_exact(memberships + memberships / PATCH_HEADROOM);
        let count = clusters.len();
        term.cluster_range.reserve_exact(count);
        term.colour_of.reserve_exact(count);
        term.compliance.reserve_exact(count);
        term.rotations.reserve_exact(count);
        term.substep_start.reserve_exact(count);
        term.offset_bias.reserve_exact(count);
        term.rest_centroid.reserve_exact(count);
        term.inv_weight_sum.reserve_exact(count);
        for c in &clusters {
            term.push_cluster(c, None, 0);
        }
        term.inv_count = term
            .member_count
            .iter()
            .map(|c| if *c > 0 { 1.0 / *c as f32 } else { 0.0 })
            .collect();
        for k in 0..clusters.len() {
            term.fill_constants(k);
        }
        let cluster_start: Vec<u32> = std::iter::once(0)
            .chain(term.cluster_range.iter().map(|r| r[1]))
            .collect();
        match colour_clusters_by_bits(&cluster_start, &term.member_particle, n) {
            Some((colours, bits)) => {
                term.colour_of = colours;
                term.particle_colours = bits;
            }
            // more than 64 colours: colour by the inverse lists; the term cannot be
            // patched (no colour bits)
            None => {
                term.colour_of = colour_clusters_by_lists(&cluster_start, &term.member_particle, n)
            }
        }
        term.build_batches();
        term
    }

    /// Appends cluster `spec` in `slot` (a new slot when `None`) with colour `colour`;
    /// counts its memberships. Its constants are filled later ([`Self::fill_constants`]).
    pub(in crate::solver) fn push_cluster(
        &mut self,
        spec: &ClusterSpec,
        slot: Option<usize>,
        colour: u32,
    ) -> usize {
        let start = self.member_particle.len() as u32;
        self.member_particle.extend_from_slice(spec.members);
        for &m in spec.members {
            self.member_count[m as usize] += 1;
        }
        let range = [start, self.member_particle.len() as u32];
        let compliance = spec.compliance;
        // the batched fit expects unit warm starts
        let rotation = warm_start(spec.rotation);
        let k = match slot {
            Some(k) => {
                self.cluster_range[k] = range;
                self.colour_of[k] = colour;
                self.compliance[k] = compliance;
                self.rotations[k] = rotation;
                self.substep_start[k] = rotation;
                k
            }
            None => {
                self.cluster_range.push(range);
                self.colour_of.push(colour);
                self.compliance.push(compliance);
                self.rotations.push(rotation);
                self.substep_start.push(rotation);
                self.offset_bias.push(Vec3A::ZERO);
                self.rest_centroid.push(Vec3A::ZERO);
                self.inv_weight_sum.push(0.0);
                self.cluster_range.len() - 1
            }
        };
        self.set_plastic(k, spec.members.len(), spec.plastic);
        k
    }

    /// The matching weight of particle `m` in every cluster: `1/nᵢ` for Jacobi and
    /// projective dynamics (with the current membership counts), 1 for Gauss–Seidel.
    #[inline]
    pub(in crate::solver) fn weight(&self, m: u32) -> f32 {
        if self.count_weights {
            self.inv_count[m as usize]
        } else {
            1.0
        }
    }

    /// Computes the weighted rest centroid, offset bias and weight sum of cluster `k`
    /// from the rest positions and (Jacobi) the current membership counts.
    pub(in crate::solver) fn fill_constants(&mut self, k: usize) {
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
        self.rest_centroid[k] = weighted / total;
        // Σ w q is zero up to rounding (and a plastic shift); the fit subtracts its
        // rotated residue so that every cluster's pull has exactly zero momentum.
        let bias: Vec3A = (members.iter().enumerate())
            .map(|(j, m)| self.rest_offset(k, j, *m) * self.weight(*m))
            .sum();
        self.offset_bias[k] = bias;
        self.inv_weight_sum[k] = 1.0 / total;
    }

    /// Müller iterations per cluster fit under this term's scheme.
    #[inline(always)]
    pub(in crate::solver) fn rotation_iterations(&self) -> u32 {
        if self.mode == SolverMode::Projective {
            PROJECTIVE_ROTATION_ITERATIONS
        } else {
            ROTATION_ITERATIONS
        }
    }

    /// The scheme this term was built for.
    pub fn mode(&self) -> SolverMode {
        self.mode
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.rest.len()
    }

    /// Number of clusters.
    pub fn cluster_count(&self) -> usize {
        self.colour_of.iter().filter(|c| **c != FREE_SLOT).count()
    }

    /// Number of memberships (sum of cluster sizes).
    pub fn membership_count(&self) -> usize {
        self.member_particle.len() - self.garbage
    }

    /// The number of clusters each particle is in, kept up to date by every patch.
    pub fn member_counts(&self) -> &[u32] {
        &self.member_count
    }

    /// Warm-start rotation of every cluster slot (free slots included).
    pub fn rotations(&self) -> &[Quat] {
        &self.rotations
    }

    /// Brings the per-particle coefficients up to date (after a change of clusters),
    /// computes this substep's step coefficients and warm-start weights for particles of
    /// inverse masses `inv_mass` in `step`, and starts every particle from its prediction
    /// plus its weighted carry. `global`: projective dynamics (whose global step corrects
    /// every mode at once, so it takes the whole carry). `previous`: the positions the
    /// substep started from (see [`super::spin`]). Clears `corrections`.
    pub(in crate::solver) fn begin_substep(
        &mut self,
        previous: &[Vec3A],
        positions: &mut [Vec3A],
        corrections: &mut [Vec3A],
        inv_mass: &[f32],
        step: &Substep,
        global: bool,
    ) {
        if self.coefficients_stale {
            self.refresh_coefficients();
        }
        let (dt, iterations) = (step.dt, step.iterations);
        if self.carry_dt != dt {
            self.carry_dt = dt;
            self.forget_carry();
        }
        self.turn_warm_starts();
        if std::mem::take(&mut self.turns_forgotten) && previous.len() == positions.len() {
            self.fit_turns(previous, positions);
        }
        let inv_dt2 = 1.0 / (dt * dt);
        let n = positions.len();
        for scratch in [
            &mut self.step_scale,
            &mut self.anchor,
            &mut self.warm_weight,
        ] {
            scratch.resize(n, 0.0);
        }
        let (inv_count, stiffness) = (&self.inv_count, &self.particle_stiffness);
        // (unweighted pulls count 1 each: the inertia relative to a cluster's stiffness)
        let inertia_unit = self.shared_compliance.unwrap_or(1.0);
        // one pass: each particle's step coefficients, its warm-start weight, and its
        // start at the prediction plus the weighted carry
        positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.carry.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.step_scale.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.anchor.par_chunks_mut(PARTICLES_PER_TASK))
            .zip(self.warm_weight.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(
                |(task, (((((p, carry), correction), scale), anchor), weight))| {
                    let range = task * PARTICLES_PER_TASK..task * PARTICLES_PER_TASK + p.len();
                    let read = inv_count[range.clone()]
                        .iter()
                        .zip(&stiffness[range.clone()])
                        .zip(&inv_mass[range]);
                    let write = p
                        .iter_mut()
                        .zip(carry)
                        .zip(correction)
                        .zip(scale.iter_mut().zip(anchor).zip(weight));
                    for (((&inv_count, &stiffness), &inv_mass), (((p, carry), correction), s)) in
                        read.zip(write)
                    {
                        let ((scale, anchor), weight) = s;
                        (*scale, *anchor) = step_coefficients(
                            inv_count,
                            stiffness,
                            inertia_unit * inv_dt2 / inv_mass.max(f32::MIN_POSITIVE),
                            inv_mass,
                        );
                        // (a particle held still, or a carry a repaired particle left, starts
                        // afresh; one in no cluster — of the oriented model — is moved by
                        // terms whose local steps lag the global step, so it takes the
                        // share that keeps a lagging mode stable)
                        *weight = if inv_mass == 0.0 || !carry.is_finite() {
                            0.0
                        } else {
                            warm_start_weight(*anchor, iterations, global && inv_count > 0.0)
                        };
                        *carry *= *weight;
                        *p += *carry;
                        *correction = Vec3A::ZERO;
                    }
                },
            );
    }

    /// Recomputes each particle's summed cluster stiffness from the current clusters.
    pub(in crate::solver) fn refresh_coefficients(&mut self) {
        let n = self.rest.len();
        let mut live = (self.cluster_range.iter().zip(&self.compliance))
            .filter(|(range, _)| range[0] < range[1])
            .map(|(_, c)| *c);
        let first = live.next();
        self.shared_compliance = first.filter(|c| live.all(|other| other == *c));
        let mut sum = vec![0.0f32; n];
        for (k, range) in self.cluster_range.iter().enumerate() {
            let members = &self.member_particle[range[0] as usize..range[1] as usize];
            let weight = self.pull_weight_of(k);
            for &m in members {
                sum[m as usize] += weight;
            }
        }
        self.compliant = self
            .cluster_range
            .iter()
            .zip(&self.compliance)
            .any(|(range, c)| range[0] < range[1] && *c > 0.0);
        self.particle_stiffness = sum;
        self.index_slots_by_particle();
        self.coefficients_stale = false;
        self.forget_carry();
    }

    /// The weight of cluster slot `k`'s pulls in the Jacobi step: its stiffness
    /// ([`pull_weight`]), or 1 when every cluster shares one compliance.
    #[inline]
    pub(in crate::solver) fn pull_weight_of(&self, k: usize) -> f32 {
        if self.shared_compliance.is_some() {
            1.0
        } else {
            pull_weight(self.compliance[k])
        }
    }

    /// Drops the warm start (after the clusters or the time step changed); the schemes'
    /// own warm-start state follows [`ClusterTerm::carry_epoch`].
    pub(in crate::solver) fn forget_carry(&mut self) {
        self.substep_start.clone_from(&self.rotations);
        self.turns_forgotten = true;
        self.carry_epoch += 1;
        self.carry.clear();
        self.carry.resize(self.rest.len(), Vec3A::ZERO);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_coefficients_average_the_goals_when_rigid_and_weigh_inertia_when_compliant() {
        let rigid = pull_weight(0.0);
        // 4 rigid clusters: their pulls, each weighted by the rigid stiffness, averaged
        let (scale, anchor) = step_coefficients(0.25, 4.0 * rigid, 1.0, 1.0);
        assert!(
            (scale * rigid - 0.25).abs() < 1e-6 && anchor < 1e-12,
            "{scale} {anchor}"
        );
        assert_eq!(step_coefficients(0.25, 1.0, 1.0, 0.0), (0.0, 0.0), "pinned");
        assert_eq!(
            step_coefficients(0.0, 0.0, 1.0, 1.0),
            (0.0, 0.0),
            "in no cluster"
        );
        // 4 clusters of compliance ½, inertia 1: K = 8, n I = 4, σ = 1/12, a = 4/12; each
        // pull weighs κ = 2, so the goals' share is 2σ per cluster, 8/12 in all
        let (scale, anchor) = step_coefficients(0.25, 4.0 * pull_weight(0.5), 1.0, 1.0);
        assert!((scale - 1.0 / 12.0).abs() < 1e-7 && (anchor - 4.0 / 12.0).abs() < 1e-7);
        // a rigid cluster beside a compliant one takes the particle
        let (scale, _) = step_coefficients(0.5, rigid + pull_weight(1e-6), 1.0, 1.0);
        assert!((scale * rigid - 1.0).abs() < 1e-6 && scale * pull_weight(1e-6) < 1e-8);
    }
}
