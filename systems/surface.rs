//! Stage surface: every body's [`SurfaceMesh`] brought up to date — its triangles
//! extracted again when the body's lattice changed (a cut, split or tear) or it has
//! none yet (the lattice's surface, or the body's render mesh with the cut faces the
//! lattice's surface adds to it), then its vertices carried to where the particles are
//! ([`crate::surface::deform`]). Writes surface data only.

use crate::ecs::components::{BodyLattice, Position};
use crate::ecs::resources::SurfaceChanged;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::surface::extract::extract_with_faces;
use crate::surface::smooth::smooth;
use crate::surface::{CarryLayout, deform, extract};
use bevy_ecs::prelude::*;
use glam::Mat3A;
use rayon::prelude::*;

/// Updates the surface of every body that has one.
pub fn update_surfaces(
    mut bodies: Query<(Entity, Ref<BodyLattice>, &mut SurfaceMesh)>,
    positions: Query<&Position>,
    mut changed: MessageWriter<SurfaceChanged>,
) {
    for (body, lattice, mut mesh) in &mut bodies {
        let mesh = &mut *mesh;
        let l = &lattice.lattice;
        if mesh.topology_version == 0 || lattice.is_changed() {
            mesh.topology = match &mesh.render_mesh {
                None if mesh.options.smooth => {
                    let mut surface = extract(l);
                    smooth(l, &mut surface);
                    surface
                }
                None => extract(l),
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
            mesh.topology_version += 1;
            changed.write(SurfaceChanged {
                body,
                topology_version: mesh.topology_version,
            });
        }
        mesh.gathered
            .par_iter_mut()
            .with_min_len(4096)
            .zip(&mesh.layout.read)
            .for_each(|(at, &p)| {
                // (a particle whose entity is gone keeps its last place)
                let entity = lattice.particles.get(p as usize);
                if let Some(x) = entity.and_then(|e| positions.get(*e).ok()) {
                    *at = x.0.into();
                }
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
    }
}
