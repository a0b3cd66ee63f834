//! A render mesh embedded in a body: a closed triangle mesh (the OBJ a body was
//! voxelised from, or any mesh given as its `render_mesh`) drawn instead of the
//! lattice's boxy surface, carried by the particles, and cut where the tools pass.
//!
//! Each vertex is bound to the particles at the corners of the cell of particle centres
//! it lies in, with trilinear weights — those of the eight that are live and linked,
//! within the eight, to the one nearest it (so that a vertex does not bind across a
//! gap narrower than a cell) — and carried like a lattice surface's vertex
//! ([`super::deform`]): `Σ wᵢ (xᵢ + Rᵢ (v̄ − r̄ᵢ))`.
//!
//! A cut clips the mesh where it passed and closes each piece with a cap
//! ([`super::clip`]), so each piece draws a closed mesh. Where particles are removed,
//! the triangles they carry are left out and the lattice's faces toward the removed
//! particles (cells the body filled when the mesh was embedded) drawn instead.

use super::clip::clip;
use super::extract::{LatticeFace, SurfaceTopology};
use super::trilinear::bind_vertex;
use crate::body::lattice::Lattice;
use crate::error::{CleaveError, Result};
use crate::geometry::mesh::TriangleMesh;
use glam::IVec3;
use rustc_hash::FxHashSet;

/// A render mesh bound to a body's lattice (see the module docs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EmbeddedMesh {
    /// The vertices, their rest positions (lattice frame) and bindings, and the
    /// triangles: a topology whose every triangle is drawn while the body is whole.
    mesh: SurfaceTopology,
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
            bind_vertex(lattice, at, None, &mut topology.bindings).ok_or_else(|| {
                CleaveError::Mesh {
                    path: mesh.source.clone(),
                    reason: format!(
                        "render mesh vertex {v} at {at} lies outside its body (farther than a \
                     cell, {} m, from every particle)",
                        lattice.spacing()
                    ),
                }
            })?;
            topology.rest.push(at);
            topology.binding_start.push(topology.bindings.len() as u32);
        }
        topology.triangles = mesh.triangles.clone();
        Ok(Self {
            mesh: topology,
            solid: lattice.live_particles().map(|p| lattice.coord(p)).collect(),
        })
    }

    /// What is wrong with an embedded mesh read from elsewhere (a save) for a body of
    /// `particles` particles ([`SurfaceTopology::fault`]); `None` when nothing is.
    pub fn fault(&self, particles: usize) -> Option<&'static str> {
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

    /// What to draw of the body now: the mesh clipped at the cuts and capped
    /// ([`super::clip`]), then the faces of `surface`, the lattice's surface (with its
    /// `faces`, from [`super::extract::extract_with_faces`]), toward particles a cut
    /// removed, where the mesh's triangles carried by them are left out. The mesh's
    /// vertices come first, in its order, then the clipped and capping ones, then those
    /// of the lattice's faces; triangles are numbered by piece as [`Lattice::pieces`]
    /// numbers them.
    pub fn drawn(
        &self,
        lattice: &Lattice,
        surface: &SurfaceTopology,
        faces: &[LatticeFace],
    ) -> SurfaceTopology {
        // the mesh's vertices keep their numbers (a renderer's texture coordinates and
        // other per-vertex data stay valid), whether or not a drawn triangle uses them
        let mut drawn = SurfaceTopology::default();
        let removed = |t: usize| {
            self.mesh.triangles[t]
                .iter()
                .flat_map(|&v| self.mesh.bindings_of(v as usize))
                .any(|b| !lattice.is_live(b.particle))
        };
        clip(lattice, &self.mesh, removed, &mut drawn);
        let mut renumber = Renumber::new(surface.vertex_count());
        for (q, face) in faces.iter().enumerate() {
            let gone = face.cell != face.across
                && self.solid.contains(&face.across)
                && lattice.at(face.across).is_none();
            if !gone {
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
