//! Spawning into any world prepared with [`crate::systems::install`]: bodies (step by
//! step in [`crate::ecs::spawn_body`], re-exported here), cutting tools and colliders;
//! and replacing a body's clusters by a fresh clustering.

use crate::clusters::clustering::clusters_on_grid;
use crate::cut::tool::{Path, Pose};
use crate::ecs::components::*;
use crate::ecs::desc::{ColliderDesc, ToolDesc};
use crate::ecs::groups::cluster_compliance;
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::*;
pub use crate::ecs::spawn_body::spawn_body;
use crate::ecs::spawn_body::spawn_clusters;
use crate::ecs::spawn_body::spawn_into;
use crate::error::{CleaveError, Result, SIZE, check_vec_within};
use crate::math::rotation::unit_quaternion;
use bevy_ecs::prelude::*;

/// Spawns a cutting tool into any world prepared with [`crate::systems::install`].
/// Despawn it, or disable it (bevy's `Disabled` component), to stop it cutting; a
/// disabled tool's motion is still followed, so enabling it again cuts only from where
/// it is then.
pub fn spawn_tool(world: &mut World, desc: &ToolDesc) -> Result<Entity> {
    spawn_tool_into(world, None, desc)
}

/// [`spawn_tool`], making the entity `into` (if given, else a new one) the tool.
pub(crate) fn spawn_tool_into(
    world: &mut World,
    into: Option<Entity>,
    desc: &ToolDesc,
) -> Result<Entity> {
    desc.shape.validate("tool.shape")?;
    SIZE.check("tool.cut_width", desc.cut_width)?;
    let (pose, path) = starting_pose(world, "tool", &desc.path, desc.pose)?;
    let tool = Tool {
        shape: desc.shape,
        cut_width: desc.cut_width,
        mode: desc.cut_mode,
    };
    let at = ToolPose {
        current: pose,
        last: pose,
    };
    Ok(spawn_keyframed(world, into, (tool, at), path, ToolPath))
}

/// Spawns `object` (into `into`, if given), with the component `follow` makes of
/// `path` when it has keys.
fn spawn_keyframed<C: Component>(
    world: &mut World,
    into: Option<Entity>,
    object: impl Bundle,
    path: Path,
    follow: impl FnOnce(Path) -> C,
) -> Entity {
    let e = spawn_into(world, into, object);
    let mut e = world.entity_mut(e);
    if !path.keys.is_empty() {
        e.insert(follow(path));
    }
    e.id()
}

/// Checks a keyframed object's `path` and `pose` (errors name `what`) and returns its
/// pose at the world's current time (the path's, or `pose` without a path) and the path
/// with unit rotations.
fn starting_pose(world: &World, what: &str, path: &Path, pose: Pose) -> Result<(Pose, Path)> {
    path.validate(what)?;
    let pose = checked_pose(&format!("{what}.pose"), pose)?;
    let now = world.get_resource::<SimClock>().map_or(0.0, |c| c.time);
    let path = path.normalized();
    let pose = path.sample(now as f32).unwrap_or(pose);
    Ok((pose, path))
}

/// `pose` with a unit rotation, if its position is within the world's bounds and its
/// rotation a finite, non-zero quaternion; errors name `field`.
pub fn checked_pose(field: &str, pose: Pose) -> Result<Pose> {
    check_vec_within(
        &format!("{field}.position"),
        pose.position,
        &crate::error::POSITION,
    )?;
    let rotation = unit_quaternion(pose.rotation).ok_or_else(|| {
        crate::error::out_of_range(
            &format!("{field}.rotation"),
            pose.rotation,
            crate::error::ROTATION,
        )
    })?;
    Ok(Pose { rotation, ..pose })
}

/// Spawns a collider into any world prepared with [`crate::systems::install`].
pub fn spawn_collider(world: &mut World, desc: &ColliderDesc) -> Result<Entity> {
    spawn_collider_into(world, None, desc)
}

/// [`spawn_collider`], making the entity `into` (if given, else a new one) the collider.
pub(crate) fn spawn_collider_into(
    world: &mut World,
    into: Option<Entity>,
    desc: &ColliderDesc,
) -> Result<Entity> {
    desc.shape.validate("collider.shape")?;
    crate::config::ranges::FRICTION.check("collider.friction", desc.friction)?;
    let (pose, path) = starting_pose(world, "collider", &desc.path, desc.pose)?;
    let collider = Collider {
        shape: desc.shape.clone(),
        friction: desc.friction,
    };
    let at = ColliderPose {
        current: pose,
        last: pose,
    };
    Ok(spawn_keyframed(
        world,
        into,
        (collider, at),
        path,
        ColliderPath,
    ))
}

/// Replaces the clusters of `body` by a fresh clustering of its current geometry: the
/// initial clustering, with the body's seed grid, of the particles and lattice edges
/// that are live now — the clusters the body would have if it had been spawned with
/// this shape. This is the reference a cut body's rebuilt clusters are measured
/// against (`cleave fidelity`). Particles keep their positions and velocities; the
/// solver layout is rebuilt at the next step. Returns the new cluster entities.
pub fn recluster(world: &mut World, body: Entity) -> Result<Vec<Entity>> {
    let not_a_body = || CleaveError::not_a("a body", body);
    let (table, particles, material, groups, spacing) = {
        let b = world.get::<Body>(body).ok_or_else(not_a_body)?;
        let lattice = &world
            .get::<BodyLattice>(body)
            .ok_or_else(not_a_body)?
            .lattice;
        (
            clusters_on_grid(lattice, &b.material, b.seed_grid),
            lattice.len(),
            b.material.clone(),
            b.groups.clone(),
            lattice.spacing(),
        )
    };
    let compliance = |members: &[u32]| cluster_compliance(&material, &groups, members, spacing);
    let old: Vec<Entity> = world
        .query::<(Entity, &ClusterOf)>()
        .iter(world)
        .filter(|(_, of)| of.body == body)
        .map(|(e, _)| e)
        .collect();
    for e in old {
        world.despawn(e);
    }
    let (body_clusters, clusters) = spawn_clusters(world, body, &table, particles, compliance);
    world.entity_mut(body).insert(body_clusters);
    world.resource_mut::<SolverCache>().layout.invalidate();
    Ok(clusters)
}
