//! The coloured Gauss–Seidel scheme: colour after colour, every cluster of the colour is
//! fitted to the current positions and moves its members toward their goals at once.
//! Clusters of one colour share no particle (see [`super::colour_clusters`]), so they
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

use super::SolverLayout;
use super::batch::{BatchKernel, FitRow, PARTICLE_BYTES};
use super::sweep::Disjoint;
use crate::math::lanes::LANES;
use crate::math::simd::Lane;
use glam::{Quat, Vec3A};

impl SolverLayout {
    /// One sweep over all colours: every cluster (eight at a time) is fitted to the
    /// current positions and moves its unpinned members by their XPBD step.
    pub(super) fn sweep_colours(&mut self, dt: f32) {
        if self.compliant {
            self.sweep::<true>(dt);
        } else {
            self.sweep::<false>(dt);
        }
    }

    /// [`Self::sweep_colours`]; `COMPLIANT`: whether any cluster is (else every `β` is
    /// 0, the step is the pull, and the memberships' corrections are not kept).
    fn sweep<const COMPLIANT: bool>(&mut self, dt: f32) {
        // one accumulated correction per membership row and lane, zero after a change
        // of clusters or time step
        let rows = if COMPLIANT {
            self.row_count() * LANES
        } else {
            0
        };
        if self.membership_carry.len() != rows {
            self.membership_carry.clear();
            self.membership_carry.resize(rows, Vec3A::ZERO);
        }
        let inv_dt2 = 1.0 / (dt * dt);
        let positions = Disjoint::new(&mut self.positions);
        let carry = Disjoint::new(&mut self.carry);
        let membership_carry = Disjoint::new(&mut self.membership_carry);
        let rotations = Disjoint::new(&mut self.rotations);
        let this = &*self;
        // `self`'s other arrays are only read; positions, carries and rotations go
        // through the `Disjoint` pointers (no reference to them is alive in a colour).
        this.for_each_batch_by_colour(&SweepKernel::<COMPLIANT> {
            layout: this,
            inv_dt2,
            positions,
            carry,
            membership_carry,
            rotations,
        });
    }
}

/// A sweep's work on one batch (see [`SolverLayout::sweep_colours`]).
struct SweepKernel<'a, const COMPLIANT: bool> {
    layout: &'a SolverLayout,
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
        let this = self.layout;
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
                    let inv_mass = this.inv_mass[m];
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
