//! The drawable surface of a body, as an ECS component: the closed mesh of each of its
//! pieces ([`crate::surface`]), kept by the `Surface` stage. A renderer reads the
//! positions, normals and triangles, and polls [`SurfaceMesh::topology_version`] (or
//! reads [`crate::ecs::resources::SurfaceChanged`]) to know when to upload new
//! triangles.

use crate::body::lattice::Lattice;
use crate::ecs::desc::SurfaceOptions;
use crate::surface::embed::EmbeddedMesh;
use crate::surface::{CarryLayout, SurfaceTopology};
use bevy_ecs::prelude::*;
use glam::{Mat3A, Quat, Vec3, Vec3A};
use std::sync::Arc;

/// A body's surface. Every spawned body gets one; remove it to skip the work (the
/// `Surface` stage updates only bodies that have it).
#[derive(Component, Clone, Debug, Default)]
pub struct SurfaceMesh {
    /// Vertex positions (world frame), this frame.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, this frame.
    pub normals: Vec<Vec3>,
    /// Grows by one each time the triangles change (the first surface is version 1):
    /// positions and normals change every frame, triangles only with this.
    pub topology_version: u64,
    /// Milliseconds the last change of the triangles took (extraction, or the local
    /// update after a cut, with the carriers' layout), for reports.
    pub topology_ms: f64,
    pub(crate) topology: SurfaceTopology,
    /// The particles the surface reads, by slot.
    pub(crate) layout: CarryLayout,
    /// Per slot of the layout, its particle's position this frame.
    pub(crate) gathered: Vec<Vec3A>,
    /// Per carrier, its frame (see [`crate::surface::deform`]) and its matrix.
    pub(crate) frames: Vec<Quat>,
    pub(crate) rotations: Vec<Mat3A>,
    /// Per triangle, scratch for the normals.
    pub(crate) faces: Vec<Vec3A>,
    /// The render mesh drawn instead of the lattice's surface, if the body has one.
    pub(crate) render_mesh: Option<Arc<EmbeddedMesh>>,
    /// How the lattice's surface is drawn.
    pub(crate) options: SurfaceOptions,
    /// The lattice's particles, live particles and edits when the triangles were last
    /// made.
    pub(crate) seen: (usize, usize, u64),
    /// The frame whose end the vertices were last carried to (`None`: never).
    pub(crate) deformed_at: Option<u64>,
}

impl SurfaceMesh {
    /// A surface still to be extracted: the lattice's, drawn as `options` say, or
    /// `render_mesh` embedded in it.
    pub fn new(render_mesh: Option<EmbeddedMesh>, options: SurfaceOptions) -> Self {
        Self {
            render_mesh: render_mesh.map(Arc::new),
            options,
            ..Self::default()
        }
    }

    /// The render mesh drawn instead of the lattice's surface, if the body has one.
    pub fn render_mesh(&self) -> Option<&EmbeddedMesh> {
        self.render_mesh.as_deref()
    }

    /// Triangles (vertex indices), counter-clockwise seen from outside.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.topology.triangles
    }

    /// Per triangle, the piece of the body it bounds (numbered as
    /// [`crate::body::lattice::Lattice::pieces`] numbers them).
    pub fn triangle_pieces(&self) -> &[u32] {
        &self.topology.triangle_piece
    }

    /// The topology and its binding to the particles.
    pub fn topology(&self) -> &SurfaceTopology {
        &self.topology
    }

    /// What a save keeps of the surface: all the stage carries from frame to frame.
    pub(crate) fn saved(&self) -> SavedSurface {
        SavedSurface {
            positions: self.positions.clone(),
            normals: self.normals.clone(),
            topology_version: self.topology_version,
            topology: self.topology.clone(),
            gathered: self.gathered.clone(),
            frames: self.frames.clone(),
            render_mesh: self.render_mesh.as_deref().cloned(),
            options: self.options,
            seen: self.seen,
            deformed_at: self.deformed_at,
        }
    }

    /// The surface a save kept for a body whose lattice is `lattice`, its carriers laid
    /// out again; an error naming what does not fit.
    pub(crate) fn restore(saved: SavedSurface, lattice: &Lattice) -> Result<Self, String> {
        let particles = lattice.len();
        if let Some(fault) = saved
            .topology
            .fault(particles)
            .or_else(|| (saved.render_mesh.as_ref()).and_then(|m| m.fault(particles)))
        {
            return Err(fault.into());
        }
        let layout = CarryLayout::new(lattice, &saved.topology);
        let vertices = saved.topology.vertex_count();
        let finite = saved.frames.iter().all(|q| q.is_finite())
            && saved.gathered.iter().all(|x| x.is_finite())
            && saved
                .positions
                .iter()
                .chain(&saved.normals)
                .all(|x| x.is_finite());
        if saved.frames.len() != layout.carrier_count()
            || saved.gathered.len() != layout.read.len()
            || saved.positions.len() != vertices
            || saved.normals.len() != vertices
            || !finite
        {
            return Err("its carriers' state does not fit its vertices".into());
        }
        Ok(Self {
            positions: saved.positions,
            normals: saved.normals,
            topology_version: saved.topology_version,
            topology_ms: 0.0,
            topology: saved.topology,
            rotations: vec![Mat3A::IDENTITY; layout.carrier_count()],
            layout,
            gathered: saved.gathered,
            frames: saved.frames,
            faces: Vec::new(),
            render_mesh: saved.render_mesh.map(Arc::new),
            options: saved.options,
            seen: saved.seen,
            deformed_at: saved.deformed_at,
        })
    }
}

/// A surface as a save keeps it: the topology, the carriers'
/// frames and last positions, the render mesh and options, and what the stage last saw
/// — so that a loaded simulation draws, and goes on drawing, exactly what the saved one
/// would have. The carriers' layout is derived again on loading.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct SavedSurface {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    topology_version: u64,
    topology: SurfaceTopology,
    gathered: Vec<Vec3A>,
    frames: Vec<Quat>,
    render_mesh: Option<EmbeddedMesh>,
    options: SurfaceOptions,
    seen: (usize, usize, u64),
    deformed_at: Option<u64>,
}
