//! Loading a saved simulation: the entities spawned again (with new ids, in the saved
//! order where the engine orders by entity), every reference to them mapped, the
//! solver's state put back, and the whole checked before it is handed out.

use super::state::*;
use crate::ecs::check::check_invariants;
use crate::ecs::components::*;
use crate::ecs::handles::HandlePose;
use crate::ecs::layout::{SolverCache, SolverLayout};
use crate::ecs::resources::{CutReport, SimClock, SimRng};
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::{CleaveError, Result};
use crate::systems::{SyncSchedule, install};
use bevy_ecs::prelude::*;
use std::collections::HashMap;

/// Old entity → new entity, for the entities the snapshot spawns.
struct EntityMap(HashMap<Entity, Entity>);

impl EntityMap {
    /// The new entity of `e`; a placeholder for an entity the save does not hold (a
    /// particle cut before the save, say).
    fn get(&self, e: Entity) -> Entity {
        self.0.get(&e).copied().unwrap_or(Entity::PLACEHOLDER)
    }

    /// The new entity of `e`, which the save must hold.
    fn required(&self, e: Entity, what: &str) -> Result<Entity> {
        self.0
            .get(&e)
            .copied()
            .ok_or_else(|| invalid(format!("{what} names entity {e}, which is not saved")))
    }
}

pub(super) fn restore(
    snapshot: Snapshot,
    setup: impl FnOnce(&mut World) -> Result<()>,
) -> Result<World> {
    let Snapshot {
        entity_bound,
        config,
        clock,
        rng,
        bodies,
        particles,
        clusters,
        tools,
        colliders,
        attachments,
        cache,
        cut,
        label,
    } = snapshot;
    config.validate()?;
    let memory = config.memory_budget_bytes();
    let mut loaded = World::new();
    // No entity of the saving world is handed out again, so an entity kept from before
    // the save names nothing in the loaded world and is refused, instead of silently
    // naming whatever took its place. The file's bound is trusted only as far as the
    // entities it holds make plausible, so a corrupt bound cannot make the loaded
    // world's entity table huge.
    let saved: Vec<Entity> = (bodies.iter().map(|b| b.entity))
        .chain(particles.iter().map(|p| p.entity))
        .chain(clusters.iter().map(|c| c.entity))
        .chain(tools.iter().map(|t| t.entity))
        .chain(colliders.iter().map(|c| c.entity))
        .chain(attachments.iter().map(|a| a.entity))
        .collect();
    let plausible = (4 * saved.len() as u64 + (1 << 20)).min(u32::MAX as u64 / 2) as u32;
    retire_saved_ids(&mut loaded, entity_bound.min(plausible), &saved);
    install(&mut loaded, config);
    let world = &mut loaded;
    let mut map = EntityMap(HashMap::new());
    // bodies first, their new ids in the saved ids' order (the solver finds bodies by
    // it)
    for (b, e) in bodies.iter().zip(spawn_ascending(world, bodies.len())) {
        map.0.insert(b.entity, e);
    }
    spawn_particles(world, particles, &mut map)?;
    spawn_clusters(world, clusters, &mut map)?;
    let mut handles = LoadedEntities::default();
    spawn_tools_and_colliders(world, tools, colliders, &mut handles)?;
    spawn_attachments(world, attachments, &map, &mut handles)?;
    restore_bodies(world, bodies, &map, memory, &mut handles)?;
    handles.0.sort_unstable();
    world.insert_resource(handles);
    *world.resource_mut::<SimClock>() = clock;
    *world.resource_mut::<SimRng>() = rng;
    world.insert_resource(label);
    let mut cut = cut;
    for b in &mut cut.bodies {
        b.body = map.get(b.body);
    }
    *world.resource_mut::<CutReport>() = cut;
    setup(world)?;
    restore_cache(world, cache, &map)?;
    world.run_schedule(SyncSchedule);
    let violations = check_invariants(world);
    if let Some((_, v)) = violations.first() {
        return Err(invalid(format!("inconsistent: {v}")));
    }
    Ok(loaded)
}

/// Spawns the saved particles, each checked, in the saved order.
fn spawn_particles(
    world: &mut World,
    particles: Vec<ParticleState>,
    map: &mut EntityMap,
) -> Result<()> {
    for p in particles {
        let finite = p.position.0.is_finite()
            && p.velocity.0.is_finite()
            && p.spin.0.is_finite()
            && p.orientation.0.is_finite()
            && (p.orientation.0.length() - 1.0).abs() < 1e-3;
        if !(finite && p.inv_mass.0.is_finite() && p.inv_mass.0 >= 0.0) {
            return Err(invalid(format!(
                "particles: particle {} of its body has a non-finite state or a non-unit orientation",
                p.particle.index
            )));
        }
        let particle = Particle {
            body: map.required(p.particle.body, "a particle")?,
            ..p.particle
        };
        let e = world
            .spawn((
                particle,
                p.position,
                p.velocity,
                p.orientation,
                p.spin,
                p.inv_mass,
            ))
            .id();
        map.0.insert(p.entity, e);
    }
    Ok(())
}

/// Spawns the saved clusters.
fn spawn_clusters(
    world: &mut World,
    clusters: Vec<ClusterState>,
    map: &mut EntityMap,
) -> Result<()> {
    for c in clusters {
        let of = ClusterOf {
            body: map.required(c.of.body, "a cluster")?,
            ..c.of
        };
        let e = world.spawn((c.members, of, c.compliance)).id();
        map.0.insert(c.entity, e);
    }
    Ok(())
}

/// Spawns the saved tools and colliders, noting each one's new entity.
fn spawn_tools_and_colliders(
    world: &mut World,
    tools: Vec<ToolState>,
    colliders: Vec<ColliderState>,
    handles: &mut LoadedEntities,
) -> Result<()> {
    for t in tools {
        let mut e = world.spawn((t.tool, t.pose));
        if let Some(path) = t.path {
            e.insert(path);
        }
        handles.0.push((t.entity, e.id()));
    }
    for c in colliders {
        let mut e = world.spawn((c.collider, c.pose));
        if let Some(path) = c.path {
            e.insert(path);
        }
        if let Some(dynamic) = c.dynamic {
            dynamic.check()?;
            e.insert(dynamic);
        }
        handles.0.push((c.entity, e.id()));
    }
    Ok(())
}

/// Spawns the saved attachments, in the saved (entity) order, in which they reach their
/// terms.
fn spawn_attachments(
    world: &mut World,
    attachments: Vec<AttachmentState>,
    map: &EntityMap,
    handles: &mut LoadedEntities,
) -> Result<()> {
    let ids = spawn_ascending(world, attachments.len());
    for (a, id) in attachments.into_iter().zip(ids) {
        let attachment = Attachment {
            body: map.required(a.attachment.body, "an attachment")?,
            ..a.attachment
        };
        let mut e = world.entity_mut(id);
        e.insert((attachment, a.target));
        if let Some(path) = a.path {
            e.insert(path);
        }
        if let Some(velocity) = a.velocity {
            e.insert(velocity);
        }
        handles.0.push((a.entity, e.id()));
    }
    Ok(())
}

/// Gives every body entity its saved components: lattice (its particles mapped),
/// clusters index, surface and handle pose, each checked.
fn restore_bodies(
    world: &mut World,
    bodies: Vec<BodyState>,
    map: &EntityMap,
    memory: u64,
    handles: &mut LoadedEntities,
) -> Result<()> {
    for (i, b) in bodies.into_iter().enumerate() {
        if let Some((edge, c)) = b.lattice.lattice.invalid_crossing() {
            return Err(invalid(format!(
                "bodies: body {i}: the crossing of edge {edge} (fraction {}, normal {}) is out of range (allowed 0 ≤ fraction ≤ 1, a finite unit normal, an edge of the lattice)",
                c.fraction, c.normal
            )));
        }
        let mut lattice = b.lattice;
        for e in &mut lattice.particles {
            *e = map.get(*e);
        }
        let (entities, free) = b.clusters.keys.parts();
        let keys = ClusterKeys::from_parts(
            entities.iter().map(|e| map.get(*e)).collect(),
            free.to_vec(),
        );
        let clusters = ParticleClusters {
            index: b.clusters.index,
            keys,
        };
        let body = map.get(b.entity);
        let surface = b
            .surface
            .map(|s| SurfaceMesh::restore(s, &lattice.lattice))
            .transpose()
            .map_err(|e| invalid(format!("bodies: body {i}: surface: {e}")))?;
        let pose = b
            .pose
            .map(|p| HandlePose::restore(p, &lattice.lattice, memory))
            .transpose()
            .map_err(|e| invalid(format!("bodies: body {i}: handles: {e}")))?;
        let mut entity = world.entity_mut(body);
        entity.insert((b.body, lattice, clusters));
        if let Some(surface) = surface {
            entity.insert(surface);
        }
        if let Some(pose) = pose {
            entity.insert(pose);
        }
        handles.0.push((b.entity, body));
    }
    Ok(())
}

/// Takes every entity index below `bound` once and frees it again, each past the
/// generation a `saved` entity had there: the loaded world reuses the saving world's
/// indices (so a chain of saves and loads keeps the index space as large as the
/// largest world, not the sum of them) but never one of its entities. Freeing an index
/// moves its generation on, and the allocator hands the last freed index out first,
/// so an index is stepped on by freeing it, taking it back and freeing it again. An
/// index whose saved generation is implausibly far on (a damaged file) stays taken.
fn retire_saved_ids(world: &mut World, bound: u32, saved: &[Entity]) {
    /// The most times one index is stepped on.
    const MOST_STEPS: u32 = 64;
    let mut past: HashMap<u32, u32> = HashMap::new();
    for e in saved {
        let generation = past.entry(e.index_u32()).or_default();
        *generation = (*generation).max(e.generation().to_bits());
    }
    let taken: Vec<Entity> = (0..bound)
        .map_while(|_| (world.entities().len() < bound).then(|| world.spawn_empty().id()))
        .collect();
    for mut e in taken {
        let target = past.get(&e.index_u32()).copied();
        if target.is_some_and(|g| g >= MOST_STEPS) {
            continue;
        }
        loop {
            world.despawn(e);
            if target.is_none_or(|g| e.generation().to_bits() >= g) {
                break;
            }
            // (the index just freed comes back first, one generation on)
            let again = world.spawn_empty().id();
            debug_assert_eq!(again.index_u32(), e.index_u32());
            e = again;
        }
    }
}

/// `count` new empty entities, ascending. Entities order by their bits, in which
/// bevy stores an index inverted, so entities spawned one after another on fresh
/// indices descend (and on reused ones may go either way); what the engine orders by
/// entity must come back in the saved order.
fn spawn_ascending(world: &mut World, count: usize) -> Vec<Entity> {
    let mut ids: Vec<Entity> = (0..count).map(|_| world.spawn_empty().id()).collect();
    ids.sort_unstable();
    ids
}

/// Puts the saved solver state in `world`'s cache, with its entities mapped.
fn restore_cache(world: &mut World, saved: CacheState, map: &EntityMap) -> Result<()> {
    let slots = saved.particles.len();
    if saved.clusters_term.particle_count() != slots {
        return Err(invalid("the solver's particle tables disagree in length"));
    }
    if !saved.clusters_term.plasticity_fits() {
        return Err(invalid("the clusters' plastic shifts do not fit them"));
    }
    let state = &saved.particles;
    let finite = |v: &[glam::Vec3A]| v.iter().all(|x| x.is_finite());
    let masses = state.inv_mass.iter().all(|w| w.is_finite() && *w >= 0.0);
    if !(masses && finite(&state.positions) && finite(&state.previous) && finite(&state.velocities))
    {
        return Err(invalid("solver layout: non-finite particle state"));
    }
    let layout = SolverLayout::restore(saved.layout, slots, |e| map.get(e)).map_err(invalid)?;
    let mut cache = world.resource_mut::<SolverCache>();
    cache.solver.clusters = saved.clusters_term;
    cache.solver.gauss_seidel = saved.gauss_seidel;
    cache
        .solver
        .terms
        .resume_states(saved.terms)
        .map_err(|e| invalid(format!("solver layout: {e}")))?;
    cache.particles = saved.particles;
    cache.layout = layout;
    Ok(())
}

/// The entities a loaded simulation's bodies, tools, colliders and attachments had in the
/// saving world, each with its entity in the loaded one (a resource of the loaded world;
/// [`crate::sim::simulation::Simulation::loaded_entity`] reads it).
#[derive(Resource, Clone, Debug, Default)]
pub struct LoadedEntities(Vec<(Entity, Entity)>);

impl LoadedEntities {
    /// The loaded entity of `saved`, a body, tool, collider or attachment of the saved
    /// simulation.
    pub fn get(&self, saved: Entity) -> Result<Entity> {
        self.0
            .binary_search_by_key(&saved, |(old, _)| *old)
            .map(|i| self.0[i].1)
            .map_err(|_| {
                CleaveError::InvalidEntity(format!(
                    "{saved} was not a body, tool, collider or attachment of the saved simulation"
                ))
            })
    }
}
