//! Handles: what a handle deformation is controlled by (SPEC §6.3). A *point* handle
//! is one particle moved to a target position (d parameters); a *region* handle is a
//! set of particles moved together by one affine map (a 3×4 matrix: (d + 1)·d
//! parameters). A [`HandleSet`] checks a list of handles against a body once; its
//! columns are the subspace's parameters, one per point handle and four per region
//! (x, y, z about the region's rest centroid, and 1), shared by the three coordinates.

use crate::body::lattice::Lattice;
use crate::error::{CleaveError, Result};
use glam::{Affine3A, Vec3};

/// One handle of a body: which particles it moves.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Handle {
    /// One particle, moved to a target position.
    Point(u32),
    /// A set of particles, moved by one affine map.
    Region(Vec<u32>),
}

impl Handle {
    /// The particles the handle moves.
    pub fn particles(&self) -> &[u32] {
        match self {
            Handle::Point(p) => std::slice::from_ref(p),
            Handle::Region(ps) => ps,
        }
    }

    /// How many columns of the subspace the handle has (per coordinate).
    pub fn columns(&self) -> usize {
        match self {
            Handle::Point(_) => 1,
            Handle::Region(_) => 4,
        }
    }
}

/// Where a handle is asked to go.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum HandleTarget {
    /// A point handle's particle goes to this position.
    Point(Vec3),
    /// A region handle's particles go to this map of their rest positions.
    Affine(Affine3A),
}

/// A body's handles, checked: live particles, none shared, none pinned, fewer
/// parameters than particles.
#[derive(Clone, Debug)]
pub struct HandleSet {
    handles: Vec<Handle>,
    /// The first column of each handle.
    first_column: Vec<usize>,
    columns: usize,
}

impl HandleSet {
    /// Checks `handles` against `lattice` and the body's `pinned` particles (a pinned
    /// particle cannot also follow a handle); errors name `handles[i]`.
    pub fn new(lattice: &Lattice, handles: Vec<Handle>, pinned: &[u32]) -> Result<Self> {
        let invalid = |i: usize, what: String| {
            Err(CleaveError::InvalidEntity(format!("handles[{i}]: {what}")))
        };
        if handles.is_empty() {
            return Err(CleaveError::InvalidEntity(
                "handles: a deformation needs at least one handle".into(),
            ));
        }
        let mut owner = vec![u32::MAX; lattice.len()];
        let mut first_column = Vec::with_capacity(handles.len());
        let mut columns = 0;
        for (i, handle) in handles.iter().enumerate() {
            if handle.particles().is_empty() {
                return invalid(i, "selects no particle".into());
            }
            for &p in handle.particles() {
                if !lattice.is_live(p) {
                    return invalid(i, format!("particle {p} is not a live particle"));
                }
                if pinned.contains(&p) {
                    return invalid(i, format!("particle {p} is pinned"));
                }
                let o = &mut owner[p as usize];
                if *o == i as u32 {
                    return invalid(i, format!("particle {p} is listed twice"));
                }
                if *o != u32::MAX {
                    return invalid(i, format!("overlaps handles[{o}] (particle {p})"));
                }
                *o = i as u32;
            }
            first_column.push(columns);
            columns += handle.columns();
        }
        if columns >= lattice.live_count() {
            return Err(CleaveError::InvalidEntity(format!(
                "handles: {columns} parameters for {} particles (a deformation needs fewer \
                 parameters than particles)",
                lattice.live_count()
            )));
        }
        Ok(Self {
            handles,
            first_column,
            columns,
        })
    }

    /// The handles, in the order they were given.
    pub fn handles(&self) -> &[Handle] {
        &self.handles
    }

    /// The subspace's parameters per coordinate (the columns of `W`).
    pub fn columns(&self) -> usize {
        self.columns
    }

    /// The first column of handle `k`.
    pub fn first_column(&self, k: usize) -> usize {
        self.first_column[k]
    }

    /// Every particle a handle moves, with the handle's index.
    pub fn constrained(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        self.handles
            .iter()
            .enumerate()
            .flat_map(|(k, h)| h.particles().iter().map(move |&p| (k, p)))
    }

    /// The rest centroid of handle `k`'s particles (`rest` by particle index).
    pub fn rest_centroid(&self, k: usize, rest: &[Vec3]) -> Vec3 {
        let ps = self.handles[k].particles();
        ps.iter().map(|&p| rest[p as usize]).sum::<Vec3>() / ps.len() as f32
    }

    /// Row `J_p` of the handle map: the coefficients of handle `k`'s columns for its
    /// particle `p` (a point: 1; a region: the rest offset from its centroid, and 1).
    pub fn coefficients(&self, k: usize, p: u32, rest: &[Vec3]) -> [f64; 4] {
        match self.handles[k] {
            Handle::Point(_) => [1.0, 0.0, 0.0, 0.0],
            Handle::Region(_) => {
                let d = (rest[p as usize] - self.rest_centroid(k, rest)).as_dvec3();
                [d.x, d.y, d.z, 1.0]
            }
        }
    }

    /// The parameters' displacements `ΔH = H − H̄` (one row per column) that move the
    /// handles from their rest positions `rest` to `targets` (one per handle, of the
    /// handle's kind); errors name `targets[i]`.
    pub fn displacements(&self, rest: &[Vec3], targets: &[HandleTarget]) -> Result<Vec<Vec3>> {
        if targets.len() != self.handles.len() {
            return Err(CleaveError::InvalidEntity(format!(
                "targets: {} given for {} handles",
                targets.len(),
                self.handles.len()
            )));
        }
        let mut rows = Vec::with_capacity(self.columns);
        for (k, (handle, target)) in self.handles.iter().zip(targets).enumerate() {
            let bad = |what: &str| Err(CleaveError::InvalidEntity(format!("targets[{k}]: {what}")));
            match (handle, target) {
                (Handle::Point(p), HandleTarget::Point(x)) => {
                    if !x.is_finite() {
                        return bad("the position is not finite");
                    }
                    rows.push(*x - rest[*p as usize]);
                }
                (Handle::Region(_), HandleTarget::Affine(map)) => {
                    if !(map.matrix3.is_finite() && map.translation.is_finite()) {
                        return bad("the affine map is not finite");
                    }
                    // target(x̄) − x̄ = (L − I)(x̄ − c̄) + (map(c̄) − c̄)
                    let c = self.rest_centroid(k, rest);
                    let linear = map.matrix3 - glam::Mat3A::IDENTITY;
                    rows.extend([linear.x_axis, linear.y_axis, linear.z_axis].map(Vec3::from));
                    rows.push(map.transform_point3(c) - c);
                }
                (Handle::Point(_), _) => return bad("a point handle needs a point target"),
                (Handle::Region(_), _) => return bad("a region handle needs an affine target"),
            }
        }
        Ok(rows)
    }
}
