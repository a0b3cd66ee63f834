//! Stage surface: every body's [`SurfaceMesh`] brought up to date — its triangles
//! updated around what this frame's cut changed in the body's lattice
//! ([`crate::surface::update`]), or extracted again when the lattice changed otherwise
//! or the body has none yet (the lattice's surface, or the body's render mesh with the
//! cut faces the lattice's surface adds to it), then its vertices carried to where the
//! particles are ([`crate::surface::deform`]) when they moved ([`SurfaceMesh::STILL`]).
//! Writes surface data only.
//!
//! The cut's report says what changed; a lattice edited from outside in a frame that
//! also cuts it is updated around the cut's changes only.
//!
//! A change past the [`SurfaceBudget`] (a huge body diced at once) is not made within
//! the frame: its rebuild runs on the rayon pool beside the frames that follow, the body
//! drawing its last surface meanwhile, and is put in place at the frame it is due
//! (waited for then, if need be), which a [`SurfaceDeferred`] names. A further change
//! before then drops it for an extraction of the newest lattice.

use crate::body::lattice::Lattice;
use crate::ecs::components::{BodyLattice, Position};
use crate::ecs::layout::{SolverCache, SolverLayout};
use crate::ecs::resources::{
    BodyCutReport, CutReport, SimClock, SurfaceBudget, SurfaceChanged, SurfaceDeferred,
};
use crate::ecs::surface_mesh::{
    DeferredSurface, JobResult, JobSlot, LatticeState, RebuiltSurface, SurfaceMesh,
};
use crate::surface::embed::EmbeddedMesh;
use crate::surface::extract::{
    QUADS_PER_SPLIT_FACE, SurfaceTopology, extract_with_faces, face_count, quads_per_face,
};
use crate::surface::smooth::smooth;
use crate::surface::update::update;
use crate::surface::{CarryLayout, SpareLists, deform, extract};
use bevy_ecs::prelude::*;
use glam::{Mat3A, Vec3A};
use rayon::prelude::*;
use std::sync::Arc;

/// Updates the surface of every body that has one; a surface already brought up to
/// date in this frame, whose lattice has not changed since, is left as it is (so that
/// running the stage again — [`crate::sim::simulation::Simulation::update_surfaces`] —
/// changes nothing). A change past the [`SurfaceBudget`] is rebuilt beside the frames
/// and put in place when due.
#[allow(clippy::too_many_arguments)]
pub fn update_surfaces(
    mut bodies: Query<(Entity, &BodyLattice, &mut SurfaceMesh)>,
    positions: Query<&Position>,
    cut: Res<CutReport>,
    cache: Res<SolverCache>,
    clock: Res<SimClock>,
    budget: Option<Res<SurfaceBudget>>,
    mut changed: MessageWriter<SurfaceChanged>,
    mut deferred: MessageWriter<SurfaceDeferred>,
) {
    let budget = budget.as_deref().copied().unwrap_or_default();
    for (body, lattice, mut marked) in &mut bodies {
        let l = &lattice.lattice;
        let seen = lattice_state(l);
        let new_topology = marked.topology_version == 0 || marked.seen != seen;
        if !new_topology && marked.deformed_at == Some(clock.frame) {
            continue;
        }
        // marked changed below only when it changed (see `SurfaceMesh::STILL`)
        let mesh = marked.bypass_change_detection();
        let mut installed = false;
        if new_topology {
            match mesh.deferred.take() {
                // a rebuild of this very lattice, running beside the frames
                Some(job) if job.seen == seen => {
                    if clock.frame >= job.due {
                        let rebuilt = job.wait().unwrap_or_else(|| {
                            Source::of(mesh, None).rebuild(l, None, SpareLists::default())
                        });
                        install(mesh, l, rebuilt);
                        installed = true;
                    } else {
                        mesh.deferred = Some(job);
                    }
                }
                // none, or one for a lattice changed since (dropped: the cut report
                // explains no change since then, so the surface is extracted again)
                _ => {
                    let touched =
                        explained_by_cut(mesh, l, cut.bodies.iter().find(|c| c.body == body));
                    let source = Source::of(mesh, touched);
                    let quads = source.quads(mesh, l);
                    if mesh.topology_version > 0 && quads > budget.quads {
                        let due = clock.frame + budget.frames.max(1);
                        mesh.deferred = Some(source.spawn(mesh, l.clone(), seen, due));
                        tracing::warn!(
                            "the surface of {body} changes by about {quads} quads, more than a frame's budget of {}: it is rebuilt beside the frames and in place at frame {due}",
                            budget.quads
                        );
                        deferred.write(SurfaceDeferred { body, quads, due });
                    } else {
                        // (the surface is replaced: the update edits it where it lies)
                        let old = source
                            .touched
                            .is_some()
                            .then(|| std::mem::take(&mut mesh.topology));
                        // (the new layout is written into the old one's lists)
                        let spare = mesh.layout.take_lists();
                        let rebuilt = source.rebuild(l, old, spare);
                        install(mesh, l, rebuilt);
                        installed = true;
                    }
                }
            }
        }
        if installed {
            changed.write(SurfaceChanged {
                body,
                topology_version: mesh.topology_version,
            });
        }
        let report = cut.bodies.iter().find(|c| c.body == body);
        let moved = gather(
            mesh,
            body,
            report,
            &cache.layout,
            &cache.particles.positions,
            l.spacing(),
            |p| {
                let e = lattice.particles.get(p as usize)?;
                positions.get(*e).ok().map(|x| x.0.into())
            },
        );
        mesh.deformed_at = Some(clock.frame);
        // A surface at rest keeps the vertices it shows: they are within `STILL` of
        // where its particles are, as an unmarked mesh is, and a body at rest costs
        // only the gather.
        if moved || installed {
            carry_vertices(mesh);
            show_gathered(mesh);
            marked.set_changed();
        }
    }
}

/// Records the gathered positions as those `mesh` shows (copied in parallel: they are
/// every slot's).
fn show_gathered(mesh: &mut SurfaceMesh) {
    mesh.shown.resize(mesh.gathered.len(), Vec3A::ZERO);
    (mesh.shown.par_chunks_mut(GATHER_PER_TASK))
        .zip(mesh.gathered.par_chunks(GATHER_PER_TASK))
        .for_each(|(shown, gathered)| shown.copy_from_slice(gathered));
}

/// Carries `mesh`'s vertices to its gathered particles: the carriers' frames, then the
/// vertices' positions and normals.
fn carry_vertices(mesh: &mut SurfaceMesh) {
    deform::particle_frames(
        &mesh.layout,
        &mesh.gathered,
        &mut mesh.frames,
        &mut mesh.rotations,
    );
    deform::vertex_positions(
        &mesh.topology,
        &mesh.layout,
        &mesh.gathered,
        &mesh.rotations,
        &mut mesh.positions,
    );
    deform::vertex_normals(
        &mesh.topology,
        &mesh.layout,
        &mesh.positions,
        &mut mesh.faces,
        &mut mesh.normals,
    );
}

/// Slots per parallel task of [`gather`].
const GATHER_PER_TASK: usize = 4096;

/// Gathers the positions of the particles `mesh`'s carriers read into its slots: the
/// solver's dense positions, which are the particles' since the substeps stored them,
/// except where only `entity_position` (the particle's entity) has it: a particle the
/// solver does not hold, or a half of a particle the cut split this frame (moved since).
/// Each slot's dense index is looked up once per body, topology and solver layout
/// ([`SolverLayout::stamp`]), and again in the frame after a split.
///
/// Returns whether a slot now lies more than [`SurfaceMesh::STILL`] spacings (of a
/// lattice spaced `spacing`) from where the mesh last showed it, or the slots changed
/// (checked in the same pass, not in one of its own).
fn gather(
    mesh: &mut SurfaceMesh,
    body: Entity,
    report: Option<&BodyCutReport>,
    layout: &SolverLayout,
    solved: &[Vec3A],
    spacing: f32,
    entity_position: impl Fn(u32) -> Option<Vec3A> + Sync,
) -> bool {
    let mut split: Vec<u32> = report.map_or(Vec::new(), |r| {
        r.splits.iter().flat_map(|&(a, b)| [a, b]).collect()
    });
    split.sort_unstable();
    let key = (body, mesh.topology_version, layout.stamp());
    if mesh.dense_for != Some(key) || !split.is_empty() {
        let dense = layout.body(body);
        mesh.dense_slots.clear();
        mesh.dense_slots
            .par_extend(mesh.layout.read.par_iter().with_min_len(4096).map(|&p| {
                dense
                    .and_then(|b| b.slot(p))
                    .filter(|_| split.binary_search(&p).is_err())
                    .map_or(u32::MAX, |d| d as u32)
            }));
        mesh.dense_for = split.is_empty().then_some(key);
    }
    let limit = (SurfaceMesh::STILL * spacing).powi(2);
    let (read, dense, shown) = (&mesh.layout.read, &mesh.dense_slots, &mesh.shown);
    let same_slots = shown.len() == mesh.gathered.len();
    // (a plain loop per task: the slots are many and each is a few instructions)
    let moved = (mesh.gathered.par_chunks_mut(GATHER_PER_TASK).enumerate())
        .map(|(task, gathered)| {
            let first = task * GATHER_PER_TASK;
            let mut moved = false;
            for (slot, at) in (first..).zip(gathered) {
                if let Some(x) = solved
                    .get(dense[slot] as usize)
                    .copied()
                    .or_else(|| entity_position(read[slot]))
                {
                    *at = x;
                }
                // (a particle whose entity is gone keeps its last place; one slot
                // that moved is enough to tell)
                moved = moved || same_slots && at.distance_squared(shown[slot]) > limit;
            }
            moved
        })
        .reduce(|| false, |a, b| a || b);
    moved || !same_slots
}

/// What a surface records of the lattice it was made from.
fn lattice_state(l: &Lattice) -> LatticeState {
    (l.len(), l.live_count(), l.edits())
}

/// Puts a rebuilt surface in place: its topology and carriers' layout, the carriers'
/// frames and positions carried over from the last layout.
fn install(mesh: &mut SurfaceMesh, l: &Lattice, rebuilt: RebuiltSurface) {
    let (topology, layout, ms) = rebuilt;
    mesh.topology = topology;
    mesh.frames = layout.carry_frames(l, &mesh.layout, &mesh.frames);
    mesh.rotations = vec![Mat3A::IDENTITY; layout.carrier_count()];
    mesh.gathered = layout.carry_positions(&mesh.layout, &mesh.gathered);
    mesh.layout = layout;
    mesh.seen = lattice_state(l);
    mesh.topology_version += 1;
    mesh.topology_ms = ms;
}

/// What a body's new surface is made from: the lattice's surface updated around the
/// particles a cut touched, or extracted again (and smoothed, as the options say), or
/// the render mesh with the lattice surface's cut faces.
struct Source {
    render: Option<Arc<EmbeddedMesh>>,
    smooth: bool,
    /// The particles the cut touched, when the last surface can be updated around them.
    touched: Option<Vec<u32>>,
}

impl Source {
    /// The source of `mesh`'s next surface, updated locally around `touched` when the
    /// surface is the lattice's and unsmoothed.
    fn of(mesh: &SurfaceMesh, touched: Option<Vec<u32>>) -> Self {
        let lattice_surface = mesh.render_mesh.is_none() && !mesh.options.smooth;
        Self {
            render: mesh.render_mesh.clone(),
            smooth: mesh.options.smooth,
            touched: touched.filter(|_| lattice_surface),
        }
    }

    /// About how many quads the rebuild makes: those of the touched particles' faces
    /// for a local update (each touched particle gains about one face, drawn as
    /// `resolution²` quads), the whole surface for an extraction — four quads per face
    /// once a particle of the body is split (so after its first split particle, whose
    /// surface is extracted again).
    fn quads(&self, mesh: &SurfaceMesh, l: &Lattice) -> usize {
        let res = mesh.topology.resolution.max(1) as usize;
        let whole = |quads_per_face: u64| (face_count(l) * quads_per_face) as usize;
        match &self.touched {
            Some(touched) if res == 1 && touched.iter().any(|&p| l.is_split_half(p)) => {
                whole(QUADS_PER_SPLIT_FACE)
            }
            Some(touched) => touched.len() * res * res,
            None => whole(quads_per_face(l)),
        }
    }

    /// The new surface of `l` (updated from `old`, the last surface, where it can be),
    /// with its carriers' layout (written into `spare`) and the milliseconds it took.
    fn rebuild(
        &self,
        l: &Lattice,
        old: Option<SurfaceTopology>,
        spare: SpareLists,
    ) -> RebuiltSurface {
        let start = std::time::Instant::now();
        let topology = match (&self.render, &self.touched) {
            (Some(render), _) => {
                let (surface, faces) = extract_with_faces(l);
                render.drawn(l, &surface, &faces)
            }
            (None, _) if self.smooth => {
                let mut surface = extract(l);
                smooth(l, &mut surface);
                surface
            }
            (None, Some(touched)) => {
                (old.and_then(|old| update(l, old, touched))).unwrap_or_else(|| extract(l))
            }
            (None, None) => extract(l),
        };
        let layout = CarryLayout::new_into(l, &topology, spare);
        (topology, layout, start.elapsed().as_secs_f64() * 1e3)
    }

    /// Rebuilds the surface of `lattice` (a copy: the body goes on meanwhile) from
    /// `mesh`'s on the rayon pool, to be put in place at frame `due`.
    fn spawn(
        self,
        mesh: &SurfaceMesh,
        lattice: Lattice,
        seen: LatticeState,
        due: u64,
    ) -> DeferredSurface {
        let old = self.touched.as_ref().map(|_| mesh.topology.clone());
        let result = JobSlot::default();
        let slot = result.clone();
        rayon::spawn(move || {
            let rebuilt = self.rebuild(&lattice, old, SpareLists::default());
            let (slot, done) = &*slot;
            *slot.lock().unwrap_or_else(|e| e.into_inner()) = JobResult {
                done: true,
                rebuilt: Some(rebuilt),
            };
            done.notify_all();
        });
        DeferredSurface { seen, due, result }
    }
}

/// The particles this frame's cut touched in a body (removed, split, or with links
/// severed or made) when they account for every change to its lattice since `mesh` was
/// last brought up to date — its particle counts then, moved by what the cut removed
/// and split, are the lattice's now — so that a local update will do; `None` for a
/// change from elsewhere, or a surface never extracted.
fn explained_by_cut(
    mesh: &SurfaceMesh,
    lattice: &Lattice,
    cut: Option<&BodyCutReport>,
) -> Option<Vec<u32>> {
    let cut = cut.filter(|_| mesh.topology_version > 0)?;
    let (len, live, _) = mesh.seen;
    let expected = (
        len + cut.splits.len(),
        (live + cut.splits.len()).checked_sub(cut.removed.len())?,
    );
    if expected != (lattice.len(), lattice.live_count()) {
        return None;
    }
    let mut touched: Vec<u32> = cut.removed.clone();
    for &(a, b) in cut.splits.iter().chain(&cut.severed).chain(&cut.relinked) {
        touched.extend([a, b]);
    }
    Some(touched)
}
