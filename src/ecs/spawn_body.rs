//! Spawning a body, step by step: its description checked, its shape voxelised (within
//! the memory budget and the solver's reach), the regions it names selected, its
//! particles and clusters spawned as entities, and its pins, attachments and handles
//! attached.

use crate::body::groups::ParticleGroups;
use crate::body::lattice::Lattice;
use crate::clusters::clustering::{clusters_on_grid, seed_grid_offset};
use crate::clusters::index::ClusterIndex;
use crate::clusters::store::ClusterTable;
use crate::config::ranges;
use crate::ecs::attach::{TargetMotion, centroid_pose, check_compliance, spawn_attachment};
use crate::ecs::components::*;
use crate::ecs::desc::{BodyDesc, HandleDesc, Region};
use crate::ecs::groups::cluster_compliance;
use crate::ecs::resources::*;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::{CleaveError, Result, check_range, check_vec_within};
use crate::math::rotation::unit_quaternion;
use crate::solver::clusters::term::MAX_SOLVER_PARTICLES;
use crate::surface::embed::EmbeddedMesh;
use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

/// Spawns a body into any world prepared with [`crate::systems::install`]: its
/// description checked, its shape voxelised, the regions its attachments, pins, handles
/// and groups name selected, its particles and clusters spawned, and its holds attached.
pub fn spawn_body(world: &mut World, desc: &BodyDesc) -> Result<Entity> {
    spawn_body_into(world, None, desc)
}

/// [`spawn_body`], making the entity `into` (if given, else a new one) the body.
pub(crate) fn spawn_body_into(
    world: &mut World,
    into: Option<Entity>,
    desc: &BodyDesc,
) -> Result<Entity> {
    let rotation = check_placement(desc)?;
    let handles = check_holds(desc)?;
    let (lattice, render_mesh) = voxelise(world, desc)?;
    let placed = |i: u32| desc.position + rotation * lattice.rest_position(i);
    let regions = select_regions(desc, &lattice, &handles, placed)?;
    let seed_grid = seed_grid_offset(&desc.material, &mut world.resource_mut::<SimRng>().0);
    let table = clusters_on_grid(&lattice, &desc.material, seed_grid);
    let body = spawn_into(
        world,
        into,
        Body {
            material: desc.material.clone(),
            seed_grid,
            groups: regions.groups.clone(),
        },
    );
    let particles = spawn_particles(world, desc, body, &lattice, placed);
    let compliance = |members: &[u32]| {
        cluster_compliance(&desc.material, &regions.groups, members, desc.spacing)
    };
    let (clusters, _) = spawn_clusters(world, body, &table, lattice.len(), compliance);
    let pieces = lattice.piece_count();
    world.entity_mut(body).insert((
        BodyLattice {
            lattice,
            particles,
            pieces,
        },
        clusters,
        SurfaceMesh::new(render_mesh, desc.surface),
    ));
    attach(world, desc, body, regions, &handles);
    Ok(body)
}

/// The entity `into` (if given, else a new one) with `bundle`.
pub(crate) fn spawn_into(world: &mut World, into: Option<Entity>, bundle: impl Bundle) -> Entity {
    match into {
        Some(e) => world.entity_mut(e).insert(bundle).id(),
        None => world.spawn(bundle).id(),
    }
}

/// Checks the body's material, spacing, placement, motion and pins; returns its
/// rotation, normalised.
fn check_placement(desc: &BodyDesc) -> Result<Quat> {
    desc.material.validate()?;
    ranges::SPACING.check("spacing", desc.spacing)?;
    // a ball wider than two spacings would overlap balls two cells away at rest, and
    // makes every particle's neighbourhood search grow as its cube
    if let Some(r) = desc.material.contact_radius
        && r > 2.0 * desc.spacing
    {
        return Err(crate::error::out_of_range(
            "material.contact_radius",
            r,
            "≤ 2 × spacing (metres)",
        ));
    }
    check_vec_within("body.position", desc.position, &crate::error::POSITION)?;
    check_vec_within("body.velocity", desc.velocity, &crate::error::VELOCITY)?;
    let rotation = unit_quaternion(desc.rotation).ok_or_else(|| {
        crate::error::out_of_range("body.rotation", desc.rotation, crate::error::ROTATION)
    })?;
    check_vec_within(
        "body.angular_velocity",
        desc.angular_velocity,
        &crate::error::ANGULAR_VELOCITY,
    )?;
    for (i, pin) in desc.pins.iter().enumerate() {
        pin.validate(&format!("body.pins[{i}]"))?;
    }
    Ok(rotation)
}

/// The name a scene file gives attachment `i` of `desc`: its place among those of its
/// kind.
fn attachment_field(desc: &BodyDesc, i: usize) -> String {
    let hold = desc.attachments[i].hold;
    let k = desc.attachments[..i]
        .iter()
        .filter(|a| a.hold == hold)
        .count();
    match hold {
        Hold::Each => format!("body.attachments[{k}]"),
        Hold::Centroid => format!("body.centroids[{k}]"),
    }
}

/// Checks the body's attachments, handles, jitter and particle mass; returns its
/// handles, their keys normalised.
fn check_holds(desc: &BodyDesc) -> Result<Vec<HandleDesc>> {
    for (i, a) in desc.attachments.iter().enumerate() {
        let field = attachment_field(desc, i);
        a.region.validate(&format!("{field}.region"))?;
        check_compliance(&field, a.compliance)?;
        a.path.validate(&field)?;
    }
    let mut handles = desc.handles.clone();
    crate::ecs::handles::check_handles(&mut handles)?;
    crate::ecs::handles::check_rigid_keys(&handles)?;
    ranges::JITTER.check("body.jitter", desc.jitter)?;
    check_range(
        "material.particle_mass",
        desc.material.mass_at_spacing(desc.spacing),
        1e-9,
        1e9,
        "1e-9 ≤ density·spacing³ ≤ 1e9 (kg per particle)",
    )?;
    Ok(handles)
}

/// The body's lattice, within the memory budget and the solver's reach, and the render
/// mesh embedded in it (its own, or the shape's mesh).
fn voxelise(world: &mut World, desc: &BodyDesc) -> Result<(Lattice, Option<EmbeddedMesh>)> {
    let budget = world
        .get_resource::<SimSettings>()
        .map_or(crate::body::shape::DEFAULT_MEMORY_BUDGET_GB, |s| {
            s.0.memory_budget_gb
        });
    let lattice = desc.shape.voxelise_within(desc.spacing, budget)?;
    check_particle_budget(existing_particles(world), lattice.len() as u64)?;
    check_surface_budget(&lattice, budget)?;
    let render_mesh = match (&desc.render_mesh, &desc.shape) {
        (Some(mesh), _) | (None, crate::body::shape::Shape::Mesh(mesh)) => {
            Some(EmbeddedMesh::new(&lattice, mesh)?)
        }
        _ => None,
    };
    Ok((lattice, render_mesh))
}

/// The particles each attachment, pin and handle holds, where they are placed, and the
/// body's groups.
struct Regions {
    attached: Vec<Vec<u32>>,
    attached_at: Vec<Vec<Vec3>>,
    pinned: Vec<Vec<u32>>,
    pinned_at: Vec<Vec<Vec3>>,
    held: Vec<Vec<u32>>,
    /// Every particle's place, when the body has handles.
    held_at: Vec<Vec3>,
    groups: ParticleGroups,
}

/// Selects the regions `desc` names among the lattice's particles placed by `placed`
/// (a region that holds none is an error for an attachment or a handle, nothing for a
/// pin).
fn select_regions(
    desc: &BodyDesc,
    lattice: &Lattice,
    handles: &[HandleDesc],
    placed: impl Fn(u32) -> Vec3 + Copy,
) -> Result<Regions> {
    let in_region = |region: Region| -> Vec<u32> {
        lattice
            .live_particles()
            .filter(|&i| region.contains(placed(i)))
            .collect()
    };
    let attached: Vec<Vec<u32>> = desc
        .attachments
        .iter()
        .map(|a| in_region(a.region))
        .collect();
    if let Some(i) = attached.iter().position(Vec::is_empty) {
        return Err(crate::error::out_of_range(
            &format!("{}.region", attachment_field(desc, i)),
            (
                desc.attachments[i].region.min,
                desc.attachments[i].region.max,
            ),
            "a region holding at least one of the body's particles",
        ));
    }
    let live: Vec<u32> = lattice.live_particles().collect();
    let held = crate::ecs::handles::select_handles(handles, &live, placed)?;
    let held_at: Vec<Vec3> = match handles.is_empty() {
        true => Vec::new(),
        false => (0..lattice.len() as u32).map(placed).collect(),
    };
    let pinned: Vec<Vec<u32>> = desc.pins.iter().map(|p| in_region(p.region())).collect();
    let positions_of = |lists: &[Vec<u32>]| -> Vec<Vec<Vec3>> {
        lists
            .iter()
            .map(|list| list.iter().map(|&i| placed(i)).collect())
            .collect()
    };
    let groups = crate::ecs::groups::select_groups(
        &desc.groups,
        &desc.stiffness_regions,
        &desc.material,
        &live,
        placed,
    )?;
    Ok(Regions {
        attached_at: positions_of(&attached),
        pinned_at: positions_of(&pinned),
        attached,
        pinned,
        held,
        held_at,
        groups,
    })
}

/// Spawns the body's particles at their places (jittered as `desc` asks, moving with
/// the body or their pin); returns each lattice particle's entity.
fn spawn_particles(
    world: &mut World,
    desc: &BodyDesc,
    body: Entity,
    lattice: &Lattice,
    placed: impl Fn(u32) -> Vec3,
) -> Vec<Entity> {
    // In the solver layout's (Morton) order, so that the particle table's rows and the
    // layout's slots run in step and the shape-match stage copies them in sequence; in one
    // batch, so that the table is sized once instead of grown by doubling.
    let order = lattice.live_in_morton_order();
    let inv_mass = 1.0 / desc.material.mass_at_spacing(desc.spacing);
    let jitter = jitter_offsets(
        order.len(),
        desc.jitter * desc.spacing,
        &mut world.resource_mut::<SimRng>().0,
    );
    let spawned = world.spawn_batch(order.iter().zip(jitter).map(|(&i, jitter)| {
        let x = placed(i) + jitter;
        let pin = desc.pins.iter().find(|r| r.contains(placed(i)));
        (
            Particle { body, index: i },
            Position(x),
            Velocity(pin.map_or(
                desc.velocity + desc.angular_velocity.cross(x - desc.position),
                |r| r.velocity,
            )),
            // (turned from the rest frame as the body is: the oriented model's fit weighs
            // orientations against positions, so any other start is a twist to undo)
            Orientation(desc.rotation),
            AngularVelocity(desc.angular_velocity),
            InvMass(inv_mass),
        )
    }));
    let mut particles = vec![Entity::PLACEHOLDER; lattice.len()];
    for (&i, e) in order.iter().zip(spawned) {
        particles[i as usize] = e;
    }
    particles
}

/// Spawns the body's pins, attachments and handles' attachments.
fn attach(
    world: &mut World,
    desc: &BodyDesc,
    body: Entity,
    regions: Regions,
    handles: &[HandleDesc],
) {
    let now = world.get_resource::<SimClock>().map_or(0.0, |c| c.time) as f32;
    let pins = desc.pins.iter().zip(regions.pinned).zip(regions.pinned_at);
    for ((pin, particles), positions) in pins {
        if particles.is_empty() {
            continue;
        }
        let pose = centroid_pose(&positions);
        let motion = TargetMotion::Velocity(pin.velocity);
        spawn_attachment(
            world.spawn_empty(),
            body,
            particles,
            &positions,
            0.0,
            Hold::Each,
            pose,
            motion,
        );
    }
    let attachments = desc
        .attachments
        .iter()
        .zip(regions.attached)
        .zip(regions.attached_at);
    for ((a, particles), positions) in attachments {
        let path = a.path.normalized();
        let (pose, motion) = match path.sample(now) {
            Some(pose) => (pose, TargetMotion::Path(path)),
            None => (centroid_pose(&positions), TargetMotion::Still),
        };
        spawn_attachment(
            world.spawn_empty(),
            body,
            particles,
            &positions,
            a.compliance,
            a.hold,
            pose,
            motion,
        );
    }
    let at = |i: u32| regions.held_at[i as usize];
    crate::ecs::handles::spawn_handle_attachments(world, body, handles, regions.held, at);
}

/// Particle slots of the bodies already in `world` (live or cut).
fn existing_particles(world: &mut World) -> u64 {
    let Some(mut bodies) = world.try_query::<&BodyLattice>() else {
        return 0;
    };
    bodies.iter(world).map(|b| b.lattice.len() as u64).sum()
}

/// Refuses a body of `new` particle slots next to `existing` ones when the solver could
/// not address them all.
fn check_particle_budget(existing: u64, new: u64) -> Result<()> {
    let particles = existing.saturating_add(new);
    if particles > MAX_SOLVER_PARTICLES {
        return Err(CleaveError::TooManyParticles {
            particles,
            max: MAX_SOLVER_PARTICLES,
        });
    }
    Ok(())
}

/// Refuses a body whose surface and particles together would pass the memory budget of
/// `budget_gb` gigabytes.
fn check_surface_budget(lattice: &Lattice, budget_gb: f32) -> Result<()> {
    use crate::surface::extract::{BYTES_PER_FACE, face_count};
    let faces = face_count(lattice);
    let gigabytes = super::budget::surface_bytes(faces) as f64 / 1e9;
    let particle_gigabytes = super::budget::particle_bytes(lattice.len() as u64) as f64 / 1e9;
    if gigabytes + particle_gigabytes > budget_gb as f64 {
        return Err(CleaveError::SurfaceOverBudget {
            faces,
            gigabytes,
            particle_gigabytes,
            bytes_per_face: BYTES_PER_FACE,
            budget_gigabytes: budget_gb,
        });
    }
    Ok(())
}

/// `count` offsets, each uniform in the ball of radius `radius` (rejection from its
/// cube), drawn from `rng`; all zero, drawing nothing, when `radius` is 0.
fn jitter_offsets(count: usize, radius: f32, rng: &mut impl rand::Rng) -> Vec<Vec3> {
    if radius == 0.0 {
        return vec![Vec3::ZERO; count];
    }
    (0..count)
        .map(|_| {
            loop {
                let v = Vec3::new(
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                    rng.random_range(-1.0..=1.0),
                );
                if v.length_squared() <= 1.0 {
                    break v * radius;
                }
            }
        })
        .collect()
}

/// Spawns the clusters of `table` as entities of `body`, with keys in table order;
/// returns the body's cluster data and the entities, in order.
pub(super) fn spawn_clusters(
    world: &mut World,
    body: Entity,
    table: &ClusterTable,
    particles: usize,
    compliance: impl Fn(&[u32]) -> f32,
) -> (ParticleClusters, Vec<Entity>) {
    let mut clusters = ParticleClusters {
        index: ClusterIndex::new(particles),
        keys: ClusterKeys::default(),
    };
    let mut entities = Vec::with_capacity(table.len());
    for (_, members) in table.iter() {
        // (fresh keys count up from 0: the key is known before the entity)
        let key = clusters.keys.len() as u32;
        let e = world
            .spawn((
                ClusterMembers(members.to_vec()),
                ClusterOf { body, key },
                Compliance(compliance(members)),
            ))
            .id();
        let named = clusters.keys.insert(e);
        debug_assert_eq!(named, key);
        clusters.index.add_cluster(key, members);
        entities.push(e);
    }
    (clusters, entities)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodies_past_the_solver_limit_are_refused() {
        assert!(check_particle_budget(0, MAX_SOLVER_PARTICLES).is_ok());
        assert!(check_particle_budget(MAX_SOLVER_PARTICLES - 10, 10).is_ok());
        for (existing, new) in [
            (MAX_SOLVER_PARTICLES, 1),
            (1, MAX_SOLVER_PARTICLES),
            (u64::MAX, 5),
        ] {
            let err = check_particle_budget(existing, new).unwrap_err();
            assert!(
                matches!(err, CleaveError::TooManyParticles { max, .. } if max == MAX_SOLVER_PARTICLES),
                "{err}"
            );
        }
    }
}
