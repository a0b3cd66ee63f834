//! What a body's particles are grouped into besides its material: explicit
//! shape-matching groups (rigid parts and the joints between them, SPEC §5) and
//! per-particle compliance (stiffness regions). Both are given when a body spawns and
//! never written after; what a cut does to them is derived from the lattice
//! ([`ParticleGroups::explicit_pieces`]).

use super::graph::connected_components;
use super::lattice::Lattice;
use serde::{Deserialize, Serialize};

/// An explicit shape-matching group: its particles move as one rigid part of the given
/// compliance (0: rigid) and all take the group's rotation.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ExplicitGroup {
    /// Body-local particle indices, ascending.
    pub members: Vec<u32>,
    /// Compliance `1/E` in 1/Pa, as the material's.
    pub compliance: f32,
}

/// A body's explicit groups and per-particle compliances (see the module docs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ParticleGroups {
    /// Explicit groups.
    pub explicit: Vec<ExplicitGroup>,
    /// Compliance `1/E` (1/Pa) of each particle index where a stiffness region overrides
    /// the material's; empty when none does. `NaN` marks a particle without an override.
    pub compliance: Vec<f32>,
}

impl ParticleGroups {
    /// The compliance `1/E` (1/Pa) of particle `i` of a body whose material's is
    /// `material`.
    pub fn compliance_of(&self, i: u32, material: f32) -> f32 {
        match self.compliance.get(i as usize) {
            Some(c) if !c.is_nan() => *c,
            _ => material,
        }
    }

    /// The mean compliance `1/E` (1/Pa) of particles `members` (the material's,
    /// `material`, where no region overrides it): a cluster's, in the cluster model.
    pub fn mean_compliance(&self, members: &[u32], material: f32) -> f32 {
        if self.compliance.is_empty() || members.is_empty() {
            return material;
        }
        let sum: f64 = members
            .iter()
            .map(|&i| self.compliance_of(i, material) as f64)
            .sum();
        (sum / members.len() as f64) as f32
    }

    /// Whether any particle's compliance differs from the material's.
    pub fn has_stiffness_regions(&self) -> bool {
        self.compliance.iter().any(|c| !c.is_nan())
    }

    /// The explicit groups as the lattice leaves them: each group's live members split
    /// into the pieces its live edges connect (a cut through a rigid part leaves each
    /// connected piece a part), each with the group's compliance. Pieces come in group
    /// order, each one's members ascending.
    pub fn explicit_pieces(&self, lattice: &Lattice) -> Vec<ExplicitGroup> {
        self.explicit
            .iter()
            .flat_map(|group| {
                connected_components(&group.members, lattice)
                    .into_iter()
                    .map(|members| ExplicitGroup {
                        members,
                        compliance: group.compliance,
                    })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::IVec3;

    #[test]
    fn a_severed_group_becomes_one_group_per_connected_piece() {
        let coords = (0..6).map(|x| IVec3::new(x, 0, 0)).collect();
        let mut lattice = Lattice::from_coords(1.0, coords).expect("a rod");
        let groups = ParticleGroups {
            explicit: vec![
                ExplicitGroup {
                    members: vec![0, 1, 2, 3, 4],
                    compliance: 0.0,
                },
                ExplicitGroup {
                    members: vec![4, 5],
                    compliance: 1e-6,
                },
            ],
            compliance: Vec::new(),
        };
        assert_eq!(groups.explicit_pieces(&lattice).len(), 2);
        lattice.sever(1, 2);
        lattice.remove(4);
        let pieces = groups.explicit_pieces(&lattice);
        let members: Vec<&[u32]> = pieces.iter().map(|p| p.members.as_slice()).collect();
        assert_eq!(members, [&[0, 1][..], &[2, 3], &[5]]);
        assert_eq!(pieces[2].compliance, 1e-6);
    }
}
