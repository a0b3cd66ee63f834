//! The solver layout: which particle entity sits at each dense index of the solver's
//! arrays, which cluster entity at each cluster slot, and the maps back. It is the one
//! owner of those maps — its fields are private; it is laid out afresh
//! ([`SolverLayout::rebuild`]), patched after a cut ([`SolverLayout::sync`]), saved and
//! restored ([`saved::LayoutState`]) by its own methods, and read through the methods below.
//!
//! The layout lays out the solver's clusters and particles with it (both are indexed by
//! it), so those methods take the [`Solver`] and [`Particles`] they keep in step;
//! [`SolverCache`], the resource, holds the three side by side.

mod cluster_slots;
mod patch;
mod rebuild;
pub mod saved;
pub mod table_rows;

pub use cluster_slots::ClusterSlots;

use crate::config::SolverMode;
use crate::ecs::components::{
    Body, BodyLattice, ClusterMembers, ClusterOf, Compliance, ParticleClusters,
};
use crate::ecs::resources::BodyCutReport;
use crate::solver::particles::Particles;
use crate::solver::registry::Terms;
use crate::solver::solve::Solver;
use bevy_ecs::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use table_rows::{ParticleColumns, StoredColumns, TableRows};

/// Body data as the layout reads it: the lattice, and the material (plasticity).
pub type BodyItem<'a> = (Entity, &'a BodyLattice, &'a Body);

/// Cluster data as the layout reads it.
pub type ClusterItem<'a> = (Entity, &'a ClusterMembers, &'a ClusterOf, &'a Compliance);

/// The solver's state beside the ECS: the particles' dense state, the solver (clusters,
/// other terms, the schemes' state) and the layout that says which entity each dense
/// index stands for.
#[derive(Resource, Debug)]
pub struct SolverCache {
    /// The particles' dense state.
    pub particles: Particles,
    /// The clusters, the other terms and the schemes' state.
    pub solver: Solver,
    /// Which entity each dense index and cluster slot stands for.
    pub layout: SolverLayout,
}

impl Default for SolverCache {
    fn default() -> Self {
        SolverCache {
            particles: Particles::default(),
            solver: Solver::new(Default::default(), Terms::builtin()),
            layout: SolverLayout::default(),
        }
    }
}

impl SolverCache {
    /// A cache laid out afresh from `bodies` and `clusters`, with the built-in terms.
    pub fn laid_out<'b, 'c>(
        bodies: impl Iterator<Item = BodyItem<'b>>,
        clusters: impl Iterator<Item = ClusterItem<'c>>,
        mode: SolverMode,
    ) -> Self {
        let mut cache = Self::default();
        let SolverCache {
            particles,
            solver,
            layout,
        } = &mut cache;
        layout.rebuild(solver, particles, bodies, clusters, mode);
        cache
    }

    /// The bare kernel of this cache: a solver of the same clusters with only `terms`,
    /// and a copy of the particles' dense state, for timing the solve without the ECS.
    pub fn bare(&self, terms: Terms) -> (Solver, Particles) {
        (
            Solver::new(self.solver.clusters.clone(), terms),
            self.particles.clone(),
        )
    }
}

/// A stamp no layout had before (see [`SolverLayout::stamp`]).
fn fresh_stamp() -> u64 {
    static STAMPS: AtomicU64 = AtomicU64::new(1);
    STAMPS.fetch_add(1, Ordering::Relaxed)
}

/// The dense↔entity maps of the solver (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct SolverLayout {
    /// Particle entity per dense index.
    entities: Vec<Entity>,
    /// Body-local particle index per dense index (the body: see [`SolverLayout::owner`]).
    locals: Vec<u32>,
    /// Dense index per entity index (`u32::MAX` if none).
    dense_of: Vec<u32>,
    /// Whether each dense particle is still in its body (cut particles keep their dense
    /// slot, frozen, until the next full rebuild).
    live: Vec<bool>,
    /// Each body's particles in the layout, by body.
    bodies: Vec<BodyDense>,
    /// Cluster entity per cluster slot (`Entity::PLACEHOLDER` if free).
    clusters: Vec<Entity>,
    /// Cluster slot per cluster entity.
    slot_of: ClusterSlots,
    /// Dense index ↔ row of the particle table, for the parallel load and store.
    rows: TableRows,
    /// Whether the layout matches the current topology.
    valid: bool,
    /// How the layout was last brought up to date, and how long it took.
    last_update: Option<LayoutUpdate>,
    /// Set when a saved simulation is loaded: the layout matches the loaded entities,
    /// which the next update only takes note of instead of patching them in.
    adopt_changes: bool,
    /// What changed since the terms last heard of it.
    pending: Option<PendingTopology>,
    /// Counts the rebuilds (a patch keeps every particle's dense index): tables derived
    /// from the dense indices are rebuilt when it changes.
    version: u64,
    /// See [`SolverLayout::stamp`].
    stamp: u64,
}

/// What changed in the layout since the terms last heard (they hear of it in
/// [`crate::systems::term_sync`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PendingTopology {
    /// Whether the layout was laid out afresh (every dense index moved).
    pub relaid: bool,
    /// The bodies whose particles or links changed.
    pub bodies: Vec<Entity>,
}

/// One update of the layout after a topology change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayoutUpdate {
    /// True when only the changed clusters were patched in; false for a full rebuild.
    pub patched: bool,
    /// Wall-clock milliseconds it took.
    pub ms: f64,
}

/// What changed since the layout was last brought up to date.
pub struct LayoutChanges<'a, 'c> {
    /// Bodies whose lattice changed (lost particles).
    pub bodies: &'a [Entity],
    /// The last cut's report: the particles each body lost. A hint, checked against the
    /// lattices; without it (or when it does not account for every lost particle) every
    /// particle of a changed body is looked at.
    pub cut: &'a [BodyCutReport],
    /// Clusters whose members or compliance changed, or that are new.
    pub clusters: Vec<ClusterItem<'c>>,
    /// Cluster entities that lost their members (despawned).
    pub removed: &'a [Entity],
    /// Each body's particle → clusters index, sorted by body: the clusters whose Jacobi
    /// weights a patch changes are found from it instead of by a pass over every
    /// membership of the layout.
    pub indices: Vec<(Entity, &'c ParticleClusters)>,
}

/// One body's particles in the layout.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct BodyDense {
    /// The body.
    pub body: Entity,
    /// The body's first dense index: its particles are `first..first + n`.
    pub first: u32,
    /// Dense particle index per body-local particle index (`u32::MAX` if none).
    pub dense: Vec<u32>,
    /// How many of the body's particles are live in the layout.
    pub live: usize,
}

impl BodyDense {
    /// The dense slot of body-local particle `p`, if it has one.
    pub fn slot(&self, p: u32) -> Option<usize> {
        self.dense
            .get(p as usize)
            .filter(|d| **d != u32::MAX)
            .map(|d| *d as usize)
    }

    /// The position of body-local particle `p` in the dense `positions` (NaN when it
    /// has no slot).
    pub fn position(&self, positions: &[glam::Vec3A], p: u32) -> glam::Vec3 {
        self.slot(p)
            .and_then(|d| positions.get(d))
            .map_or(glam::Vec3::NAN, |x| glam::Vec3::from(*x))
    }
}

impl SolverLayout {
    /// Dense particles in the layout (live or cut).
    pub fn len(&self) -> usize {
        self.entities.len()
    }

    /// Whether the layout holds no particle.
    pub fn is_empty(&self) -> bool {
        self.entities.is_empty()
    }

    /// Whether the layout matches the topology it was last brought up to date with.
    pub fn is_valid(&self) -> bool {
        self.valid
    }

    /// Asks for a full rebuild at the next update (bodies were spawned).
    pub fn invalidate(&mut self) {
        self.valid = false;
    }

    /// The particle entity of each dense index.
    pub fn entities(&self) -> &[Entity] {
        &self.entities
    }

    /// The dense index of particle entity `e`, if the layout holds it.
    pub fn dense_of(&self, e: Entity) -> Option<usize> {
        let d = *self.dense_of.get(e.index_u32() as usize)?;
        (self.entities.get(d as usize) == Some(&e)).then_some(d as usize)
    }

    /// Whether each dense particle is still in its body.
    pub fn live(&self) -> &[bool] {
        &self.live
    }

    /// The body-local index of each dense particle.
    pub fn locals(&self) -> &[u32] {
        &self.locals
    }

    /// Each body's particles in the layout, in entity order.
    pub fn bodies(&self) -> &[BodyDense] {
        &self.bodies
    }

    /// The particles of `body` in the layout.
    pub fn body(&self, body: Entity) -> Option<&BodyDense> {
        let b = self.bodies.binary_search_by_key(&body, |b| b.body).ok()?;
        Some(&self.bodies[b])
    }

    /// The cluster entity of each cluster slot (`Entity::PLACEHOLDER` for a free slot).
    pub fn cluster_entities(&self) -> &[Entity] {
        &self.clusters
    }

    /// The body and body-local index of dense particle `d`. Each body's particles hold
    /// one range of dense indices, the bodies in entity order, so the body is found by a
    /// binary search over the ranges' starts rather than stored per particle.
    pub fn owner(&self, d: usize) -> Option<(Entity, u32)> {
        dense_owner(&self.locals, &self.bodies, d)
    }

    /// The index in [`Self::bodies`] of the body dense particle `d` belongs to (the
    /// last whose range starts at or before it).
    pub fn body_index_of(&self, d: usize) -> Option<usize> {
        dense_body(&self.bodies, d)
    }

    /// Counts the full rebuilds: a table derived from dense indices is stale when it
    /// changes.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Drawn afresh each time the layout is laid out, patched or loaded, from one
    /// counter for every layout (zero for a layout never laid out, which holds no
    /// particle): a table of some particles' dense indices is current while this is
    /// what it was when the table was made.
    pub fn stamp(&self) -> u64 {
        self.stamp
    }

    /// How the layout was last brought up to date (`None` until it was, or since
    /// [`SolverLayout::forget_last_update`]).
    pub fn last_update(&self) -> Option<LayoutUpdate> {
        self.last_update
    }

    /// Forgets the last update, so that the next one can be told apart.
    pub fn forget_last_update(&mut self) {
        self.last_update = None;
    }

    /// Hands the terms what changed since they last heard (see [`PendingTopology`]).
    pub fn take_pending_topology(&mut self) -> Option<PendingTopology> {
        self.pending.take()
    }

    /// Tells every term about every body again at the next frame (a term was added).
    pub fn retell_terms(&mut self) {
        self.pending.get_or_insert_default().relaid = true;
    }

    /// Has every term hear the topology again this frame, though the layout did not
    /// change (a term's own particles did).
    pub fn request_topology(&mut self) {
        self.pending.get_or_insert_default();
    }

    /// Tells the terms that `body` changed (its material or its rest shape).
    pub fn body_changed(&mut self, body: Entity) {
        self.pending.get_or_insert_default().bodies.push(body);
    }

    /// Whether the layout must be brought up to date: bodies were removed or something
    /// else changed (`changed`), or the layout is not valid. The first call after a
    /// simulation was loaded only takes note of the loaded entities and says no.
    pub fn wants_update(&mut self, bodies_removed: bool, changed: bool) -> bool {
        if std::mem::take(&mut self.adopt_changes) {
            return false;
        }
        if bodies_removed {
            self.valid = false;
        }
        !self.valid || changed
    }

    /// Brings the layout, and the solver's clusters and particles with it, up to date:
    /// patches in the `changes` when that is possible, else lays everything out afresh
    /// from `bodies` and `all_clusters`. Records what changed for the terms.
    pub fn sync<'a>(
        &mut self,
        solver: &mut Solver,
        particles: &mut Particles,
        bodies: &Query<BodyItem>,
        changes: LayoutChanges<'_, 'a>,
        all_clusters: impl Iterator<Item = ClusterItem<'a>>,
        mode: SolverMode,
    ) {
        let start = Instant::now();
        let changed_bodies = changes.bodies.to_vec();
        let patched =
            self.valid && solver.mode() == mode && self.patch(solver, particles, bodies, changes);
        if !patched {
            self.rebuild(solver, particles, bodies.iter(), all_clusters, mode);
        }
        let pending = self.pending.get_or_insert_with(PendingTopology::default);
        pending.relaid |= !patched;
        pending.bodies.extend(changed_bodies);
        if patched {
            self.stamp = fresh_stamp();
        }
        self.last_update = Some(LayoutUpdate {
            patched,
            ms: start.elapsed().as_secs_f64() * 1e3,
        });
    }

    /// Copies the particle table's state into the dense `particles` (in parallel, by the
    /// rows of [`table_rows::TableRows`]).
    pub fn load(&mut self, particles: &mut Particles, table: ParticleColumns) {
        self.rows
            .load(particles, &self.entities, &self.dense_of, table);
    }

    /// Writes the dense `particles` into the table's columns (the rows of the last
    /// [`SolverLayout::load`]).
    pub fn store(&self, particles: &Particles, table: StoredColumns) {
        self.rows.store(particles, table);
    }
}

/// The body and body-local index of dense particle `d`, given the body-local index per
/// dense index and the bodies' ranges (see [`SolverLayout::owner`]).
fn dense_owner(locals: &[u32], bodies: &[BodyDense], d: usize) -> Option<(Entity, u32)> {
    let local = *locals.get(d)?;
    Some((bodies[dense_body(bodies, d)?].body, local))
}

/// The index of the body of `bodies` whose dense range holds `d` (see
/// [`SolverLayout::body_index_of`]).
fn dense_body(bodies: &[BodyDense], d: usize) -> Option<usize> {
    bodies
        .partition_point(|b| b.first as usize <= d)
        .checked_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn owners_are_found_from_the_bodies_dense_ranges() {
        let mut world = World::new();
        let (a, b, c) = (
            world.spawn_empty().id(),
            world.spawn_empty().id(),
            world.spawn_empty().id(),
        );
        let body = |body, first| BodyDense {
            body,
            first,
            dense: Vec::new(),
            live: 0,
        };
        // a: dense 0..3, b: none, c: 3..5
        let layout = SolverLayout {
            locals: vec![7, 0, 2, 4, 1],
            bodies: vec![body(a, 0), body(b, 3), body(c, 3)],
            ..Default::default()
        };
        let owners: Vec<_> = (0..6).map(|d| layout.owner(d)).collect();
        assert_eq!(
            owners,
            [
                Some((a, 7)),
                Some((a, 0)),
                Some((a, 2)),
                Some((c, 4)),
                Some((c, 1)),
                None
            ]
        );
    }
}
