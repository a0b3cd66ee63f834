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
use std::ops::Range;
use std::sync::{Arc, Condvar, Mutex};

/// A piece and the range of its triangles in [`SurfaceMesh::triangles_by_piece`].
pub type PieceRange = (u32, Range<usize>);

/// What a surface records of the lattice it is made for: its particles, live particles
/// and edits (any edit changes it).
pub(crate) type LatticeState = (usize, usize, u64);

/// A body's surface. Every spawned body gets one; remove it to skip the work (the
/// `Surface` stage updates only bodies that have it).
#[derive(Component, Clone, Debug, Default)]
pub struct SurfaceMesh {
    /// Vertex positions (world frame), as the particles last placed them (carried again
    /// whenever one moved more than [`SurfaceMesh::STILL`]).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, carried with the positions.
    pub normals: Vec<Vec3>,
    /// Grows by one each time the triangles change (the first surface is version 1):
    /// positions and normals change as the particles move, triangles only with this.
    pub topology_version: u64,
    /// Milliseconds the last change of the triangles took (extraction, or the local
    /// update after a cut, with the carriers' layout), for reports.
    pub topology_ms: f64,
    pub(crate) topology: SurfaceTopology,
    /// The particles the surface reads, by slot.
    pub(crate) layout: CarryLayout,
    /// Per slot of the layout, its particle's position this frame.
    pub(crate) gathered: Vec<Vec3A>,
    /// Per slot of the layout, where the solver's dense positions hold its particle
    /// (`u32::MAX`: read its entity), for the body, topology and solver layout
    /// `dense_for` names (`None`: to be looked up again).
    pub(crate) dense_slots: Vec<u32>,
    pub(crate) dense_for: Option<(Entity, u64, u64)>,
    /// Per carrier, its frame (see [`crate::surface::deform`]) and its matrix.
    pub(crate) frames: Vec<Quat>,
    pub(crate) rotations: Vec<Mat3A>,
    /// Per triangle, scratch for the normals.
    pub(crate) faces: Vec<Vec3A>,
    /// The render mesh drawn instead of the lattice's surface, if the body has one.
    pub(crate) render_mesh: Option<Arc<EmbeddedMesh>>,
    /// How the lattice's surface is drawn.
    pub(crate) options: SurfaceOptions,
    /// The lattice's state when the triangles were last made.
    pub(crate) seen: LatticeState,
    /// The frame at whose end the stage last brought the vertices up to date, carrying
    /// them or finding them at rest (`None`: never).
    pub(crate) deformed_at: Option<u64>,
    /// Per slot of the layout, its particle's position when the mesh was last marked
    /// changed (see [`SurfaceMesh::STILL`]).
    pub(crate) shown: Vec<Vec3A>,
    /// A rebuild running beside the frames (see [`crate::ecs::resources::SurfaceBudget`]).
    pub(crate) deferred: Option<DeferredSurface>,
}

/// A surface rebuilt beside the frames: the lattice state it is made for, the frame it
/// is due, and where the job leaves its result.
#[derive(Clone, Debug)]
pub(crate) struct DeferredSurface {
    /// The lattice's state it is made for.
    pub(crate) seen: LatticeState,
    /// The frame at whose end it is put in place.
    pub(crate) due: u64,
    /// Where the job leaves its result, and the signal that it did.
    pub(crate) result: JobSlot,
}

/// A rebuilt surface: its topology, its carriers' layout and the milliseconds it took.
pub(crate) type RebuiltSurface = (SurfaceTopology, CarryLayout, f64);

/// Where a rebuild job leaves its result (see [`JobResult`]), with the signal that it
/// did.
pub(crate) type JobSlot = Arc<(Mutex<JobResult>, Condvar)>;

/// What a rebuild job hands back: `done` once it finished, and its result until a
/// waiter takes it.
#[derive(Debug, Default)]
pub(crate) struct JobResult {
    pub(crate) done: bool,
    pub(crate) rebuilt: Option<RebuiltSurface>,
}

impl DeferredSurface {
    /// The result, waited for; `None` when a copy of the mesh (a clone shares its
    /// pending rebuild) took it first. A thread of a rayon pool runs the pool's pending
    /// work while it waits (the job itself, should it still be queued there).
    pub(crate) fn wait(self) -> Option<RebuiltSurface> {
        let (slot, done) = &*self.result;
        let lock = || slot.lock().unwrap_or_else(|e| e.into_inner());
        let mut result = lock();
        loop {
            if result.done {
                return result.rebuilt.take();
            }
            drop(result);
            result = if rayon::yield_now() == Some(rayon::Yield::Executed) {
                lock()
            } else {
                let timeout = std::time::Duration::from_millis(1);
                (done.wait_timeout(lock(), timeout))
                    .unwrap_or_else(|e| e.into_inner())
                    .0
            };
        }
    }
}

impl SurfaceMesh {
    /// How far (a fraction of the lattice spacing) no particle the surface reads may have
    /// moved since the mesh was last marked changed for the stage to leave it unmarked:
    /// bevy's `Changed<SurfaceMesh>` then fires on a frame only when the triangles
    /// changed or the surface moved, so a body at rest (whose particles settle to a
    /// millionth of a spacing, never to the bit) stops re-uploading. Nor are an unmarked
    /// mesh's vertices carried again: it keeps the positions and normals it last showed,
    /// made from particles each within this distance of where they are now, so a
    /// surface at rest costs only that test.
    pub const STILL: f32 = 1e-3;

    /// A surface still to be extracted: the lattice's, drawn as `options` say, or
    /// `render_mesh` embedded in it.
    pub fn new(render_mesh: Option<EmbeddedMesh>, options: SurfaceOptions) -> Self {
        Self {
            render_mesh: render_mesh.map(Arc::new),
            options,
            ..Self::default()
        }
    }

    /// Whether a rebuild of the surface is running beside the frames (see
    /// [`crate::ecs::resources::SurfaceBudget`]): the triangles are still the last ones.
    pub fn is_rebuilding(&self) -> bool {
        self.deferred.is_some()
    }

    /// Makes a rebuild running beside the frames due at `frame` at the latest.
    pub(crate) fn hurry(&mut self, frame: u64) {
        if let Some(job) = &mut self.deferred {
            job.due = job.due.min(frame);
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
    /// [`crate::body::lattice::Lattice::pieces`] numbers them: by their lowest live
    /// particle, so ids are not stable across later cuts — a cut renumbers the pieces
    /// after the one it splits; follow a piece by one of its particles).
    pub fn triangle_pieces(&self) -> &[u32] {
        &self.topology.triangle_piece
    }

    /// Per vertex, the piece of the body it belongs to (numbered as
    /// [`SurfaceMesh::triangle_pieces`]; a vertex no triangle uses gets `u32::MAX`).
    pub fn vertex_pieces(&self) -> Vec<u32> {
        let mut piece = vec![u32::MAX; self.positions.len()];
        for (t, &p) in self.triangles().iter().zip(self.triangle_pieces()) {
            for &v in t {
                if let Some(at) = piece.get_mut(v as usize) {
                    *at = p;
                }
            }
        }
        piece
    }

    /// The triangles sorted by piece (stably), with each piece's range in them: to draw
    /// or upload one piece at a time.
    pub fn triangles_by_piece(&self) -> (Vec<[u32; 3]>, Vec<PieceRange>) {
        let mut order: Vec<usize> = (0..self.triangles().len()).collect();
        let pieces = self.triangle_pieces();
        order.sort_by_key(|&t| pieces[t]);
        let sorted = order.iter().map(|&t| self.triangles()[t]).collect();
        let mut ranges: Vec<PieceRange> = Vec::new();
        for (i, &t) in order.iter().enumerate() {
            match ranges.last_mut() {
                Some((p, r)) if *p == pieces[t] => r.end = i + 1,
                _ => ranges.push((pieces[t], i..i + 1)),
            }
        }
        (sorted, ranges)
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
            shown: self.shown.clone(),
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
            && saved
                .gathered
                .iter()
                .chain(&saved.shown)
                .all(|x| x.is_finite())
            && saved
                .positions
                .iter()
                .chain(&saved.normals)
                .all(|x| x.is_finite());
        if saved.frames.len() != layout.carrier_count()
            || saved.gathered.len() != layout.read.len()
            || saved.shown.len() != layout.read.len()
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
            dense_slots: Vec::new(),
            dense_for: None,
            frames: saved.frames,
            faces: Vec::new(),
            render_mesh: saved.render_mesh.map(Arc::new),
            options: saved.options,
            seen: saved.seen,
            deformed_at: saved.deformed_at,
            shown: saved.shown,
            deferred: None,
        })
    }
}

/// A surface as a save keeps it: the topology, the carriers' frames, last positions and
/// positions last shown, the render mesh and options, and what the stage last saw — so
/// that a loaded simulation draws, and goes on drawing, exactly what the saved one would
/// have. The carriers' layout is derived again on loading.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct SavedSurface {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    topology_version: u64,
    topology: SurfaceTopology,
    gathered: Vec<Vec3A>,
    shown: Vec<Vec3A>,
    frames: Vec<Quat>,
    render_mesh: Option<EmbeddedMesh>,
    options: SurfaceOptions,
    seen: LatticeState,
    deformed_at: Option<u64>,
}
