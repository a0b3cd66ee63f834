//! The coloured Gauss–Seidel scheme: colour after colour, every cluster of the colour is
//! fitted to the current positions and moves its members toward their goals at once.
//! Clusters of one colour share no particle (see [`crate::solver::clusters::colouring`]), so they
//! run in parallel and the result does not depend on their order or the thread count.
//!
//! A member's step is XPBD's (Macklin et al. 2016) for the constraint `pᵢ − gᵢ = 0`
//! with compliance `α`: `Δdᵢ = ((gᵢ − pᵢ) − β dᵢ)/(1 + β)`, `β = α mᵢ/dt²`, where `dᵢ`
//! is the correction this membership has made in the substep (`λ` over the particle's
//! inverse mass), and `α/wᵢ` the membership's compliance under the clusters' energy
//! `(κ/2) Σᵢ wᵢ |xᵢ − gᵢ|²`. Iterated, it solves the same implicit step as Jacobi. With
//! compliant clusters the members are weighted `wᵢ = 1/nᵢ` as in Jacobi, so that the
//! energies (and the static shapes) agree; a step then moves momentum, which the
//! converged step gives back. Rigid clusters (`β` = 0) weigh every member 1, which
//! keeps each cluster's step free of momentum.

use crate::math::lanes::LANES;
use crate::math::simd::Lane;
use crate::solver::clusters::fit::BatchKernel;
use crate::solver::clusters::rows::FitRow;
use crate::solver::clusters::rows::PARTICLE_BYTES;
use crate::solver::clusters::term::ClusterTerm;
use crate::solver::disjoint::Disjoint;
use crate::solver::particles::Particles;
use glam::{Quat, Vec3A};

/// The Gauss–Seidel scheme's state: each membership's accumulated correction in this
/// substep (XPBD's `λ` over the particle's mass), by particle row of the batches × lane.
/// It holds the parts of the clusters' warm start, so it is dropped with it.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct GaussSeidel {
    pub(in crate::solver) membership_carry: Vec<Vec3A>,
    /// The clusters' [`ClusterTerm::carry_epoch`] the memberships' parts belong to.
    epoch: u64,
}

impl GaussSeidel {
    /// Drops the memberships' parts when the clusters dropped their carry; then scales
    /// them by the particles' warm-start weights of this substep, as the carry was.
    pub fn begin_substep(&mut self, clusters: &ClusterTerm) {
        if self.epoch != clusters.carry_epoch {
            self.epoch = clusters.carry_epoch;
            self.membership_carry.clear();
        }
        let particles = clusters.batches.membership_particles();
        for (carry, m) in self.membership_carry.iter_mut().zip(particles) {
            *carry *= clusters.warm_weight[m as usize];
        }
    }

    /// Whether the memberships hold parts of the warm start (a compliant layout's).
    pub fn holds_carry(&self) -> bool {
        !self.membership_carry.is_empty()
    }

    /// Sets the memberships' parts for a solve restarted with the clusters' carry
    /// `carry`: each particle's displacement shared equally among its memberships.
    pub fn restart(&mut self, clusters: &ClusterTerm) {
        let (carry, inv_count) = (&clusters.carry, &clusters.inv_count);
        self.epoch = clusters.carry_epoch;
        self.membership_carry = clusters
            .batches
            .membership_particles()
            .map(|m| carry[m as usize] * inv_count[m as usize])
            .collect();
        // (padding slots name a member too, but no step reads or writes theirs)
    }

    /// One sweep over all colours: every cluster (eight at a time) is fitted to the
    /// current positions and moves its members of non-zero inverse mass by their XPBD
    /// step.
    pub fn sweep(&mut self, clusters: &mut ClusterTerm, particles: &mut Particles, dt: f32) {
        if clusters.compliant {
            self.sweep_with::<true>(clusters, particles, dt);
        } else {
            self.sweep_with::<false>(clusters, particles, dt);
        }
    }

    /// [`Self::sweep`]; `COMPLIANT`: whether any cluster is (else every `β` is 0, the
    /// step is the pull, and the memberships' corrections are not kept).
    fn sweep_with<const COMPLIANT: bool>(
        &mut self,
        clusters: &mut ClusterTerm,
        particles: &mut Particles,
        dt: f32,
    ) {
        // one accumulated correction per membership row and lane, zero after a change
        // of clusters or time step
        let rows = if COMPLIANT {
            clusters.row_count() * LANES
        } else {
            0
        };
        if self.membership_carry.len() != rows {
            self.membership_carry.clear();
            self.membership_carry.resize(rows, Vec3A::ZERO);
        }
        let inv_dt2 = 1.0 / (dt * dt);
        let positions = Disjoint::new(&mut particles.positions);
        let carry = Disjoint::new(&mut clusters.carry);
        let membership_carry = Disjoint::new(&mut self.membership_carry);
        let rotations = Disjoint::new(&mut clusters.rotations);
        let this = &*clusters;
        // the clusters' other arrays and the inverse masses are only read; positions,
        // carries and rotations go through the `Disjoint` pointers (no reference to them
        // is alive in a colour)
        this.for_each_batch_by_colour(&SweepKernel::<COMPLIANT> {
            clusters: this,
            inv_mass: &particles.inv_mass,
            inv_dt2,
            positions,
            carry,
            membership_carry,
            rotations,
        });
    }
}

/// A sweep's work on one batch (see [`GaussSeidel::sweep`]).
struct SweepKernel<'a, const COMPLIANT: bool> {
    clusters: &'a ClusterTerm,
    /// Inverse masses.
    inv_mass: &'a [f32],
    /// `1/dt²`.
    inv_dt2: f32,
    /// Per particle: its position.
    positions: Disjoint<Vec3A>,
    /// Per particle: its moves this substep.
    carry: Disjoint<Vec3A>,
    /// Per membership row and lane: its correction this substep (compliant only).
    membership_carry: Disjoint<Vec3A>,
    /// Per cluster: its warm-start rotation.
    rotations: Disjoint<Quat>,
}

impl<const COMPLIANT: bool> BatchKernel for SweepKernel<'_, COMPLIANT> {
    #[inline(always)]
    fn batch<L: Lane>(&self, b: usize, fit_rows: &mut Vec<FitRow>) {
        let this = self.clusters;
        let (positions, carry, membership_carry) =
            (self.positions, self.carry, self.membership_carry);
        // each lane's cluster's compliance over dt² (unread when no cluster is)
        let compliance = if COMPLIANT {
            this.lane_clusters(b)
                .map(|k| k.map_or(0.0, |k| this.compliance[k] * self.inv_dt2))
        } else {
            [0.0; LANES]
        };
        let first_row = this.first_row(b);
        // SAFETY (both blocks): this task owns the batch's clusters, their rotations,
        // their membership rows and their members' positions and carries for the colour
        // (see `Disjoint`); member indices were bounds-checked when the layout was built.
        unsafe {
            this.fit_batch::<L>(b, fit_rows, positions.as_ptr(), self.rotations, |row| {
                for (l, &compliance) in compliance.iter().enumerate() {
                    let m = (row.at[l] / PARTICLE_BYTES) as usize;
                    let inv_mass = self.inv_mass[m];
                    if row.row < row.size[l] as usize && inv_mass != 0.0 {
                        let step = if COMPLIANT {
                            let at = (first_row + row.row) * LANES + l;
                            // β = α mᵢ / (dt² wᵢ)
                            let beta = compliance / (inv_mass * this.inv_count[m]);
                            let done = membership_carry.read(at);
                            let step = (row.pull[l] - done * beta) / (1.0 + beta);
                            membership_carry.write(at, done + step);
                            step
                        } else {
                            row.pull[l]
                        };
                        positions.write(m, row.position.lane(l) + step);
                        carry.write(m, carry.read(m) + step);
                    }
                }
            })
        };
    }
}
