//! The data the SIMD kernel reads: the clusters in batches of eight, a batch's members
//! row by row (one cluster per lane), as particle byte offsets and as rest offsets with
//! weights — each batch's own, or the shared rest shape's (`Template`). Built and
//! patched in [`super::batches`], read in [`super::fit`].

use crate::math::lanes::{LANES, Vec3x8};
use glam::Vec3A;
use smallvec::SmallVec;
use wide::f32x8;

/// Lane marker: no cluster.
pub(in crate::solver) const EMPTY_LANE: u32 = u32::MAX;

/// A group of batches: the batches `[first, end)`, run in order by one task.
pub(in crate::solver) type Group = [u32; 2];

/// Member `j`'s rest offset and weight in each of a batch's clusters, as fixed by the
/// layout (or by its template, see `template.rs`).
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(in crate::solver) struct MomentRow {
    /// Rest offsets `q` from the cluster's rest centroid (padding: 0).
    pub(in crate::solver) offset: Vec3x8,
    /// Matching weights (padding: 0).
    #[serde(with = "crate::math::lanes::f32x8_serde")]
    pub(in crate::solver) weight: f32x8,
}

/// Member `j`'s particle in each of a batch's clusters, as a byte offset into a
/// per-particle `Vec3A` array ([`PARTICLE_BYTES`] × index: x86 addressing scales an
/// index by at most 8, so a stored index would cost a shift per lane and pass); padding
/// repeats the lane's first member (0 for an empty lane), so that it sits at the lane's
/// origin.
pub(in crate::solver) type ParticleRow = [u32; LANES];

/// A batch's first row in `Batches::moments` when it reads the template instead.
pub(in crate::solver) const TEMPLATED: u32 = u32::MAX;

/// Bytes per particle in the per-particle `Vec3A` arrays the rows address.
pub(in crate::solver) const PARTICLE_BYTES: u32 = size_of::<Vec3A>() as u32;

/// The members' positions of one row during a fit: scratch of one task.
pub(in crate::solver) type FitRow = Vec3x8;

/// One cluster's members with their rest offsets and weights, in canonical order.
pub(in crate::solver) type Canonical = SmallVec<[(u32, Vec3A, f32); 32]>;

/// The shared rest shape (see [`super::template`]).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(in crate::solver) struct Template {
    /// Member `j`'s rest offset and weight, the same in every lane.
    pub(in crate::solver) rows: Vec<MomentRow>,
    /// `Σ w q` over the rows (the fit's bias, as [`ClusterTerm::fill_constants`]).
    pub(in crate::solver) bias: Vec3A,
    /// `1 / Σ w`.
    pub(in crate::solver) inv_weight_sum: f32,
}

impl Template {
    /// The template of one cluster's canonical members.
    pub(in crate::solver) fn of(members: &Canonical) -> Self {
        let total: f32 = members.iter().map(|(_, _, w)| w).sum();
        let bias = members.iter().map(|(_, q, w)| *q * *w).sum();
        let rows = members
            .iter()
            .map(|(_, q, w)| MomentRow {
                offset: Vec3x8 {
                    x: f32x8::splat(q.x),
                    y: f32x8::splat(q.y),
                    z: f32x8::splat(q.z),
                },
                weight: f32x8::splat(*w),
            })
            .collect();
        Template {
            rows,
            bias,
            inv_weight_sum: 1.0 / total,
        }
    }

    /// Number of members.
    pub(in crate::solver) fn len(&self) -> usize {
        self.rows.len()
    }

    /// Offset and weight of member `j` (lane 0 of its row).
    pub(in crate::solver) fn member(&self, j: usize) -> (Vec3A, f32) {
        let row = &self.rows[j];
        let x = |v: f32x8| v.as_array()[0];
        let offset = Vec3A::new(x(row.offset.x), x(row.offset.y), x(row.offset.z));
        (offset, x(row.weight))
    }
}

/// The clusters in batches of [`LANES`] clusters, the batches in coloured groups.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub(in crate::solver) struct Batches {
    /// All batches' particle rows.
    pub(super) particles: Vec<ParticleRow>,
    /// Per batch: its first particle row; one entry more than batches.
    pub(super) start: Vec<u32>,
    /// The moment rows of the batches that do not read the template.
    pub(super) moments: Vec<MomentRow>,
    /// Per batch: its first moment row, or [`TEMPLATED`].
    pub(super) moment_start: Vec<u32>,
    /// The shared rest shape (empty when the layout has none).
    pub(super) template: Template,
    /// Per batch: the cluster slot of each lane ([`EMPTY_LANE`] for none).
    pub(super) lanes: Vec<[u32; LANES]>,
    /// Per colour: its groups (which share no particle).
    pub(super) of_colour: Vec<Vec<Group>>,
    /// Per cluster slot: `batch × LANES + lane`.
    pub(super) place: Vec<u32>,
    /// Lanes without a cluster.
    pub(super) empty_lanes: usize,
    /// Spatial batches (Jacobi): per particle, bit `c` set when a group of colour `c`
    /// holds it. Empty when the batches are by cluster colour.
    pub(super) group_colours: Vec<u64>,
}

impl Batches {
    /// The particle of every membership slot, row by row, lane by lane (a padding
    /// slot names its lane's first member).
    pub(in crate::solver) fn membership_particles(&self) -> impl Iterator<Item = u32> + '_ {
        self.particles
            .iter()
            .flat_map(|row| row.map(|at| at / PARTICLE_BYTES))
    }

    /// Number of batches.
    #[cfg(test)]
    pub(in crate::solver) fn len(&self) -> usize {
        self.lanes.len()
    }

    /// Number of lanes without a cluster.
    #[cfg(test)]
    pub(in crate::solver) fn empty_lanes(&self) -> usize {
        self.empty_lanes
    }

    /// Whether cluster slot `k` has a lane.
    pub(in crate::solver) fn has_lane(&self, k: usize) -> bool {
        self.place.get(k).is_some_and(|p| *p != u32::MAX)
    }

    /// Records the batches from `first` to the last one as a group of `colour`.
    pub(super) fn push_group(&mut self, colour: usize, first: u32) {
        if self.of_colour.len() <= colour {
            self.of_colour.resize(colour + 1, Vec::new());
        }
        self.of_colour[colour].push([first, self.lanes.len() as u32]);
    }

    /// Whether so many lanes are empty that the batches should be laid out afresh.
    pub(in crate::solver) fn fragmented(&self) -> bool {
        4 * self.empty_lanes > self.lanes.len() * LANES
    }
}
