//! Stage surface: every body's [`SurfaceMesh`] brought up to date — its triangles
//! extracted again when the body's lattice changed (a cut, split or tear) or it has
//! none yet, then its vertices carried to where the particles are
//! ([`crate::surface::deform`]). Writes surface data only.

use crate::ecs::components::{BodyLattice, Position};
use crate::ecs::resources::SurfaceChanged;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::surface::{deform, extract};
use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

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
            mesh.topology = extract(l);
            let mut read = mesh.topology.particles.clone();
            for &p in &mesh.topology.particles {
                read.extend(l.neighbours(p));
            }
            read.sort_unstable();
            read.dedup();
            mesh.read = read;
            // a particle new since the last extraction (a split's new half) starts from
            // the frame of a particle it is linked to, so that a turned body's halves
            // do not start from the identity where their links leave the turn open
            let known = mesh.frames.len();
            mesh.frames.resize(l.len(), Quat::IDENTITY);
            for p in known..l.len() {
                if let Some(q) = l.neighbours(p as u32).find(|q| (*q as usize) < known) {
                    mesh.frames[p] = mesh.frames[q as usize];
                }
            }
            mesh.gathered.resize(l.len(), Vec3::ZERO);
            mesh.topology_version += 1;
            changed.write(SurfaceChanged {
                body,
                topology_version: mesh.topology_version,
            });
        }
        for &p in &mesh.read {
            // (a particle despawned from outside keeps its last place until cut removes it)
            let entity = lattice.particles.get(p as usize);
            if let Some(x) = entity.and_then(|e| positions.get(*e).ok()) {
                mesh.gathered[p as usize] = x.0;
            }
        }
        deform::particle_frames(l, &mesh.topology, &mesh.gathered, &mut mesh.frames);
        deform::vertex_positions(
            &mesh.topology,
            &mesh.gathered,
            &mesh.frames,
            &mut mesh.positions,
        );
        deform::vertex_normals(&mesh.positions, &mesh.topology.triangles, &mut mesh.normals);
    }
}
