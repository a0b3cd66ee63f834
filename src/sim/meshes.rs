//! Each body's surface on screen (cargo feature `bevy_mesh`): the plugin gives every
//! body with a [`SurfaceMesh`] a [`Mesh3d`] whose `Mesh` asset it keeps in step — after
//! each simulation frame, in [`CleaveSystems::Writeback`], positions and normals written
//! in place, triangles and per-piece colours only when the triangles changed; and on every
//! app update (in `PostUpdate`), with [`MeshInterpolation`] on and `Time<Fixed>` present,
//! the positions blended between the last two frames by the fixed clock's overstep, so
//! that a 60 Hz simulation moves smoothly on a 144 Hz display (a frame behind, as
//! transform interpolation is). The meshes live in the main world and the render world
//! (`RenderAssetUsages::default()`), so that they can be written every frame. A game
//! without `Assets<Mesh>` (no renderer, no asset plugin) gets nothing and pays nothing.

use super::sets::CleaveSystems;
use crate::ecs::surface_mesh::SurfaceMesh;
use bevy_app::{App, PostUpdate};
use bevy_asset::{Assets, RenderAssetUsages};
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::ScheduleLabel;
use bevy_mesh::{Indices, Mesh, Mesh3d, PrimitiveTopology, VertexAttributeValues};
use bevy_time::{Fixed, Time};

/// Whether the drawn positions are blended between the last two simulation frames
/// (see the module docs); on by default.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshInterpolation(pub bool);

impl Default for MeshInterpolation {
    fn default() -> Self {
        Self(true)
    }
}

/// What the plugin keeps beside a body's [`Mesh3d`]: the last two frames' vertex
/// positions, the triangles' version it last uploaded, and how many times it uploaded
/// triangles (for tests and profiles).
#[derive(Component, Clone, Debug, Default)]
pub struct MeshSync {
    previous: Vec<[f32; 3]>,
    current: Vec<[f32; 3]>,
    topology_version: u64,
    /// Times the triangles (index buffer and colours) were written.
    pub index_uploads: u64,
}

/// Piece colours, by piece id modulo their count (sRGB-ish, linear floats).
const PALETTE: [[f32; 4]; 6] = [
    [0.85, 0.45, 0.35, 1.0],
    [0.35, 0.6, 0.85, 1.0],
    [0.5, 0.8, 0.4, 1.0],
    [0.9, 0.75, 0.3, 1.0],
    [0.7, 0.45, 0.8, 1.0],
    [0.4, 0.8, 0.75, 1.0],
];

/// Adds the systems: the sync after each frame in `schedule`, the blend in `PostUpdate`.
pub(super) fn install(app: &mut App, schedule: impl ScheduleLabel) {
    app.init_resource::<MeshInterpolation>();
    app.add_systems(
        schedule,
        (give_meshes, sync_meshes)
            .chain()
            .in_set(CleaveSystems::Writeback),
    );
    app.add_systems(PostUpdate, blend_meshes);
}

/// Gives every body with a surface and no mesh yet a `Mesh` asset and its [`Mesh3d`].
fn give_meshes(
    mut commands: Commands,
    meshes: Option<ResMut<Assets<Mesh>>>,
    bodies: Query<Entity, (With<SurfaceMesh>, Without<Mesh3d>)>,
) {
    let Some(mut meshes) = meshes else { return };
    for body in &bodies {
        let mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        );
        commands
            .entity(body)
            .insert((Mesh3d(meshes.add(mesh)), MeshSync::default()));
    }
}

/// Writes each changed surface into its mesh; an unchanged one (at rest) stops being
/// blended, so that it is drawn still.
fn sync_meshes(
    meshes: Option<ResMut<Assets<Mesh>>>,
    mut bodies: Query<(Ref<SurfaceMesh>, &Mesh3d, &mut MeshSync)>,
) {
    let Some(mut meshes) = meshes else { return };
    for (surface, handle, mut sync) in &mut bodies {
        let resting = !surface.is_changed();
        if resting && sync.previous.is_empty() {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(&handle.0) else {
            continue;
        };
        if resting {
            // drawn where it is, once, and no longer blended (`blend_meshes` skips a
            // mesh without a previous frame)
            write_vec3(
                &mut mesh,
                Mesh::ATTRIBUTE_POSITION,
                sync.current.iter().copied(),
            );
            sync.previous.clear();
            continue;
        }
        // the last frame's positions become the previous ones, their buffer the new
        // frame's (after a change of the triangles there is nothing to blend from)
        let sync = &mut *sync;
        std::mem::swap(&mut sync.previous, &mut sync.current);
        sync.current.clear();
        (sync.current).extend(surface.positions.iter().map(|p| p.to_array()));
        let new_topology = sync.topology_version != surface.topology_version;
        if new_topology {
            sync.previous.clone_from(&sync.current);
        }
        write_vec3(
            &mut mesh,
            Mesh::ATTRIBUTE_POSITION,
            sync.current.iter().copied(),
        );
        let normals = surface.normals.iter().map(|n| n.to_array());
        write_vec3(&mut mesh, Mesh::ATTRIBUTE_NORMAL, normals);
        if new_topology {
            let indices = surface.triangles().iter().flatten().copied().collect();
            mesh.insert_indices(Indices::U32(indices));
            let colours: Vec<[f32; 4]> = (surface.vertex_pieces().iter())
                .map(|&p| PALETTE[p as usize % PALETTE.len()])
                .collect();
            mesh.insert_attribute(Mesh::ATTRIBUTE_COLOR, colours);
            sync.topology_version = surface.topology_version;
            sync.index_uploads += 1;
        }
    }
}

/// Writes `values` into the mesh's attribute `id` in place when it has their count,
/// else replaces it.
fn write_vec3(
    mesh: &mut Mesh,
    id: bevy_mesh::MeshVertexAttribute,
    values: impl ExactSizeIterator<Item = [f32; 3]>,
) {
    if let Some(VertexAttributeValues::Float32x3(old)) = mesh.attribute_mut(id)
        && old.len() == values.len()
    {
        for (at, v) in old.iter_mut().zip(values) {
            *at = v;
        }
        return;
    }
    mesh.insert_attribute(id, values.collect::<Vec<_>>());
}

/// Blends every mesh's positions between the last two frames by the fixed clock's
/// overstep.
fn blend_meshes(
    enabled: Res<MeshInterpolation>,
    fixed: Option<Res<Time<Fixed>>>,
    meshes: Option<ResMut<Assets<Mesh>>>,
    bodies: Query<(&Mesh3d, &MeshSync)>,
) {
    let (Some(fixed), Some(mut meshes)) = (fixed, meshes) else {
        return;
    };
    if !enabled.0 {
        return;
    }
    let t = fixed.overstep_fraction().clamp(0.0, 1.0);
    for (handle, sync) in &bodies {
        if sync.previous.len() != sync.current.len() || sync.current.is_empty() {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(&handle.0) else {
            continue;
        };
        if let Some(VertexAttributeValues::Float32x3(drawn)) =
            mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
            && drawn.len() == sync.current.len()
        {
            for ((d, a), b) in drawn.iter_mut().zip(&sync.previous).zip(&sync.current) {
                for k in 0..3 {
                    d[k] = a[k] + (b[k] - a[k]) * t;
                }
            }
        }
    }
}
