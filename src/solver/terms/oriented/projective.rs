//! The oriented groups in projective dynamics (Bouaziz et al. 2014): each membership
//! `j` stores `(wⱼ/2)|xⱼ − c − R(x̄ⱼ − c̄)|²` with `c = Σₖ ωₖ xₖ` the fit's weighted
//! centroid (ωₖ its normalised weights, constant while the particles held still are),
//! so its linear part `xⱼ − c` is constant and its projection is the fitted goal offset.
//! The group adds `Σⱼ wⱼ (eⱼ − Σₖ ωₖ eₖ)(…)ᵀ` to the global matrix, with `wⱼ = 1/αⱼ` (a
//! hard membership: the solver's stiffest weight). The local step fits every group at
//! the current positions and turns its centre (or its members) as the sweeps do.

use super::fit::fit;
use super::groups::Turns;
use super::{Oriented, warm};
use crate::solver::term::{ProjectiveTerm, Substep, Unknowns};
use glam::{DVec3, Quat, Vec3A};

/// The stiffness of a hard membership (compliance 0) in the global matrix, relative to
/// its group's mean `m/dt²`. The groups are a body's own elasticity, so a hard one must
/// hold a long thin body as a rigid part would: at the matrix's usual
/// [`crate::solver::term::STIFFEST`] a 24-particle rod of hard groups droops by several
/// spacings. Contacts' pushes pile up into velocity against so stiff a body (see
/// `STIFFEST`), so bodies that touch things are better given a compliance.
pub const HARD_GROUP: f64 = 1e4;

impl ProjectiveTerm for Oriented {
    fn version(&self) -> u64 {
        self.version
    }

    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    ) {
        for body in &self.bodies {
            for g in &body.groups {
                let range = body.range(g);
                let members = &body.members[range.clone()];
                let weights: Vec<f64> = range
                    .clone()
                    .map(|k| {
                        unknowns.weight_up_to(body.compliance[k], members, step.dt, HARD_GROUP)
                    })
                    .collect();
                let total: f64 = weights.iter().sum();
                let omega = centroid_weights(members, unknowns);
                // H_ab = w_a δ_ab − w_a ω_b − w_b ω_a + W ω_a ω_b
                for (a, &da) in members.iter().enumerate() {
                    let Some(ra) = unknowns.row(da) else { continue };
                    for (b, &db) in members[..=a].iter().enumerate() {
                        let Some(rb) = unknowns.row(db) else { continue };
                        let (wa, wb, oa, ob) = (weights[a], weights[b], omega[a], omega[b]);
                        let mut value = total * oa * ob - wa * ob - wb * oa;
                        if a == b {
                            value += wa;
                        }
                        entries.push((ra.max(rb), ra.min(rb), value));
                    }
                }
            }
        }
    }

    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        orientations: &mut [Quat],
        forces: &mut [DVec3],
    ) {
        for body in &self.bodies {
            for g in &body.groups {
                let range = body.range(g);
                let members = &body.members[range.clone()];
                let f = fit(
                    members,
                    &body.rest[range.clone()],
                    &body.moment[range.clone()],
                    // (the energy's weights, alike in a group: then the fit is the
                    // local step's minimiser, and the iteration cannot gain energy)
                    |_| 1.0,
                    |d| positions[d],
                    |d| orientations[d],
                    warm(body, g, |d| orientations[d]),
                );
                // force_a = w_a e_a − ω_a Σ_j w_j e_j, e_j = goal_j − x_j
                let mut sum = DVec3::ZERO;
                let mut each = Vec::with_capacity(members.len());
                for k in range.clone() {
                    let d = body.members[k] as usize;
                    let w = unknowns.weight_up_to(body.compliance[k], members, step.dt, HARD_GROUP);
                    let e = (f.goal(body.rest[k]) - positions[d]).as_dvec3() * w;
                    sum += e;
                    each.push(e);
                }
                let omega = centroid_weights(members, unknowns);
                for ((k, e), o) in range.zip(each).zip(omega) {
                    let d = body.members[k] as usize;
                    forces[d] += e - sum * o;
                    let turns = match g.turns {
                        Turns::Centre(c) => c as usize == d,
                        Turns::All => body.moment[k] != Vec3A::ZERO,
                    };
                    if turns && unknowns.row(d as u32).is_some() {
                        orientations[d] = f.rotation;
                    }
                }
            }
        }
    }
}

/// The normalised weights `ωₖ` of the fit's centroid of the group of `members`.
fn centroid_weights(members: &[u32], unknowns: &Unknowns) -> Vec<f64> {
    let _ = unknowns;
    vec![1.0 / members.len() as f64; members.len()]
}
