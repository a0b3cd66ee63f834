//! A render mesh embedded in a body: a closed triangle mesh (the OBJ a body was
//! voxelised from, or any mesh given as its `render_mesh`) drawn instead of the
//! lattice's boxy surface, carried by the particles, and opened where cuts pass.
//!
//! Each vertex is bound to the particles at the corners of the cell of particle centres
//! it lies in, with trilinear weights — those of the eight that are live and linked,
//! within the eight, to the one nearest it (so that a vertex does not bind across a
//! gap narrower than a cell) — and carried like a lattice surface's vertex
//! ([`super::deform`]): `Σ wᵢ (xᵢ + Rᵢ (v̄ − r̄ᵢ))`.
//!
//! A cut opens the mesh: a triangle is drawn while every particle its vertices are
//! bound to (its *support*) is live and the support is split into no more parts, over
//! the links among its own particles, than when the mesh was embedded. The faces the
//! cuts made in the lattice — faces of the lattice surface between two cells that were
//! both solid when the mesh was embedded, or inside a split cell — are drawn with it,
//! so a piece shows its cut faces where the blade passed and no hole opens into it.

use super::cells::octant;
use super::extract::{Binding, LatticeFace, SurfaceTopology};
use crate::body::lattice::Lattice;
use crate::error::{CleaveError, Result};
use crate::geometry::mesh::TriangleMesh;
use glam::{IVec3, Vec3};
use rustc_hash::FxHashSet;

/// Most particles a triangle's support holds: three vertices of eight.
const MAX_SUPPORT: usize = 24;

/// A render mesh bound to a body's lattice (see the module docs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EmbeddedMesh {
    /// The vertices, their rest positions (lattice frame) and bindings, and the
    /// triangles: a topology whose every triangle is drawn while the body is whole.
    mesh: SurfaceTopology,
    /// Per triangle, the parts its support made when the mesh was embedded.
    support_parts: Vec<u8>,
    /// The lattice cells the body filled when the mesh was embedded.
    #[serde(with = "sorted_cells")]
    solid: FxHashSet<IVec3>,
}

impl EmbeddedMesh {
    /// Binds `mesh` (in the body's local frame, the frame its lattice was voxelised in)
    /// to `lattice`. Fails, naming the mesh's file, when a vertex lies farther than a
    /// cell from every live particle of the body.
    pub fn new(lattice: &Lattice, mesh: &TriangleMesh) -> Result<Self> {
        let mut topology = SurfaceTopology {
            binding_start: vec![0],
            ..SurfaceTopology::default()
        };
        for (v, &at) in mesh.vertices.iter().enumerate() {
            bind_vertex(lattice, at, &mut topology.bindings).ok_or_else(|| CleaveError::Mesh {
                path: mesh.source.clone(),
                reason: format!(
                    "render mesh vertex {v} at {at} lies outside its body (farther than a \
                     cell, {} m, from every particle)",
                    lattice.spacing()
                ),
            })?;
            topology.rest.push(at);
            topology.binding_start.push(topology.bindings.len() as u32);
        }
        topology.triangles = mesh.triangles.clone();
        let support_parts = (0..mesh.triangles.len())
            .map(|t| support_parts(lattice, &topology, t).unwrap_or(0) as u8)
            .collect();
        Ok(Self {
            mesh: topology,
            support_parts,
            solid: lattice.live_particles().map(|p| lattice.coord(p)).collect(),
        })
    }

    /// What is wrong with an embedded mesh read from elsewhere (a save) for a body of
    /// `particles` particles ([`SurfaceTopology::fault`]); `None` when nothing is.
    pub fn fault(&self, particles: usize) -> Option<&'static str> {
        if self.support_parts.len() != self.mesh.triangles.len() {
            return Some("its triangles' supports do not match its triangles");
        }
        self.mesh.fault(particles)
    }

    /// Number of the mesh's vertices.
    pub fn vertex_count(&self) -> usize {
        self.mesh.vertex_count()
    }

    /// Number of the mesh's triangles.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangles.len()
    }

    /// What to draw of the body now: the mesh's triangles that no cut opened, then the
    /// cut faces of `surface`, the lattice's surface (with its `faces`, from
    /// [`super::extract::extract_with_faces`]). The mesh's vertices come first, in its
    /// order, then those of the cut faces; triangles are numbered by piece as
    /// [`Lattice::pieces`] numbers them.
    pub fn drawn(
        &self,
        lattice: &Lattice,
        surface: &SurfaceTopology,
        faces: &[LatticeFace],
    ) -> SurfaceTopology {
        let piece = &lattice.pieces().label;
        // the mesh's vertices keep their numbers (a renderer's texture coordinates and
        // other per-vertex data stay valid), whether or not a drawn triangle uses them
        let mut drawn = SurfaceTopology {
            triangles: Vec::new(),
            triangle_piece: Vec::new(),
            particles: Vec::new(),
            ..self.mesh.clone()
        };
        for (t, tri) in self.mesh.triangles.iter().enumerate() {
            let parts = support_parts(lattice, &self.mesh, t);
            if parts.is_none_or(|n| n > self.support_parts[t] as usize) {
                continue;
            }
            drawn.triangles.push(*tri);
            let heaviest = self
                .mesh
                .bindings_of(tri[0] as usize)
                .iter()
                .max_by(|a, b| a.weight.total_cmp(&b.weight));
            drawn
                .triangle_piece
                .push(heaviest.map_or(0, |b| piece[b.particle as usize]));
        }
        let mut renumber = Renumber::new(surface.vertex_count());
        for (q, face) in faces.iter().enumerate() {
            if face.cell != face.across && !self.solid.contains(&face.across) {
                continue;
            }
            for t in [2 * q, 2 * q + 1] {
                let tri = surface.triangles[t].map(|v| renumber.vertex(surface, v, &mut drawn));
                drawn.triangles.push(tri);
                drawn.triangle_piece.push(surface.triangle_piece[t]);
            }
        }
        let mut particles: Vec<u32> = drawn.bindings.iter().map(|b| b.particle).collect();
        particles.sort_unstable();
        particles.dedup();
        drawn.particles = particles;
        drawn
    }
}

/// A set of cells saved as a list in ascending order (so that a save does not depend on
/// the set's order).
mod sorted_cells {
    use glam::IVec3;
    use rustc_hash::FxHashSet;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(set: &FxHashSet<IVec3>, s: S) -> Result<S::Ok, S::Error> {
        let mut list: Vec<[i32; 3]> = set.iter().map(|c| c.to_array()).collect();
        list.sort_unstable();
        list.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<FxHashSet<IVec3>, D::Error> {
        let list: Vec<[i32; 3]> = Vec::deserialize(d)?;
        Ok(list.into_iter().map(IVec3::from_array).collect())
    }
}

/// Vertices of one topology copied into another on first use.
struct Renumber(Vec<u32>);

impl Renumber {
    fn new(vertices: usize) -> Self {
        Self(vec![u32::MAX; vertices])
    }

    /// The index in `to` of vertex `v` of `from`, copying it over the first time.
    fn vertex(&mut self, from: &SurfaceTopology, v: u32, to: &mut SurfaceTopology) -> u32 {
        let slot = &mut self.0[v as usize];
        if *slot == u32::MAX {
            *slot = to.rest.len() as u32;
            to.rest.push(from.rest[v as usize]);
            to.bindings.extend_from_slice(from.bindings_of(v as usize));
            to.binding_start.push(to.bindings.len() as u32);
        }
        *slot
    }
}

/// Appends the bindings of a vertex resting at `at` (see the module docs); `None` when
/// no live particle is near enough.
fn bind_vertex(lattice: &Lattice, at: Vec3, bindings: &mut Vec<Binding>) -> Option<()> {
    let h = lattice.spacing();
    // particle k rests at (k + ½)·h: the cell of centres around `at` starts at `base`
    let g = at / h - Vec3::splat(0.5);
    let base = g.floor();
    let f = g - base;
    let base = base.as_ivec3();
    let mut corners: Vec<(u32, f32)> = (0..8)
        .filter_map(|k| {
            let o = octant(k);
            let w = Vec3::select(o.cmpeq(IVec3::ONE), f, Vec3::ONE - f);
            let p = lattice.at(base + o)?;
            Some((p, w.x * w.y * w.z))
        })
        .collect();
    if corners.is_empty() {
        // a vertex of a feature thinner than a cell: the nearest particle around
        let nearest = (0..27)
            .filter_map(|k| {
                let c = IVec3::new(k % 3, k / 3 % 3, k / 9) - IVec3::ONE + g.round().as_ivec3();
                lattice.at(c)
            })
            .map(|p| (p, lattice.rest_position(p).distance(at)))
            .filter(|&(_, d)| d <= 1.5 * h)
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        corners.push((nearest.0, 1.0));
    }
    // keep the corners linked (within the eight) to the heaviest
    corners.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    let mut kept = vec![corners[0]];
    let mut grew = true;
    while grew {
        grew = false;
        for &(p, w) in &corners {
            if !kept.iter().any(|k| k.0 == p)
                && lattice.neighbours(p).any(|q| kept.iter().any(|k| k.0 == q))
            {
                kept.push((p, w));
                grew = true;
            }
        }
    }
    // a vertex exactly on a face of the cell gives its far corners no weight
    let total: f32 = kept.iter().map(|k| k.1).sum();
    let weight = |w: f32| {
        if total > 0.0 {
            w / total
        } else {
            1.0 / kept.len() as f32
        }
    };
    bindings.extend(kept.iter().map(|&(p, w)| Binding {
        particle: p,
        weight: weight(w),
        offset: at - lattice.rest_position(p),
    }));
    Some(())
}

/// The parts the support of triangle `t` of `mesh` makes over the links among its own
/// particles; `None` when one of them is no longer live.
fn support_parts(lattice: &Lattice, mesh: &SurfaceTopology, t: usize) -> Option<usize> {
    let mut support = [0u32; MAX_SUPPORT];
    let mut n = 0;
    for &v in &mesh.triangles[t] {
        for b in mesh.bindings_of(v as usize) {
            if !support[..n].contains(&b.particle) {
                support[n] = b.particle;
                n += 1;
            }
        }
    }
    let support = &support[..n];
    if support.iter().any(|&p| !lattice.is_live(p)) {
        return None;
    }
    // union–find over the support's own links
    let mut parent: [usize; MAX_SUPPORT] = std::array::from_fn(|i| i);
    let find = |parent: &[usize; MAX_SUPPORT], mut i: usize| {
        while parent[i] != i {
            i = parent[i];
        }
        i
    };
    let mut parts = n;
    for (i, &p) in support.iter().enumerate() {
        for q in lattice.neighbours(p) {
            if let Some(j) = support.iter().position(|&s| s == q) {
                let (a, b) = (find(&parent, i), find(&parent, j));
                if a != b {
                    parent[a] = b;
                    parts -= 1;
                }
            }
        }
    }
    Some(parts)
}
