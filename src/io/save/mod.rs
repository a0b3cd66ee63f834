//! Saving a simulation and resuming it: everything that decides how a simulation goes
//! on — settings, clock, random stream, bodies with their lattices and clusters,
//! particles, attachments, tools, colliders, the solver's own state (its cluster
//! layout, in the order a run's cuts left it, and its warm starts) and the bodies'
//! drawable surfaces (their triangles, render meshes and carriers' frames) and the
//! handles of posed bodies (with their pose method) — in a
//! compact binary file. A run that is
//! saved, loaded and continued is bit for bit the run that was never interrupted.
//!
//! The file ([`crate::io::save_file`]) is a header and one checksummed section per
//! part of the state below. Entities are written
//! with their ids in the saving world and given new ones when loaded; everything that
//! names them (a particle's body, a cluster's body, a body's particles and cluster keys,
//! the solver's tables) is mapped. Cleave names clusters by keys of its own
//! ([`crate::ecs::components::ClusterKeys`]), so nothing it decides depends on the ids the
//! loading world hands out. What the file claims is checked before it is used: lengths
//! against each other, indices against their tables, values finite, and the invariants
//! of the loaded world; a save is loaded whole or refused.
//!
//! Saved: what cleave spawned (bodies, particles, clusters, attachments, tools,
//! colliders) and its resources; the terms besides the clusters are taken again from
//! them, as after any change of the layout. Not saved: other entities, components a game added to cleave's entities,
//! messages not yet read, and projective dynamics' factor (it is computed again from the
//! same matrix).

use crate::ecs::components::*;
use crate::ecs::handles::HandlePose;
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{CutReport, SceneLabel, SimClock, SimRng, SimSettings};
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::Result;
use crate::io::save_file::{SaveReader, SaveWriter};
use crate::systems::SyncSchedule;
use bevy_ecs::prelude::*;
use std::io::{Read, Write};

mod restore;
mod state;

pub use restore::LoadedEntities;
use state::*;

/// Writes `world`'s simulation to `writer` (see the module docs). The solver layout is
/// brought up to date first, as the next frame would.
pub fn save(world: &mut World, writer: impl Write) -> Result<()> {
    world.run_schedule(SyncSchedule);
    let s = snapshot(world)?;
    let mut file = SaveWriter::new(writer)?;
    write_sections(&mut file, &s)?;
    file.finish()
}

/// The parts of the state, each a field of [`Snapshot`] and a section of the file (its
/// name in errors), in file order: one table, so that saving and loading cannot disagree.
macro_rules! sections {
    ($($field:ident: $name:literal),* $(,)?) => {
        /// The sections of a saved simulation, in their order in the file.
        pub const SECTIONS: &[&str] = &[$($name),*];

        fn write_sections<W: Write>(file: &mut SaveWriter<W>, s: &Snapshot) -> Result<()> {
            $(file.section($name, &s.$field)?;)*
            Ok(())
        }

        // (a struct literal's fields are evaluated in the order written: file order)
        fn read_sections<R: Read>(file: &mut SaveReader<R>) -> Result<Snapshot> {
            Ok(Snapshot { $($field: file.section($name)?),* })
        }
    };
}

sections!(
    entity_bound: "entity bound",
    config: "settings",
    clock: "clock",
    rng: "random stream",
    bodies: "bodies",
    particles: "particles",
    clusters: "clusters",
    tools: "tools",
    colliders: "colliders",
    attachments: "attachments",
    cache: "solver layout",
    cut: "cut report",
    label: "scene label",
);

fn snapshot(world: &mut World) -> Result<Snapshot> {
    let bodies = saved_bodies(world);
    let particles = saved_particles(world);
    let clusters = saved_clusters(world);
    let tools = saved_tools(world);
    let colliders = saved_colliders(world);
    let attachments = saved_attachments(world);
    let cache = world.resource::<SolverCache>();
    if !cache.layout.is_valid() {
        return Err(invalid("the solver layout could not be brought up to date"));
    }
    Ok(Snapshot {
        entity_bound: world.entities().len(),
        config: world.resource::<SimSettings>().0.clone(),
        clock: *world.resource::<SimClock>(),
        rng: world.resource::<SimRng>().clone(),
        bodies,
        particles,
        clusters,
        tools,
        colliders,
        attachments,
        cache: CacheState {
            clusters_term: cache.solver.clusters.clone(),
            gauss_seidel: cache.solver.gauss_seidel.clone(),
            terms: cache.solver.terms.saved_states(),
            particles: cache.particles.clone(),
            layout: cache.layout.saved_state(),
        },
        cut: world.resource::<CutReport>().clone(),
        label: world.resource::<SceneLabel>().clone(),
    })
}

/// The bodies, in entity order (the solver finds bodies by it).
fn saved_bodies(world: &mut World) -> Vec<BodyState> {
    let mut bodies: Vec<BodyState> = world
        .query::<(
            Entity,
            &Body,
            &BodyLattice,
            &ParticleClusters,
            Option<&SurfaceMesh>,
            Option<&HandlePose>,
        )>()
        .iter(world)
        .map(
            |(entity, body, lattice, clusters, surface, pose)| BodyState {
                entity,
                body: body.clone(),
                lattice: lattice.clone(),
                clusters: clusters.clone(),
                surface: surface.map(SurfaceMesh::saved),
                pose: pose.map(HandlePose::saved),
            },
        )
        .collect();
    bodies.sort_unstable_by_key(|b| b.entity);
    bodies
}

/// The particles, in the order the world stores them (which decides the order new ones join).
fn saved_particles(world: &mut World) -> Vec<ParticleState> {
    world
        .query::<(
            Entity,
            &Particle,
            &Position,
            &Velocity,
            &Orientation,
            &AngularVelocity,
            &InvMass,
        )>()
        .iter(world)
        .map(|(entity, p, x, v, q, w, m)| ParticleState {
            entity,
            particle: *p,
            position: *x,
            velocity: *v,
            orientation: *q,
            spin: *w,
            inv_mass: *m,
        })
        .collect()
}

/// The clusters.
fn saved_clusters(world: &mut World) -> Vec<ClusterState> {
    world
        .query::<(Entity, &ClusterMembers, &ClusterOf, &Compliance)>()
        .iter(world)
        .map(|(entity, m, of, c)| ClusterState {
            entity,
            members: m.clone(),
            of: *of,
            compliance: *c,
        })
        .collect()
}

/// The tools.
fn saved_tools(world: &mut World) -> Vec<ToolState> {
    world
        .query::<(Entity, &Tool, &ToolPose, Option<&ToolPath>)>()
        .iter(world)
        .map(|(entity, tool, pose, path)| ToolState {
            entity,
            tool: *tool,
            pose: *pose,
            path: path.cloned(),
        })
        .collect()
}

/// The colliders.
fn saved_colliders(world: &mut World) -> Vec<ColliderState> {
    world
        .query::<(
            Entity,
            &Collider,
            &ColliderPose,
            Option<&ColliderPath>,
            Option<&DynamicCollider>,
        )>()
        .iter(world)
        .map(|(entity, collider, pose, path, dynamic)| ColliderState {
            entity,
            collider: collider.clone(),
            pose: *pose,
            path: path.cloned(),
            dynamic: dynamic.copied(),
        })
        .collect()
}

/// The attachments, in entity order (the order they reach their terms).
fn saved_attachments(world: &mut World) -> Vec<AttachmentState> {
    let mut attachments: Vec<AttachmentState> = world
        .query::<(
            Entity,
            &Attachment,
            &AttachmentTarget,
            Option<&AttachmentPath>,
            Option<&AttachmentVelocity>,
        )>()
        .iter(world)
        .map(|(entity, a, target, path, velocity)| AttachmentState {
            entity,
            attachment: a.clone(),
            target: *target,
            path: path.cloned(),
            velocity: velocity.copied(),
        })
        .collect();
    attachments.sort_unstable_by_key(|a| a.entity);
    attachments
}

/// Reads a simulation written by [`save`]: a new world, prepared as
/// [`crate::systems::install`] prepares one, that goes on exactly as the saved one would
/// have.
pub fn load(reader: impl Read) -> Result<World> {
    load_with(reader, |_| Ok(()))
}

/// [`load`], with `setup` run on the loaded world once its entities are spawned (their
/// saved ids mapped in [`LoadedEntities`]) and before the solver's state is put back:
/// there the game registers its own terms — whose saved state the loading hands them
/// — and gives their components back to the entities it keeps them on.
pub fn load_with(reader: impl Read, setup: impl FnOnce(&mut World) -> Result<()>) -> Result<World> {
    let mut file = SaveReader::new(reader)?;
    let snapshot = read_sections(&mut file)?;
    file.finish()?;
    restore::restore(snapshot, setup)
}
