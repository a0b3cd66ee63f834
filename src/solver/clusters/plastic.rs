//! Plasticity of the clusters (material `yield_strain`, `creep`, `max_plastic_strain`):
//! a plastic cluster's rest offsets are its members' lattice offsets plus a plastic
//! shift each. This module holds that data and the flow of one cluster's shape; the
//! term's pass over its clusters, after every substep, is [`super::creep`].

use crate::config::Yield;
use crate::solver::yielding::flow;
use glam::{Quat, Vec3A};
use smallvec::SmallVec;

/// A cluster's plasticity as [`super::term::ClusterTerm::new`] and
/// [`super::term::ClusterTerm::patch`] take it.
#[derive(Clone, Copy, Debug)]
pub struct PlasticSpec<'a> {
    /// The material's yield.
    pub yielding: Yield,
    /// The plastic shift of each member's rest offset, in member order, that the cluster
    /// had in the layout it is carried over from
    /// ([`super::term::ClusterTerm::plastic_shift`]); empty (or of another length): none
    /// yet.
    pub shift: &'a [Vec3A],
}

/// A plastic cluster: its yield, and the plastic shift of each member's rest offset
/// from its lattice offset, in member order.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub(in crate::solver) struct PlasticCluster {
    pub(in crate::solver) yielding: Yield,
    pub(in crate::solver) shift: Vec<Vec3A>,
}

/// Per-member offsets of one cluster (scratch of one creep fit).
pub(in crate::solver) type Offsets = SmallVec<[Vec3A; 32]>;

impl PlasticCluster {
    /// The plastic cluster of `spec`, with `members` members.
    pub(in crate::solver) fn new(spec: PlasticSpec, members: usize) -> Self {
        let carried = spec.shift.len() == members && spec.shift.iter().all(|s| s.is_finite());
        PlasticCluster {
            yielding: spec.yielding,
            shift: if carried {
                spec.shift.to_vec()
            } else {
                vec![Vec3A::ZERO; members]
            },
        }
    }

    /// Lets the cluster's rest shape flow over a substep of `dt` toward its members'
    /// positions `at` (relative to any point), fitted by `rotation`, with their lattice
    /// offsets `lattice` and weights `weight(j)` ([`crate::solver::yielding`]); returns
    /// whether it did (then the shift is the new one).
    pub(in crate::solver) fn flow(
        &mut self,
        mut lattice: Offsets,
        mut at: Offsets,
        weight: impl Fn(usize) -> f32 + Copy,
        rotation: Quat,
        dt: f32,
    ) -> bool {
        let mut offsets: Offsets = lattice
            .iter()
            .zip(&self.shift)
            .map(|(l, s)| *l + *s)
            .collect();
        // weighted-centred (a cut may have changed the weights since the shift was taken)
        for list in [&mut lattice, &mut offsets, &mut at] {
            centre(list, weight);
        }
        let back = rotation.conjugate();
        let deformation: Offsets = at
            .iter()
            .zip(&offsets)
            .map(|(x, o)| back * *x - *o)
            .collect();
        if !flow(
            &self.yielding,
            dt,
            weight,
            &lattice,
            &mut offsets,
            &deformation,
        ) {
            return false;
        }
        for ((s, o), l) in self.shift.iter_mut().zip(&offsets).zip(&lattice) {
            *s = *o - *l;
        }
        true
    }
}

/// Subtracts the weighted mean of `list` from every entry.
fn centre(list: &mut [Vec3A], weight: impl Fn(usize) -> f32) {
    let (mut sum, mut total) = (Vec3A::ZERO, 0.0f32);
    for (j, v) in list.iter().enumerate() {
        sum += *v * weight(j);
        total += weight(j);
    }
    if total > 0.0 {
        let mean = sum / total;
        list.iter_mut().for_each(|v| *v -= mean);
    }
}
