//! [`ClusterStore`] over ECS cluster entities: member lists live in `ClusterMembers`
//! components, the particle index in the body's `ParticleClusters`. New clusters get
//! reserved entities whose components are inserted by [`EcsClusterStore::finish`].

use crate::cluster_store::{
    ClusterList, ClusterStore, index_add, index_remove, index_replace, merge_sorted, normalise,
};
use crate::components::{ClusterMembers, ClusterOf, Stiffness};
use bevy_ecs::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};

/// The clusters of one body, editable by the reconstruction algorithms.
pub struct EcsClusterStore<'a, 'd, 'qw, 'qs, 'cw, 'cs> {
    body: Entity,
    stiffness: f32,
    index: &'a mut Vec<ClusterList<Entity>>,
    clusters: &'a mut Query<'qw, 'qs, &'d mut ClusterMembers>,
    commands: &'a mut Commands<'cw, 'cs>,
    created: FxHashMap<Entity, Vec<u32>>,
    removed: FxHashSet<Entity>,
}

impl<'a, 'd, 'qw, 'qs, 'cw, 'cs> EcsClusterStore<'a, 'd, 'qw, 'qs, 'cw, 'cs> {
    /// Wraps one body's clusters; new clusters get `stiffness`.
    pub fn new(
        body: Entity,
        stiffness: f32,
        index: &'a mut Vec<ClusterList<Entity>>,
        clusters: &'a mut Query<'qw, 'qs, &'d mut ClusterMembers>,
        commands: &'a mut Commands<'cw, 'cs>,
    ) -> Self {
        Self {
            body,
            stiffness,
            index,
            clusters,
            commands,
            created: FxHashMap::default(),
            removed: FxHashSet::default(),
        }
    }

    /// Inserts the components of the clusters created through this store.
    pub fn finish(self) {
        for (e, members) in self.created {
            self.commands.entity(e).insert((
                ClusterMembers(members),
                ClusterOf(self.body),
                Stiffness(self.stiffness),
            ));
        }
    }
}

impl ClusterStore for EcsClusterStore<'_, '_, '_, '_, '_, '_> {
    type Key = Entity;

    fn particle_index(&self) -> &[ClusterList<Entity>] {
        self.index
    }

    fn members(&self, k: Entity) -> &[u32] {
        if self.removed.contains(&k) {
            return &[];
        }
        stored_members(&self.created, self.clusters, k)
    }

    fn set_members(&mut self, k: Entity, members: Vec<u32>) {
        let members = normalise(members);
        if let Some(m) = self.created.get_mut(&k) {
            index_replace(self.index, m, &members, k);
            *m = members;
        } else if !self.removed.contains(&k)
            && let Ok(mut m) = self.clusters.get_mut(k)
        {
            index_replace(self.index, &m.0, &members, k);
            m.0 = members;
        }
    }

    fn add_members(&mut self, k: Entity, extra: &[u32]) {
        let new = if let Some(m) = self.created.get_mut(&k) {
            merge_sorted(m, extra)
        } else if let Ok(mut m) = self.clusters.get_mut(k) {
            // marked changed only when it did change: the solver layout re-reads changed
            // clusters
            let new = merge_sorted(&mut m.bypass_change_detection().0, extra);
            if new > 0 {
                m.set_changed();
            }
            new
        } else {
            return;
        };
        if new > 0 {
            index_add(self.index, extra, k);
        }
    }

    fn create(&mut self, members: Vec<u32>) -> Entity {
        let members = normalise(members);
        let e = self.commands.spawn_empty().id();
        index_add(self.index, &members, e);
        self.created.insert(e, members);
        e
    }

    fn remove(&mut self, k: Entity) {
        if !self.removed.contains(&k) {
            // (the member list and the index are separate fields: no copy of the list)
            let members = stored_members(&self.created, self.clusters, k);
            index_remove(self.index, members, k);
        }
        if self.created.remove(&k).is_none() {
            self.removed.insert(k);
        }
        self.commands.entity(k).despawn();
    }
}

/// The members of cluster `k` as stored: in `created` if this store made it, else in
/// its `ClusterMembers` component (empty if it has none). Takes the fields, not the
/// store, so that the index can be edited while the list is borrowed.
fn stored_members<'x>(
    created: &'x FxHashMap<Entity, Vec<u32>>,
    clusters: &'x Query<'_, '_, &mut ClusterMembers>,
    k: Entity,
) -> &'x [u32] {
    match created.get(&k) {
        Some(m) => m,
        None => clusters.get(k).map(|m| m.0.as_slice()).unwrap_or(&[]),
    }
}
