//! Stage surface: every body's [`SurfaceMesh`] brought up to date — its triangles
//! updated around what this frame's cut changed in the body's lattice
//! ([`crate::surface::update`]), or extracted again when the lattice changed otherwise
//! or the body has none yet (the lattice's surface, or the body's render mesh with the
//! cut faces the lattice's surface adds to it), then its vertices carried to where the
//! particles are ([`crate::surface::deform`]). Writes surface data only.
//!
//! The cut's report says what changed; a lattice edited from outside in a frame that
//! also cuts it is updated around the cut's changes only.

use crate::body::lattice::Lattice;
use crate::ecs::components::{BodyLattice, Position};
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{BodyCutReport, CutReport, SimClock, SurfaceChanged};
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::surface::extract::extract_with_faces;
use crate::surface::smooth::smooth;
use crate::surface::update::update;
use crate::surface::{CarryLayout, deform, extract};
use bevy_ecs::prelude::*;
use glam::Mat3A;
use rayon::prelude::*;

/// Updates the surface of every body that has one; a surface already brought up to
/// date in this frame, whose lattice has not changed since, is left as it is (so that
/// running the stage again — [`crate::sim::simulation::Simulation::update_surfaces`] —
/// changes nothing).
pub fn update_surfaces(
    mut bodies: Query<(Entity, &BodyLattice, &mut SurfaceMesh)>,
    positions: Query<&Position>,
    cut: Res<CutReport>,
    cache: Res<SolverCache>,
    clock: Res<SimClock>,
    mut changed: MessageWriter<SurfaceChanged>,
) {
    for (body, lattice, mut marked) in &mut bodies {
        let l = &lattice.lattice;
        let seen = (l.len(), l.live_count(), l.edits());
        let new_topology = marked.topology_version == 0 || marked.seen != seen;
        if !new_topology && marked.deformed_at == Some(clock.frame) {
            continue;
        }
        // marked changed below only when it changed (see `SurfaceMesh::STILL`)
        let mesh = marked.bypass_change_detection();
        if new_topology {
            let start = std::time::Instant::now();
            let touched = explained_by_cut(mesh, l, cut.bodies.iter().find(|c| c.body == body));
            mesh.topology = match &mesh.render_mesh {
                None if mesh.options.smooth => {
                    let mut surface = extract(l);
                    smooth(l, &mut surface);
                    surface
                }
                None => touched
                    .and_then(|touched| update(l, &mesh.topology, &touched))
                    .unwrap_or_else(|| extract(l)),
                Some(render) => {
                    let (surface, faces) = extract_with_faces(l);
                    render.drawn(l, &surface, &faces)
                }
            };
            let layout = CarryLayout::new(l, &mesh.topology);
            mesh.frames = layout.carry_frames(l, &mesh.layout, &mesh.frames);
            mesh.rotations = vec![Mat3A::IDENTITY; layout.carrier_count()];
            mesh.gathered = layout.carry_positions(&mesh.layout, &mesh.gathered);
            mesh.layout = layout;
            mesh.seen = seen;
            mesh.topology_version += 1;
            mesh.topology_ms = start.elapsed().as_secs_f64() * 1e3;
            changed.write(SurfaceChanged {
                body,
                topology_version: mesh.topology_version,
            });
        }
        // the solver's dense positions are the particles' since the substeps stored
        // them; only the cut has moved some since (the halves of split particles)
        let report = cut.bodies.iter().find(|c| c.body == body);
        let mut moved: Vec<u32> = report.map_or(Vec::new(), |r| {
            r.splits.iter().flat_map(|&(a, b)| [a, b]).collect()
        });
        moved.sort_unstable();
        let dense = cache.layout.body(body);
        let solved = &cache.particles.positions;
        mesh.gathered
            .par_iter_mut()
            .with_min_len(4096)
            .zip(&mesh.layout.read)
            .for_each(|(at, &p)| {
                let slot = dense
                    .and_then(|b| b.slot(p))
                    .filter(|_| moved.binary_search(&p).is_err());
                if let Some(x) = slot.and_then(|d| solved.get(d)) {
                    *at = *x;
                } else if let Some(x) =
                    (lattice.particles.get(p as usize)).and_then(|e| positions.get(*e).ok())
                {
                    *at = x.0.into();
                }
                // (a particle whose entity is gone keeps its last place)
            });
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
        mesh.deformed_at = Some(clock.frame);
        if mesh.moved_since_shown(l.spacing()) || new_topology {
            marked.set_changed();
        }
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
