//! `Simulation`: a World plus the cleave schedules, for headless use; body and tool
//! descriptions; `check_invariants` over a World.

use crate::cluster_index::ClusterIndex;
use crate::cluster_store::ClusterTable;
use crate::clustering::{clusters_on_grid, seed_grid_offset};
use crate::collider::ColliderShape;
use crate::components::*;
use crate::config::{Material, SimConfig};
use crate::error::{
    CleaveError, MAX_COORDINATE, Result, check_finite_vec, check_positive, check_range,
    check_vec_within,
};
use crate::invariants::{Violation, check_body, check_index};
use crate::lattice::Shape;
use crate::resources::*;
use crate::rotation::unit_quaternion;
use crate::solver::MAX_SOLVER_PARTICLES;
use crate::systems::{CleaveSchedule, install};
use crate::tool::{CutMode, Path, Pose, ToolShape};
use bevy_ecs::message::message_update_system;
use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

/// An axis-aligned world-space region whose particles are pinned (inverse mass 0): they
/// move at the region's constant velocity whatever acts on them (zero: they stay), so
/// pins can hold a body or pull it.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PinRegion {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
    /// Velocity of the pinned particles (m/s).
    #[serde(default)]
    pub velocity: Vec3,
}

impl PinRegion {
    /// Whether the world position `x` lies in the region (bounds included).
    pub fn contains(&self, x: Vec3) -> bool {
        x.cmpge(self.min).all() && x.cmple(self.max).all()
    }
}

/// Everything needed to spawn a body.
#[derive(Clone, Debug)]
pub struct BodyDesc {
    /// Shape to voxelise (local frame).
    pub shape: Shape,
    /// Lattice spacing h (> 0).
    pub spacing: f32,
    /// World position of the shape's local origin.
    pub position: Vec3,
    /// Initial rotation (rest shape stays unrotated: a rotated body returns to a
    /// rotated copy of it).
    pub rotation: Quat,
    /// Initial velocity.
    pub velocity: Vec3,
    /// Material and clustering parameters.
    pub material: Material,
    /// Regions of pinned particles (world space, after placement).
    pub pins: Vec<PinRegion>,
}

impl BodyDesc {
    /// A body of the given shape and spacing with default material at the origin.
    pub fn new(shape: Shape, spacing: f32) -> Self {
        Self {
            shape,
            spacing,
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            material: Material::default(),
            pins: Vec::new(),
        }
    }
}

/// Everything needed to spawn a cutting tool.
#[derive(Clone, Debug)]
pub struct ToolDesc {
    /// Shape.
    pub shape: ToolShape,
    /// Width of the cut zone (> 0).
    pub cut_width: f32,
    /// What the tool does where it passes.
    pub cut_mode: CutMode,
    /// Keyframed path; if empty the tool stays at `pose` until game code moves it.
    pub path: Path,
    /// Initial pose.
    pub pose: Pose,
}

/// Everything needed to spawn a collider.
#[derive(Clone, Debug)]
pub struct ColliderDesc {
    /// Shape in the local frame.
    pub shape: ColliderShape,
    /// Coulomb friction coefficient (≥ 0).
    pub friction: f32,
    /// Pose (before the path starts, or for good without a path).
    pub pose: Pose,
    /// Keyframed path; empty: static, or moved by game code through
    /// [`ColliderPose::current`].
    pub path: Path,
}

/// A headless simulation: a [`World`] with the cleave resources and schedules.
pub struct Simulation {
    world: World,
}

impl Simulation {
    /// Validates `config` and builds an empty simulation.
    pub fn new(config: SimConfig) -> Result<Self> {
        config.validate()?;
        let mut world = World::new();
        install(&mut world, config);
        Ok(Self { world })
    }

    /// A simulation of `scene`: its settings, then its bodies, tools and colliders
    /// spawned in order (the first error stops it).
    pub fn from_scene(scene: &crate::scene::Scene) -> Result<Self> {
        let mut sim = Self::new(scene.config.clone())?;
        for b in &scene.bodies {
            sim.spawn_body(b)?;
        }
        for t in &scene.tools {
            sim.spawn_tool(t)?;
        }
        for c in &scene.colliders {
            sim.spawn_collider(c)?;
        }
        Ok(sim)
    }

    /// The world (read).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world (write), e.g. to move tools or pin particles from game code.
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The settings in force.
    pub fn config(&self) -> &SimConfig {
        &self.world.resource::<SimSettings>().0
    }

    /// Voxelises, clusters and spawns a body; returns the body entity.
    pub fn spawn_body(&mut self, desc: &BodyDesc) -> Result<Entity> {
        spawn_body(&mut self.world, desc)
    }

    /// Spawns a cutting tool; returns its entity.
    pub fn spawn_tool(&mut self, desc: &ToolDesc) -> Result<Entity> {
        spawn_tool(&mut self.world, desc)
    }

    /// Spawns a collider; returns its entity.
    pub fn spawn_collider(&mut self, desc: &ColliderDesc) -> Result<Entity> {
        spawn_collider(&mut self.world, desc)
    }

    /// Advances one frame.
    pub fn step(&mut self) {
        self.world.run_system_cached(message_update_system).ok();
        self.world.run_schedule(CleaveSchedule);
    }

    /// Advances `frames` frames.
    pub fn run(&mut self, frames: u32) {
        for _ in 0..frames {
            self.step();
        }
    }

    /// Writes the whole simulation to `writer` in cleave's binary format (see
    /// [`crate::save`]); [`Simulation::load`] resumes it exactly.
    pub fn save(&mut self, writer: impl std::io::Write) -> Result<()> {
        crate::save::save(&mut self.world, writer)
    }

    /// Reads a simulation written by [`Simulation::save`]: it goes on bit for bit as the
    /// saved one would have.
    pub fn load(reader: impl std::io::Read) -> Result<Self> {
        crate::save::load(reader)
    }

    /// Replaces the clusters of `body` by a fresh clustering of its current geometry
    /// (see [`recluster`]); returns the new cluster entities.
    pub fn recluster(&mut self, body: Entity) -> Result<Vec<Entity>> {
        recluster(&mut self.world, body)
    }

    /// Every body entity, in entity order.
    pub fn bodies(&mut self) -> Vec<Entity> {
        let mut bodies: Vec<Entity> = self
            .world
            .query_filtered::<Entity, With<BodyLattice>>()
            .iter(&self.world)
            .collect();
        bodies.sort_unstable();
        bodies
    }

    /// The live particles of `body`, by body-local index, each with a value read from
    /// its entity.
    fn read_particles<T>(
        &self,
        body: Entity,
        read: impl Fn(EntityRef) -> Option<T>,
    ) -> Result<Vec<(u32, T)>> {
        let lattice = self
            .world
            .get::<BodyLattice>(body)
            .ok_or_else(|| CleaveError::InvalidEntity(format!("{body} is not a body")))?;
        lattice
            .lattice
            .live_particles()
            .map(|i| {
                let e = lattice.particles[i as usize];
                let value = self
                    .world
                    .get_entity(e)
                    .ok()
                    .and_then(&read)
                    .ok_or_else(|| {
                        CleaveError::InvalidEntity(format!(
                            "particle {i} of body {body} has lost its entity or components"
                        ))
                    })?;
                Ok((i, value))
            })
            .collect()
    }

    /// Positions of the live particles of `body`, with their body-local indices, in
    /// index order.
    pub fn positions(&self, body: Entity) -> Result<Vec<(u32, Vec3)>> {
        self.read_particles(body, |e| e.get::<Position>().map(|p| p.0))
    }

    /// Velocities of the live particles of `body`, with their body-local indices, in
    /// index order.
    pub fn velocities(&self, body: Entity) -> Result<Vec<(u32, Vec3)>> {
        self.read_particles(body, |e| e.get::<Velocity>().map(|v| v.0))
    }

    /// The pieces of `body` (connected components of its live particles), each as its
    /// sorted body-local particle indices, ordered by their smallest index.
    pub fn pieces(&self, body: Entity) -> Result<Vec<Vec<u32>>> {
        let lattice = &self
            .world
            .get::<BodyLattice>(body)
            .ok_or_else(|| CleaveError::InvalidEntity(format!("{body} is not a body")))?
            .lattice;
        let (labels, count) = crate::graph::body_pieces(lattice);
        let mut pieces = vec![Vec::new(); count];
        for i in lattice.live_particles() {
            pieces[labels[i as usize] as usize].push(i);
        }
        Ok(pieces)
    }

    /// The clusters of `body` as `(cluster entity, sorted body-local members)`, by
    /// entity.
    pub fn clusters(&mut self, body: Entity) -> Result<Vec<(Entity, Vec<u32>)>> {
        if self.world.get::<BodyLattice>(body).is_none() {
            return Err(CleaveError::InvalidEntity(format!("{body} is not a body")));
        }
        let mut clusters: Vec<(Entity, Vec<u32>)> = self
            .world
            .query::<(Entity, &ClusterMembers, &ClusterOf)>()
            .iter(&self.world)
            .filter(|(_, _, of)| of.body == body)
            .map(|(e, m, _)| (e, m.0.clone()))
            .collect();
        clusters.sort_unstable_by_key(|(e, _)| *e);
        Ok(clusters)
    }
}

/// Spawns a cutting tool into any world prepared with [`crate::systems::install`].
pub fn spawn_tool(world: &mut World, desc: &ToolDesc) -> Result<Entity> {
    desc.shape.validate()?;
    check_positive("tool.cut_width", desc.cut_width)?;
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
    Ok(spawn_keyframed(world, (tool, at), path, ToolPath))
}

/// Spawns `object`, with the component `follow` makes of `path` when it has keys.
fn spawn_keyframed<C: Component>(
    world: &mut World,
    object: impl Bundle,
    path: Path,
    follow: impl FnOnce(Path) -> C,
) -> Entity {
    let mut e = world.spawn(object);
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
    check_vec_within(
        &format!("{what}.pose.position"),
        pose.position,
        MAX_COORDINATE,
        "|x|, |y|, |z| ≤ 1e6 (metres)",
    )?;
    let rotation = unit_quaternion(pose.rotation).ok_or_else(|| {
        crate::error::out_of_range(
            &format!("{what}.pose.rotation"),
            pose.rotation,
            "finite, non-zero quaternion",
        )
    })?;
    let now = world.get_resource::<SimClock>().map_or(0.0, |c| c.time);
    let path = path.normalized();
    let pose = path.sample(now as f32).unwrap_or(Pose { rotation, ..pose });
    Ok((pose, path))
}

/// Spawns a collider into any world prepared with [`crate::systems::install`].
pub fn spawn_collider(world: &mut World, desc: &ColliderDesc) -> Result<Entity> {
    desc.shape.validate("collider.shape")?;
    check_range(
        "collider.friction",
        desc.friction,
        0.0,
        100.0,
        "0 ≤ friction ≤ 100",
    )?;
    let (pose, path) = starting_pose(world, "collider", &desc.path, desc.pose)?;
    let collider = Collider {
        shape: desc.shape.clone(),
        friction: desc.friction,
    };
    let at = ColliderPose {
        current: pose,
        last: pose,
    };
    Ok(spawn_keyframed(world, (collider, at), path, ColliderPath))
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

/// Spawns a body into any world prepared with [`crate::systems::install`].
pub fn spawn_body(world: &mut World, desc: &BodyDesc) -> Result<Entity> {
    desc.material.validate()?;
    check_range(
        "spacing",
        desc.spacing,
        1e-4,
        100.0,
        "1e-4 ≤ spacing ≤ 100 (metres)",
    )?;
    check_vec_within(
        "body.position",
        desc.position,
        MAX_COORDINATE,
        "|x|, |y|, |z| ≤ 1e6 (metres)",
    )?;
    check_vec_within(
        "body.velocity",
        desc.velocity,
        1e4,
        "|vx|, |vy|, |vz| ≤ 1e4 (m/s)",
    )?;
    let rotation = unit_quaternion(desc.rotation).ok_or_else(|| {
        crate::error::out_of_range(
            "body.rotation",
            desc.rotation,
            "finite, non-zero quaternion",
        )
    })?;
    for (i, pin) in desc.pins.iter().enumerate() {
        check_finite_vec(&format!("body.pins[{i}].min"), pin.min)?;
        check_finite_vec(&format!("body.pins[{i}].max"), pin.max)?;
        check_vec_within(
            &format!("body.pins[{i}].velocity"),
            pin.velocity,
            1e4,
            "|vx|, |vy|, |vz| ≤ 1e4 (m/s)",
        )?;
    }
    check_range(
        "material.particle_mass",
        desc.material.mass_at_spacing(desc.spacing),
        1e-9,
        1e9,
        "1e-9 ≤ density·spacing³ ≤ 1e9 (kg per particle)",
    )?;
    let budget = world
        .get_resource::<SimSettings>()
        .map_or(crate::lattice::DEFAULT_MEMORY_BUDGET_GB, |s| {
            s.0.memory_budget_gb
        });
    let lattice = desc.shape.voxelise_within(desc.spacing, budget)?;
    check_particle_budget(existing_particles(world), lattice.len() as u64)?;
    let seed_grid = seed_grid_offset(&desc.material, &mut world.resource_mut::<SimRng>().0);
    let table = clusters_on_grid(&lattice, &desc.material, seed_grid);
    let body = world
        .spawn(Body {
            material: desc.material.clone(),
            seed_grid,
        })
        .id();
    // In the solver layout's (Morton) order, so that the particle table's rows and the
    // layout's slots run in step and the shape-match stage copies them in sequence; in one
    // batch, so that the table is sized once instead of grown by doubling.
    let order = lattice.live_in_morton_order();
    let inv_mass = 1.0 / desc.material.mass_at_spacing(desc.spacing);
    let spawned = world.spawn_batch(order.iter().map(|&i| {
        let x = desc.position + rotation * lattice.rest_position(i);
        let pin = desc.pins.iter().find(|r| r.contains(x));
        (
            Particle { body, index: i },
            Position(x),
            PrevPosition(x),
            Velocity(pin.map_or(desc.velocity, |r| r.velocity)),
            InvMass(if pin.is_some() { 0.0 } else { inv_mass }),
        )
    }));
    let mut particles = vec![Entity::PLACEHOLDER; lattice.len()];
    for (&i, e) in order.iter().zip(spawned) {
        particles[i as usize] = e;
    }
    let compliance = desc.material.cluster_compliance(desc.spacing);
    let (clusters, _) = spawn_clusters(world, body, &table, lattice.len(), compliance);
    let pieces = lattice.piece_count();
    world.entity_mut(body).insert((
        BodyLattice {
            lattice,
            particles,
            pieces,
        },
        clusters,
    ));
    Ok(body)
}

/// Spawns the clusters of `table` as entities of `body`, with keys in table order;
/// returns the body's cluster data and the entities, in order.
fn spawn_clusters(
    world: &mut World,
    body: Entity,
    table: &ClusterTable,
    particles: usize,
    compliance: f32,
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
                Compliance(compliance),
            ))
            .id();
        let named = clusters.keys.insert(e);
        debug_assert_eq!(named, key);
        clusters.index.add_cluster(key, members);
        entities.push(e);
    }
    (clusters, entities)
}

/// Replaces the clusters of `body` by a fresh clustering of its current geometry: the
/// initial clustering, with the body's seed grid, of the particles and lattice edges
/// that are live now — the clusters the body would have if it had been spawned with
/// this shape. This is the reference a cut body's rebuilt clusters are measured
/// against (`cleave fidelity`). Particles keep their positions and velocities; the
/// solver layout is rebuilt at the next step. Returns the new cluster entities.
pub fn recluster(world: &mut World, body: Entity) -> Result<Vec<Entity>> {
    let not_a_body = || CleaveError::InvalidEntity(format!("{body} is not a body"));
    let (table, particles, compliance) = {
        let b = world.get::<Body>(body).ok_or_else(not_a_body)?;
        let lattice = &world
            .get::<BodyLattice>(body)
            .ok_or_else(not_a_body)?
            .lattice;
        (
            clusters_on_grid(lattice, &b.material, b.seed_grid),
            lattice.len(),
            b.material.cluster_compliance(lattice.spacing()),
        )
    };
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
    world.resource_mut::<SolverCache>().valid = false;
    Ok(clusters)
}

/// Checks the invariants ([`crate::invariants`]) of every body in `world`, that each body's particle →
/// clusters index matches its clusters' members, and that every live particle has a
/// finite position; returns `(body, violation)`.
pub fn check_invariants(world: &World) -> Vec<(Entity, Violation)> {
    let Some(mut bodies) =
        world.try_query::<(Entity, &Body, &BodyLattice, Option<&ParticleClusters>)>()
    else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (e, body, lattice, clusters) in bodies.iter(world) {
        // each body's clusters by key, as its key table names them
        let mut listed: Vec<(u32, &[u32])> = Vec::new();
        if let Some(clusters) = clusters {
            for (k, entity) in clusters.keys.iter() {
                let of_body = world
                    .get::<ClusterOf>(entity)
                    .is_some_and(|of| of.body == e);
                match world.get::<ClusterMembers>(entity) {
                    Some(m) if of_body => listed.push((k, m.0.as_slice())),
                    _ => out.push((e, Violation::MissingCluster { cluster: k as u64 })),
                }
            }
            let violations = check_index(listed.iter().copied(), clusters.index.iter());
            out.extend(violations.into_iter().map(|v| (e, v)));
        }
        for v in check_body(
            &lattice.lattice,
            listed.iter().map(|(k, m)| (*k as u64, *m)),
            body.material.max_cluster_size as usize,
        ) {
            out.push((e, v));
        }
        for i in lattice.lattice.live_particles() {
            let position = world.get::<Position>(lattice.particles[i as usize]);
            if !position.is_some_and(|p| p.0.is_finite()) {
                out.push((e, Violation::NonFinite { particle: i }));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_simulation_reads_out_positions_velocities_pieces_and_clusters() -> Result<()> {
        let mut sim = Simulation::new(SimConfig::default())?;
        let shape = crate::lattice::Shape::cuboid(glam::UVec3::new(6, 3, 3), 0.1);
        let mut desc = BodyDesc::new(shape, 0.1);
        desc.position = Vec3::new(0.0, 1.0, 0.0);
        let body = sim.spawn_body(&desc)?;
        let start = sim.positions(body)?;
        sim.run(5);
        assert_eq!(sim.bodies(), vec![body]);
        let (positions, velocities) = (sim.positions(body)?, sim.velocities(body)?);
        assert_eq!(positions.len(), 54);
        // falling: every particle below its start and moving down, as the ECS says
        for (((i, p), (j, v)), (k, p0)) in positions.iter().zip(&velocities).zip(&start) {
            assert_eq!((i, j), (k, k));
            assert!(p.y < p0.y && v.y < 0.0, "{p0} → {p}, {v}");
            let entity = sim
                .world()
                .get::<BodyLattice>(body)
                .expect("a body")
                .particles[*i as usize];
            assert_eq!(sim.world().get::<Position>(entity).map(|x| x.0), Some(*p));
        }
        let pieces = sim.pieces(body)?;
        assert_eq!(pieces.len(), 1);
        assert_eq!(pieces[0].len(), 54);
        let clusters = sim.clusters(body)?;
        assert!(!clusters.is_empty());
        let covered: std::collections::BTreeSet<u32> = clusters
            .iter()
            .flat_map(|(_, m)| m.iter().copied())
            .collect();
        assert_eq!(covered.len(), 54, "every particle in a cluster");
        // a NaN written into one position is reported
        assert!(check_invariants(sim.world()).is_empty());
        let entity = sim
            .world()
            .get::<BodyLattice>(body)
            .expect("a body")
            .particles[7];
        sim.world_mut()
            .entity_mut(entity)
            .insert(Position(Vec3::NAN));
        assert_eq!(
            check_invariants(sim.world()),
            vec![(body, Violation::NonFinite { particle: 7 })]
        );
        // not a body: a clear error
        let tool = sim.world_mut().spawn_empty().id();
        assert!(
            sim.positions(tool)
                .unwrap_err()
                .to_string()
                .contains("is not a body")
        );
        assert!(sim.clusters(tool).is_err());
        Ok(())
    }

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

    #[test]
    fn the_particle_index_resolves_to_the_clusters_that_hold_each_particle() -> Result<()> {
        let mut sim = Simulation::new(SimConfig::default())?;
        // freed indices, so that the body's entities reuse them with a later generation
        let scratch: Vec<Entity> = (0..200)
            .map(|_| sim.world_mut().spawn_empty().id())
            .collect();
        for e in scratch {
            sim.world_mut().despawn(e);
        }
        let shape = crate::lattice::Shape::cuboid(glam::UVec3::new(5, 4, 3), 0.1);
        let body = sim.spawn_body(&BodyDesc::new(shape, 0.1))?;
        let world = sim.world_mut();
        let mut clusters = world.query::<(Entity, &ClusterMembers, &ClusterOf)>();
        let mut holding: Vec<Vec<Entity>> = vec![Vec::new(); 5 * 4 * 3];
        for (e, members, of) in clusters.iter(world) {
            assert_eq!(of.body, body);
            for &p in &members.0 {
                holding[p as usize].push(e);
            }
        }
        let index = world.get::<ParticleClusters>(body).expect("a body's index");
        for (p, expected) in holding.iter_mut().enumerate() {
            let mut found: Vec<Entity> = index.clusters_of(p as u32).collect();
            found.sort_unstable();
            expected.sort_unstable();
            assert!(!found.is_empty(), "particle {p} is in no cluster");
            assert_eq!(&found, expected, "particle {p}");
        }
        assert_eq!(index.clusters_of(1000).count(), 0);
        Ok(())
    }
}
