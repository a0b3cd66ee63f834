//! Plasticity of the oriented groups (material `yield_strain`, `creep`,
//! `max_plastic_strain`): each substep every group of a plastic body is fitted to the
//! last substep's solved positions, and its rest shape flows as
//! [`crate::solver::yielding`] describes (members weighted alike). The groups' rest
//! shapes are their own; the lattice's rest positions never change.

use super::fit::fit;
use super::groups::BodyGroups;
use crate::solver::yielding::flow;
use glam::{Quat, Vec3A};
use smallvec::SmallVec;

/// Per-member offsets of one group (an implicit group has at most seven members).
type Offsets = SmallVec<[Vec3A; 8]>;

/// Lets every group of `body` yield at `positions` (the last substep's solved positions)
/// over a substep of `dt`; returns whether any group's rest shape changed.
pub fn creep(body: &mut BodyGroups, positions: &[Vec3A], orientations: &[Quat], dt: f32) -> bool {
    let Some(plastic) = body.plastic.take() else {
        return false;
    };
    let mut any = false;
    for g in &body.groups {
        let range = body.range(g);
        let members = &body.members[range.clone()];
        let rest = &body.rest[range.clone()];
        let f = fit(
            members,
            rest,
            &body.moment[range.clone()],
            |_| 1.0,
            |d| positions[d],
            |d| orientations[d],
            orientations[members[0] as usize],
        );
        // each member's rest offset, and its deformation in the group's rest frame
        let back = f.rotation.conjugate();
        let mut offsets: Offsets = rest.iter().map(|r| *r - f.rest_centroid).collect();
        let deformation: Offsets = members
            .iter()
            .zip(&offsets)
            .map(|(&m, o)| back * (positions[m as usize] - f.centroid) - *o)
            .collect();
        let lattice = &plastic.lattice_rest[range.clone()];
        let lattice_centroid = lattice.iter().copied().sum::<Vec3A>() / lattice.len() as f32;
        let lattice: Offsets = lattice.iter().map(|l| *l - lattice_centroid).collect();
        let yielded = flow(
            &plastic.yielding,
            dt,
            |_| 1.0,
            &lattice,
            &mut offsets,
            &deformation,
        );
        any |= yielded;
        if yielded {
            for (r, o) in body.rest[range].iter_mut().zip(&offsets) {
                *r = lattice_centroid + *o;
            }
        }
    }
    body.plastic = Some(plastic);
    any
}
