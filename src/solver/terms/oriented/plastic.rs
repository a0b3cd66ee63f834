//! Plasticity of the oriented groups (material `yield_strain`, `creep`,
//! `max_plastic_strain`): where a group's shape strays from its fitted rigid motion by
//! more than the yield strain, its rest shape creeps toward the deformed shape, up to the
//! largest plastic strain. Rest shapes here are the groups' own; the lattice's rest
//! positions, which the reconstruction and the fidelity comparison use, never change.
//!
//! A group's strain is `ε = √(Σ|dⱼ|² / Σ|r̄ⱼ|²)` with `dⱼ = Rᵀ(xⱼ − c) − r̄ⱼ` the
//! deformation of member `j` in the group's rest frame and `r̄ⱼ` its rest offset. Past
//! the yield, each rest offset takes the share `min(creep·dt, 1)·(1 − ε_yield/ε)` of
//! its deformation every substep (so the elastic strain left tends to the yield); the
//! rest shape's own strain from the lattice's is then capped at the maximum.

use super::fit::fit;
use super::groups::BodyGroups;
use glam::{Quat, Vec3A};

/// Lets every group of `body` yield at `positions` (the last substep's solved positions)
/// over a substep of `dt` (see the module docs). Members are weighted alike.
pub fn creep(body: &mut BodyGroups, positions: &[Vec3A], orientations: &[Quat], dt: f32) {
    let Some(plastic) = body.plastic.take() else {
        return;
    };
    let share = (plastic.creep * dt).min(1.0);
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
        let offsets: Vec<(Vec3A, Vec3A)> = members
            .iter()
            .zip(rest)
            .map(|(&m, r)| {
                let offset = *r - f.rest_centroid;
                (offset, back * (positions[m as usize] - f.centroid) - offset)
            })
            .collect();
        let deformed: f32 = offsets.iter().map(|(_, d)| d.length_squared()).sum();
        let spread: f32 = offsets.iter().map(|(o, _)| o.length_squared()).sum();
        if spread == 0.0 {
            continue;
        }
        let strain = (deformed / spread).sqrt();
        // (a NaN strain yields nothing either)
        if strain.is_nan() || strain <= plastic.yield_strain {
            continue;
        }
        let take = share * (1.0 - plastic.yield_strain / strain);
        let lattice = &plastic.lattice_rest[range.clone()];
        let lattice_centroid = lattice.iter().copied().sum::<Vec3A>() / lattice.len() as f32;
        let moved: Vec<Vec3A> = offsets.iter().map(|(o, d)| *o + *d * take).collect();
        // the rest shape's drift from the lattice's, capped
        let centroid = moved.iter().copied().sum::<Vec3A>() / moved.len() as f32;
        let (mut drift, mut base) = (0.0f32, 0.0f32);
        for (m, l) in moved.iter().zip(lattice) {
            drift += (*m - centroid - (*l - lattice_centroid)).length_squared();
            base += (*l - lattice_centroid).length_squared();
        }
        let plastic_strain = (drift / base.max(f32::MIN_POSITIVE)).sqrt();
        let keep = if plastic_strain > plastic.max_strain {
            plastic.max_strain / plastic_strain
        } else {
            1.0
        };
        for ((r, m), l) in body.rest[range].iter_mut().zip(&moved).zip(lattice) {
            let lattice_offset = *l - lattice_centroid;
            *r = lattice_centroid + lattice_offset + (*m - centroid - lattice_offset) * keep;
        }
    }
    body.plastic = Some(plastic);
}
