//! `Simulation`: a World plus the cleave schedules, for headless use.

use crate::config::SimConfig;
use crate::cut::tool::Pose;
use crate::ecs::components::*;
use crate::ecs::desc::{BodyDesc, ColliderDesc, ToolDesc};
use crate::ecs::ecs_term::{EcsSubstepTerm, EcsTerm};
use crate::ecs::resources::{SceneLabel, SimSettings};
use crate::ecs::spawn::{recluster, spawn_body, spawn_collider, spawn_tool};
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::{CleaveError, Result};
use crate::solver::term::Term;
use crate::systems::{install, run_frame};
use bevy_ecs::message::{Message, Messages, message_update_system};
use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

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
    /// spawned in order (the first error stops it), then, if its settings ask for it
    /// ([`SimConfig::relax`]), every body relaxed in turn
    /// ([`Simulation::relax`]; the reports in [`Simulation::relax_reports`]).
    pub fn from_scene(scene: &crate::ecs::desc::Scene) -> Result<Self> {
        let mut sim = Self::new(scene.config.clone())?;
        let mut bodies = Vec::with_capacity(scene.bodies.len());
        for b in &scene.bodies {
            bodies.push(sim.spawn_body(b)?);
        }
        for t in &scene.tools {
            sim.spawn_tool(t)?;
        }
        for c in &scene.colliders {
            sim.spawn_collider(c)?;
        }
        if let Some(options) = &scene.config.relax {
            let mut reports = Vec::with_capacity(bodies.len());
            for body in bodies {
                reports.push((body, sim.relax(body, options)?));
            }
            sim.world
                .insert_resource(crate::sim::relax_report::RelaxReports(reports));
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

    /// Labels what this simulation is a run of (a scene's name, say); saves keep it.
    pub fn set_label(&mut self, label: impl Into<String>) {
        self.world.insert_resource(SceneLabel(Some(label.into())));
    }

    /// The label [`Simulation::set_label`] gave, here or in the simulation this one was
    /// loaded from.
    pub fn label(&self) -> Option<&str> {
        self.world.get_resource::<SceneLabel>()?.0.as_deref()
    }

    /// Voxelises, clusters and spawns a body; returns the body entity.
    pub fn spawn_body(&mut self, desc: &BodyDesc) -> Result<Entity> {
        spawn_body(&mut self.world, desc)
    }

    /// Poses `body` by `handles` from now on: its particles become kinematic and follow
    /// the handles each frame by `method` (see [`crate::ecs::handles`]); game code may
    /// move handles without a path through [`HandlePose::targets`].
    ///
    /// [`HandlePose::targets`]: crate::ecs::handles::HandlePose::targets
    pub fn pose_by_handles(
        &mut self,
        body: Entity,
        handles: &[crate::ecs::desc::HandleDesc],
        method: crate::ecs::handles::PoseMethod,
    ) -> Result<()> {
        crate::ecs::handles::pose_by_handles(&mut self.world, body, handles, method)
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
        run_frame(&mut self.world);
    }

    /// Advances `frames` frames.
    pub fn run(&mut self, frames: u32) {
        for _ in 0..frames {
            self.step();
        }
    }

    /// Writes the whole simulation to `writer` in cleave's binary format (see
    /// [`crate::io::save`]); [`Simulation::load`] resumes it exactly.
    pub fn save(&mut self, writer: impl std::io::Write) -> Result<()> {
        crate::io::save::save(&mut self.world, writer)
    }

    /// Reads a simulation written by [`Simulation::save`]: it goes on bit for bit as the
    /// saved one would have. Its entities are new: [`Simulation::loaded_entity`] maps the
    /// saved ones, and an entity kept from before is refused by every call.
    pub fn load(reader: impl std::io::Read) -> Result<Self> {
        crate::io::save::load(reader).map(|world| Self { world })
    }

    /// [`Simulation::load`], with `setup` run on the loaded world before the solver's
    /// state is put back (see [`crate::io::save::load_with`]): register your own terms
    /// there ([`crate::systems::add_ecs_term`], or the solver's registry) so
    /// that they take up the state they saved.
    pub fn load_with(
        reader: impl std::io::Read,
        setup: impl FnOnce(&mut World) -> Result<()>,
    ) -> Result<Self> {
        crate::io::save::load_with(reader, setup).map(|world| Self { world })
    }

    /// The entity that `saved` — a body, tool, collider or attachment of the simulation
    /// this one was loaded from — has here. Entities kept from before a save name nothing
    /// in the loaded simulation (every call given one is refused): map them with this.
    /// An error if this simulation was not loaded or `saved` was none of those.
    pub fn loaded_entity(&self, saved: Entity) -> Result<Entity> {
        self.world
            .get_resource::<crate::io::save::LoadedEntities>()
            .ok_or_else(|| CleaveError::InvalidEntity("this simulation was not loaded".into()))?
            .get(saved)
    }

    /// Replaces the clusters of `body` by a fresh clustering of its current geometry
    /// (see [`recluster`]); returns the new cluster entities.
    pub fn recluster(&mut self, body: Entity) -> Result<Vec<Entity>> {
        recluster(&mut self.world, body)
    }

    /// Attaches `body`'s live particles `particles` (body-local) where they are now, each
    /// by a spring of `compliance` (m/N; 0: hard, a pin), to a target at their centroid;
    /// returns the attachment. Move it with [`Simulation::move_attachment`]; despawn it to
    /// let go.
    pub fn attach(&mut self, body: Entity, particles: &[u32], compliance: f32) -> Result<Entity> {
        crate::ecs::attach::attach(&mut self.world, body, particles, compliance, Hold::Each)
    }

    /// Holds the centroid of `body`'s live particles `particles` (body-local) where it is
    /// now, by a spring of `compliance` (m/N; 0: hard), while the particles themselves
    /// move freely about it (see [`crate::solver::terms::centroids`]); returns the hold,
    /// an attachment: [`Simulation::move_attachment`] moves its target (a translation
    /// moves the centroid's target by as much), [`Simulation::detach`] lets go.
    pub fn hold_centroid(
        &mut self,
        body: Entity,
        particles: &[u32],
        compliance: f32,
    ) -> Result<Entity> {
        crate::ecs::attach::attach(&mut self.world, body, particles, compliance, Hold::Centroid)
    }

    /// Sets where attachment `attachment` pulls at the end of the next frame (its target
    /// moves there over the frame). An error if it is not an attachment, the pose is not
    /// finite or beyond ±1e6 m, or a path or a velocity moves it.
    pub fn move_attachment(&mut self, attachment: Entity, pose: Pose) -> Result<()> {
        crate::ecs::poses::set_attachment_pose(&mut self.world, attachment, pose)
    }

    /// Lets go of attachment `attachment`: its particles move freely from the next frame.
    pub fn detach(&mut self, attachment: Entity) -> Result<()> {
        let holds = self
            .world
            .get_entity(attachment)
            .is_ok_and(|e| e.contains::<Attachment>());
        if !holds {
            return Err(CleaveError::not_a("an attachment", attachment));
        }
        self.world.despawn(attachment);
        Ok(())
    }

    /// Sets where tool `tool` is at the end of the next frame: the frame cuts along all
    /// it sweeps from where the last frame left it, at any speed, as a keyframed path
    /// does. An error if it is not a tool, follows a path, or the pose is not finite or
    /// beyond ±1e6 m.
    pub fn set_tool_pose(&mut self, tool: Entity, pose: Pose) -> Result<()> {
        crate::ecs::poses::set_tool_pose(&mut self.world, tool, pose)
    }

    /// Sets where collider `collider` is at the end of the next frame: the substeps move
    /// it there from where the last frame left it, so it does not pass through bodies.
    /// Errors as [`Simulation::set_tool_pose`]'s.
    pub fn set_collider_pose(&mut self, collider: Entity, pose: Pose) -> Result<()> {
        crate::ecs::poses::set_collider_pose(&mut self.world, collider, pose)
    }

    /// The messages of type `M` the last frame sent ([`BodySplit`](crate::ecs::resources::BodySplit),
    /// [`ParticlesCut`](crate::ecs::resources::ParticlesCut), …), oldest first; each
    /// frame's are readable until the next [`Simulation::step`].
    pub fn messages<M: Message + Clone>(&self) -> Vec<M> {
        self.world
            .get_resource::<Messages<M>>()
            .map(|m| m.iter_current_update_messages().cloned().collect())
            .unwrap_or_default()
    }

    /// Adds a term of your own that takes data from the ECS (see
    /// [`crate::ecs::ecs_term`]): the term, after the built-in ones, and its sync, run
    /// at the start of every frame. Not saved: add it again when loading, in
    /// [`Simulation::load_with`], so that it takes up its saved state.
    pub fn add_ecs_term<T: EcsTerm>(&mut self, term: T) {
        crate::systems::add_ecs_term(&mut self.world, term);
    }

    /// [`Simulation::add_ecs_term`] for a kind that takes its ECS data every substep
    /// ([`crate::ecs::ecs_term::EcsSubstepTerm`]).
    pub fn add_ecs_substep_term<T: EcsSubstepTerm>(&mut self, term: T) {
        crate::systems::add_ecs_substep_term(&mut self.world, term);
    }

    /// Adds a term of your own to the solver, after the built-in ones: it is solved with
    /// them under every scheme (see [`crate::solver::term`]). Not saved: add it again
    /// after [`Simulation::load`] (in [`Simulation::load_with`] if it keeps a saved
    /// state).
    pub fn add_term(&mut self, term: impl Term) {
        crate::systems::add_term(&mut self.world, term);
    }

    /// Stops keeping the drawable surfaces of the bodies spawned so far (their
    /// [`SurfaceMesh`] components are removed, and the surface stage skips them):
    /// headless runs and benchmarks that draw nothing save its work. Bodies spawned
    /// later get one again.
    pub fn drop_surfaces(&mut self) {
        for body in self.bodies() {
            self.world.entity_mut(body).remove::<SurfaceMesh>();
        }
    }

    /// Brings every body's surface up to date now, as the surface stage does at the end
    /// of each frame: for pictures or exports of the state before the first frame, or of
    /// the last one (a rebuild spread over frames, see
    /// [`crate::ecs::resources::SurfaceBudget`], is waited for and put in place).
    pub fn update_surfaces(&mut self) -> Result<()> {
        use bevy_ecs::system::RunSystemOnce;
        let frame = self
            .world
            .resource::<crate::ecs::resources::SimClock>()
            .frame;
        let mut meshes = self.world.query::<&mut SurfaceMesh>();
        for mut mesh in meshes.iter_mut(&mut self.world) {
            mesh.bypass_change_detection().hurry(frame);
        }
        self.world
            .run_system_once(crate::systems::surface::update_surfaces)
            .map_err(|e| CleaveError::InvalidEntity(format!("surface stage: {e}")))
    }

    /// The drawable surface of `body` (brought up to date at the end of each frame); an
    /// error if `body` is not a body or its surface was dropped.
    pub fn surface(&self, body: Entity) -> Result<&SurfaceMesh> {
        self.world
            .get::<SurfaceMesh>(body)
            .ok_or_else(|| CleaveError::not_a("a body with a surface (see `drop_surfaces`)", body))
    }

    /// What the particles did to `collider` over the last frame: the mean force (N) and
    /// torque about its centre (N·m) of their contact impulses, as its
    /// [`ColliderWrench`] holds them; an error if
    /// `collider` is not a collider.
    pub fn collider_wrench(&self, collider: Entity) -> Result<(Vec3, Vec3)> {
        let w = (self
            .world
            .get::<crate::ecs::components::ColliderWrench>(collider))
        .ok_or_else(|| CleaveError::not_a("a collider", collider))?;
        Ok((w.force, w.torque))
    }

    /// Makes `collider` a rigid body cleave moves ([`DynamicCollider`]),
    /// starting where it is now; an error naming the field for a state out of bounds, or
    /// if `collider` is not a collider.
    pub fn make_dynamic(
        &mut self,
        collider: Entity,
        dynamic: crate::ecs::components::DynamicCollider,
    ) -> Result<()> {
        dynamic.check()?;
        if self
            .world
            .get::<crate::ecs::components::Collider>(collider)
            .is_none()
        {
            return Err(CleaveError::not_a("a collider", collider));
        }
        self.world.entity_mut(collider).insert(dynamic);
        Ok(())
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
            .ok_or_else(|| CleaveError::not_a("a body", body))?;
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

    /// Orientations of the live particles of `body` (see [`Orientation`]), with their
    /// body-local indices, in index order.
    pub fn orientations(&self, body: Entity) -> Result<Vec<(u32, Quat)>> {
        self.read_particles(body, |e| e.get::<Orientation>().map(|q| q.0))
    }

    /// The pieces of `body` (connected components of its live particles), each as its
    /// sorted body-local particle indices, ordered by their smallest index.
    pub fn pieces(&self, body: Entity) -> Result<Vec<Vec<u32>>> {
        let lattice = &self
            .world
            .get::<BodyLattice>(body)
            .ok_or_else(|| CleaveError::not_a("a body", body))?
            .lattice;
        let (labels, count) = (&lattice.pieces().label, lattice.pieces().count);
        let mut pieces = vec![Vec::new(); count];
        for i in lattice.live_particles() {
            pieces[labels[i as usize] as usize].push(i);
        }
        Ok(pieces)
    }

    /// The centre of mass of `body`'s live particles (a kinematic particle, of inverse
    /// mass 0, weighs nothing unless every particle is kinematic: then the mean).
    pub fn centroid(&self, body: Entity) -> Result<Vec3> {
        let all = self.pieces(body)?.concat();
        Ok(self.centroids_of(body, &[all])?[0])
    }

    /// The centre of mass of each piece of `body`, in the order of
    /// [`Simulation::pieces`] (weighted as in [`Simulation::centroid`]).
    pub fn piece_centroids(&self, body: Entity) -> Result<Vec<Vec3>> {
        let pieces = self.pieces(body)?;
        self.centroids_of(body, &pieces)
    }

    /// The centre of mass of each set of `body`'s live particles in `sets`.
    fn centroids_of(&self, body: Entity, sets: &[Vec<u32>]) -> Result<Vec<Vec3>> {
        let state = self.read_particles(body, |e| {
            Some((e.get::<Position>()?.0, e.get::<InvMass>()?.0))
        })?;
        let mut of_particle =
            vec![(Vec3::ZERO, 0.0f32); state.last().map_or(0, |(i, _)| *i as usize + 1)];
        for (i, x) in state {
            of_particle[i as usize] = x;
        }
        Ok(sets
            .iter()
            .map(|set| {
                let (mut sum, mut mass, mut plain) = (glam::DVec3::ZERO, 0.0f64, glam::DVec3::ZERO);
                for &i in set {
                    let (x, w) = of_particle[i as usize];
                    let m = if w > 0.0 { 1.0 / w as f64 } else { 0.0 };
                    sum += x.as_dvec3() * m;
                    mass += m;
                    plain += x.as_dvec3();
                }
                let centre = if mass > 0.0 {
                    sum / mass
                } else {
                    plain / set.len().max(1) as f64
                };
                centre.as_vec3()
            })
            .collect())
    }

    /// The clusters of `body` as `(cluster entity, sorted body-local members)`, by
    /// entity.
    pub fn clusters(&mut self, body: Entity) -> Result<Vec<(Entity, Vec<u32>)>> {
        if self.world.get::<BodyLattice>(body).is_none() {
            return Err(CleaveError::not_a("a body", body));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clusters::invariants::Violation;
    use crate::ecs::check::check_invariants;

    #[test]
    fn a_simulation_reads_out_positions_velocities_pieces_and_clusters() -> Result<()> {
        let mut sim = Simulation::new(SimConfig::default())?;
        let shape = crate::body::shape::Shape::cuboid(glam::UVec3::new(6, 3, 3));
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
    fn the_particle_index_resolves_to_the_clusters_that_hold_each_particle() -> Result<()> {
        let mut sim = Simulation::new(SimConfig::default())?;
        // freed indices, so that the body's entities reuse them with a later generation
        let scratch: Vec<Entity> = (0..200)
            .map(|_| sim.world_mut().spawn_empty().id())
            .collect();
        for e in scratch {
            sim.world_mut().despawn(e);
        }
        let shape = crate::body::shape::Shape::cuboid(glam::UVec3::new(5, 4, 3));
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
