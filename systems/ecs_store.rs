//! [`ClusterStore`] over ECS cluster entities: member lists live in `ClusterMembers`
//! components, the particle index and the key → entity table in the body's
//! `ParticleClusters`. New clusters get reserved entities, named by a key the body hands
//! out at once, whose components are inserted by [`EcsClusterStore::finish`]; the keys
//! of removed clusters are freed there too, so that no key is handed out twice within
//! one store's edits. [`BodyClusters`] is the system parameter the reconstruction stages
//! open a body's store from.

use crate::body::groups::ParticleGroups;
use crate::body::lattice::Lattice;
use crate::clusters::edits::{ClusterEdits, diff_into};
use crate::clusters::index::ClusterIndex;
use crate::clusters::store::{ClusterStore, extend_indexed, extend_members, normalise, owned_list};
use crate::config::Material;
use crate::ecs::components::{
    Body, BodyLattice, ClusterKeys, ClusterMembers, ClusterOf, Compliance, ParticleClusters,
};
use crate::ecs::groups::cluster_compliance;
use bevy_ecs::prelude::*;
use bevy_ecs::system::SystemParam;
use rustc_hash::{FxHashMap, FxHashSet};

/// What a reconstruction stage reads and writes: the bodies' particle indices and the
/// cluster entities (it reads no particle data).
#[derive(SystemParam)]
pub struct BodyClusters<'w, 's> {
    commands: Commands<'w, 's>,
    bodies: Query<
        'w,
        's,
        (
            Entity,
            &'static Body,
            &'static BodyLattice,
            &'static mut ParticleClusters,
        ),
    >,
    clusters: Query<'w, 's, &'static mut ClusterMembers>,
}

impl<'w, 's> BodyClusters<'w, 's> {
    /// Per body, the keys whose entities are among `gone` (despawned) while the body's key
    /// table still names them: clusters despawned from outside. By body, keys ascending.
    pub fn lost_clusters(&self, gone: &FxHashSet<Entity>) -> Vec<(Entity, Vec<u32>)> {
        if gone.is_empty() {
            return Vec::new();
        }
        let mut lost: Vec<(Entity, Vec<u32>)> = self
            .bodies
            .iter()
            .map(|(body, _, _, clusters)| {
                let keys = clusters.keys.iter();
                (
                    body,
                    keys.filter(|(_, e)| gone.contains(e))
                        .map(|(k, _)| k)
                        .collect(),
                )
            })
            .filter(|(_, keys): &(Entity, Vec<u32>)| !keys.is_empty())
            .collect();
        lost.sort_unstable_by_key(|(body, _)| *body);
        lost
    }

    /// Where `body`'s seed grid lies (see [`crate::ecs::components::Body::seed_grid`]);
    /// `None` if `body` is not a body.
    pub fn seed_grid(&self, body: Entity) -> Option<glam::IVec3> {
        self.bodies.get(body).ok().map(|(_, b, ..)| b.seed_grid)
    }

    /// The store of `body`'s clusters, with its material and lattice; `None` if `body`
    /// is not a body, or one of the oriented model (its groups follow its lattice, and
    /// the reconstruction keeps them so by leaving it alone).
    pub fn open(
        &mut self,
        body: Entity,
    ) -> Option<(EcsClusterStore<'_, 'w, 's>, &Material, &Lattice)> {
        let (_, b, lattice, clusters) = self.bodies.get_mut(body).ok()?;
        if b.material.model == crate::config::Model::Oriented {
            return None;
        }
        let ParticleClusters { index, keys } = clusters.into_inner();
        // (particles split by the cut have their slots from here on)
        index.grow(lattice.lattice.len());
        let store = EcsClusterStore {
            body,
            compliance: ClusterCompliance {
                material: b.material.clone(),
                groups: b.groups.clone(),
                spacing: lattice.lattice.spacing(),
            },
            index,
            keys,
            clusters: &mut self.clusters,
            commands: &mut self.commands,
            created: FxHashMap::default(),
            removed: FxHashSet::default(),
        };
        Some((store, &b.material, &lattice.lattice))
    }
}

/// A body's material, groups and spacing, from which a new cluster's compliance follows
/// ([`cluster_compliance`]).
struct ClusterCompliance {
    material: Material,
    groups: ParticleGroups,
    spacing: f32,
}

/// The clusters of one body, editable by the reconstruction algorithms.
pub struct EcsClusterStore<'a, 'w, 's> {
    body: Entity,
    /// What gives the clusters this store creates their compliance.
    compliance: ClusterCompliance,
    index: &'a mut ClusterIndex,
    keys: &'a mut ClusterKeys,
    clusters: &'a mut Query<'w, 's, &'static mut ClusterMembers>,
    commands: &'a mut Commands<'w, 's>,
    /// Clusters made through this store: key → (reserved entity, members).
    created: FxHashMap<u32, (Entity, Vec<u32>)>,
    removed: FxHashSet<u32>,
}

impl EcsClusterStore<'_, '_, '_> {
    /// The entities of clusters `keys`, in order (see [`EcsClusterStore::entity`]).
    pub fn entities_of(&self, keys: Vec<u32>) -> Vec<Entity> {
        keys.into_iter().map(|k| self.entity(k)).collect()
    }

    /// The entity of cluster `k` (reserved, if this store created it;
    /// `Entity::PLACEHOLDER` if `k` names none).
    pub fn entity(&self, k: u32) -> Entity {
        self.keys.entity(k).unwrap_or(Entity::PLACEHOLDER)
    }

    /// Forgets clusters `lost` whose entities are gone: takes them out of the particle
    /// index and frees their keys. Returns the particles they held, ascending.
    pub fn forget(&mut self, lost: &[u32]) -> Vec<u32> {
        let mut held = Vec::new();
        for (p, keys) in self.index.iter().enumerate() {
            if keys.iter().any(|k| lost.binary_search(k).is_ok()) {
                held.push(p as u32);
            }
        }
        for &p in &held {
            for &k in lost {
                self.index.remove(p, k);
            }
        }
        for &k in lost {
            self.keys.remove(k);
        }
        held
    }

    /// Inserts the components of the clusters created through this store, and frees the
    /// keys of those it removed.
    pub fn finish(self) {
        let mut removed: Vec<u32> = self.removed.into_iter().collect();
        // (in key order: the free list's order decides the keys handed out next)
        removed.sort_unstable();
        for k in removed {
            self.keys.remove(k);
        }
        let mut created: Vec<(u32, (Entity, Vec<u32>))> = self.created.into_iter().collect();
        created.sort_unstable_by_key(|(k, _)| *k);
        for (key, (e, members)) in created {
            let compliance = cluster_compliance(
                &self.compliance.material,
                &self.compliance.groups,
                &members,
                self.compliance.spacing,
            );
            self.commands.entity(e).insert((
                ClusterMembers(members),
                ClusterOf {
                    body: self.body,
                    key,
                },
                Compliance(compliance),
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
        stored_members(&self.created, self.clusters, self.keys, k)
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
                && let Ok(mut m) = self.clusters.get_mut(self.entity(k))
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
                && let Ok(mut m) = self.clusters.get_mut(self.entity(k))
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
            let members = stored_members(&self.created, self.clusters, self.keys, k);
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
                let k = self.keys.insert(e);
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
            && let Ok(mut m) = self.clusters.get_mut(self.entity(k))
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
        let k = self.keys.insert(e);
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
    keys: &ClusterKeys,
    k: u32,
) -> &'x [u32] {
    match created.get(&k) {
        Some((_, m)) => m,
        None => clusters
            .get(keys.entity(k).unwrap_or(Entity::PLACEHOLDER))
            .map(|m| m.0.as_slice())
            .unwrap_or(&[]),
    }
}
