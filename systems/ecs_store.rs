//! [`ClusterStore`] over ECS cluster entities: member lists live in `ClusterMembers`
//! components, the particle index in the body's `ParticleClusters`. A cluster's key is
//! its entity index (`Entity::index_u32`), resolved to the live entity when a component
//! is read or written. New clusters get reserved entities whose components are inserted
//! by [`EcsClusterStore::finish`]. [`BodyClusters`] is the system parameter the
//! reconstruction stages open a body's store from.

use crate::cluster_edits::{ClusterEdits, diff_into};
use crate::cluster_index::ClusterIndex;
use crate::cluster_store::{ClusterStore, extend_indexed, extend_members, normalise, owned_list};
use crate::components::{
    Body, BodyLattice, ClusterMembers, ClusterOf, Compliance, ParticleClusters, cluster_entity,
};
use crate::config::Material;
use crate::lattice::Lattice;
use bevy_ecs::entity::Entities;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use rustc_hash::{FxHashMap, FxHashSet};

/// What a reconstruction stage reads and writes: the bodies' particle indices and the
/// cluster entities (it reads no particle data).
#[derive(SystemParam)]
pub struct BodyClusters<'w, 's> {
    commands: Commands<'w, 's>,
    entities: &'w Entities,
    bodies: Query<
        'w,
        's,
        (
            &'static Body,
            &'static BodyLattice,
            &'static mut ParticleClusters,
        ),
    >,
    clusters: Query<'w, 's, &'static mut ClusterMembers>,
}

impl<'w, 's> BodyClusters<'w, 's> {
    /// The store of `body`'s clusters, with its material and lattice; `None` if `body`
    /// is not a body.
    pub fn open(
        &mut self,
        body: Entity,
    ) -> Option<(EcsClusterStore<'_, 'w, 's>, &Material, &Lattice)> {
        let (b, lattice, index) = self.bodies.get_mut(body).ok()?;
        let index = &mut index.into_inner().0;
        // (particles split by the cut have their slots from here on)
        index.grow(lattice.lattice.len());
        let store = EcsClusterStore {
            body,
            compliance: b.material.cluster_compliance(lattice.lattice.spacing()),
            index,
            entities: self.entities,
            clusters: &mut self.clusters,
            commands: &mut self.commands,
            created: FxHashMap::default(),
            removed: FxHashSet::default(),
        };
        Some((store, &b.material, &lattice.lattice))
    }
}

/// The clusters of one body, editable by the reconstruction algorithms.
pub struct EcsClusterStore<'a, 'w, 's> {
    body: Entity,
    /// Compliance of the clusters this store creates.
    compliance: f32,
    index: &'a mut ClusterIndex,
    entities: &'a Entities,
    clusters: &'a mut Query<'w, 's, &'static mut ClusterMembers>,
    commands: &'a mut Commands<'w, 's>,
    /// Clusters made through this store: key → (reserved entity, members).
    created: FxHashMap<u32, (Entity, Vec<u32>)>,
    removed: FxHashSet<u32>,
}

/// The store keys of cluster entities (their entity indices), in order.
pub fn keys_of(clusters: &[Entity]) -> Vec<u32> {
    clusters.iter().map(|e| e.index_u32()).collect()
}

impl EcsClusterStore<'_, '_, '_> {
    /// The entities of clusters `keys`, in order (see [`EcsClusterStore::entity`]).
    pub fn entities_of(&self, keys: Vec<u32>) -> Vec<Entity> {
        keys.into_iter().map(|k| self.entity(k)).collect()
    }

    /// The entity of cluster `k` (reserved, if this store created it).
    pub fn entity(&self, k: u32) -> Entity {
        match self.created.get(&k) {
            Some((e, _)) => *e,
            None => cluster_entity(self.entities, k),
        }
    }

    /// Inserts the components of the clusters created through this store.
    pub fn finish(self) {
        for (e, members) in self.created.into_values() {
            self.commands.entity(e).insert((
                ClusterMembers(members),
                ClusterOf(self.body),
                Compliance(self.compliance),
            ));
        }
    }
}

impl ClusterStore for EcsClusterStore<'_, '_, '_> {
    fn index(&self) -> &ClusterIndex {
        self.index
    }

    fn members(&self, k: u32) -> &[u32] {
        if self.removed.contains(&k) {
            return &[];
        }
        stored_members(&self.created, self.clusters, self.entities, k)
    }

    fn apply(&mut self, edits: &ClusterEdits) -> Vec<u32> {
        // (removed clusters are sized by their entity's list, which the loop below reads
        // anyway: a guess of 32 members each saves a second lookup)
        let mut changes = Vec::with_capacity(edits.changes_capacity(32 * edits.removed().len()));
        for (k, members) in edits.replaced() {
            if let Some((_, m)) = self.created.get_mut(&k) {
                diff_into(m, members, k, &mut changes);
                m.clear();
                m.extend_from_slice(members);
            } else if !self.removed.contains(&k)
                && let Ok(mut m) = self.clusters.get_mut(cluster_entity(self.entities, k))
            {
                diff_into(&m.0, members, k, &mut changes);
                m.0.clear();
                m.0.extend_from_slice(members);
            }
        }
        for (k, extra) in edits.extended() {
            if let Some((_, m)) = self.created.get_mut(&k) {
                extend_members(m, extra, k, &mut changes);
            } else if !self.removed.contains(&k)
                && let Ok(mut m) = self.clusters.get_mut(cluster_entity(self.entities, k))
            {
                // marked changed only when it did change: the solver layout re-reads
                // changed clusters
                let before = changes.len();
                extend_members(&mut m.bypass_change_detection().0, extra, k, &mut changes);
                if changes.len() > before {
                    m.set_changed();
                }
            }
        }
        for &k in edits.removed() {
            if self.removed.contains(&k) {
                continue;
            }
            let members = stored_members(&self.created, self.clusters, self.entities, k);
            diff_into(members, &[], k, &mut changes);
            let e = self.entity(k);
            self.created.remove(&k);
            self.removed.insert(k);
            self.commands.entity(e).despawn();
        }
        let created = edits
            .created()
            .map(|members| {
                let e = self.commands.spawn_empty().id();
                let k = e.index_u32();
                diff_into(&[], members, k, &mut changes);
                self.created.insert(k, (e, owned_list(members)));
                k
            })
            .collect();
        self.index.apply(&changes);
        created
    }

    fn add_members(&mut self, k: u32, extra: &[u32]) {
        if let Some((_, m)) = self.created.get_mut(&k) {
            extend_indexed(m, extra, k, self.index);
        } else if !self.removed.contains(&k)
            && let Ok(mut m) = self.clusters.get_mut(cluster_entity(self.entities, k))
        {
            // marked changed only when it did change (see `apply`)
            let members = &mut m.bypass_change_detection().0;
            let before = members.len();
            extend_indexed(members, extra, k, self.index);
            if members.len() > before {
                m.set_changed();
            }
        }
    }

    fn create(&mut self, members: Vec<u32>) -> u32 {
        let members = normalise(members);
        let e = self.commands.spawn_empty().id();
        let k = e.index_u32();
        self.index.add_cluster(k, &members);
        self.created.insert(k, (e, members));
        k
    }
}

/// The members of cluster `k` as stored: in `created` if this store made it, else in
/// its `ClusterMembers` component (empty if it has none). Takes the fields, not the
/// store, so that the index can be edited while the list is borrowed.
fn stored_members<'x>(
    created: &'x FxHashMap<u32, (Entity, Vec<u32>)>,
    clusters: &'x Query<'_, '_, &mut ClusterMembers>,
    entities: &Entities,
    k: u32,
) -> &'x [u32] {
    match created.get(&k) {
        Some((_, m)) => m,
        None => clusters
            .get(cluster_entity(entities, k))
            .map(|m| m.0.as_slice())
            .unwrap_or(&[]),
    }
}
