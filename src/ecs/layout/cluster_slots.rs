//! The layout slot of each cluster entity, as a table by entity index.

use bevy_ecs::prelude::Entity;

/// The layout slot of each cluster entity, as a table by entity index: a lookup is two
/// array reads where a hash map costs a hash and a probe (the layout patch looks up every
/// cluster of every particle a cut touched). A slot is only reported for the entity that
/// holds it, checked against the layout's entity per slot, so an index reused by another
/// entity never finds a stale slot.
#[derive(Clone, Debug, Default)]
pub struct ClusterSlots {
    by_index: Vec<u32>,
}

impl ClusterSlots {
    /// The table of `clusters` (the entity per slot; placeholders are skipped).
    pub fn from_clusters(clusters: &[Entity]) -> Self {
        let mut slots = Self::default();
        for (k, e) in clusters.iter().enumerate() {
            if *e != Entity::PLACEHOLDER {
                slots.insert(*e, k as u32);
            }
        }
        slots
    }

    /// The slot of `e`, given the entity per slot.
    #[inline]
    pub fn get(&self, e: Entity, clusters: &[Entity]) -> Option<u32> {
        let slot = *self.by_index.get(e.index_u32() as usize)?;
        (clusters.get(slot as usize) == Some(&e)).then_some(slot)
    }

    /// Records that `e` holds `slot` (the caller records `e` as the entity of `slot`).
    pub fn insert(&mut self, e: Entity, slot: u32) {
        let i = e.index_u32() as usize;
        if self.by_index.len() <= i {
            self.by_index.resize(i + 1, u32::MAX);
        }
        self.by_index[i] = slot;
    }

    /// Forgets the slot of `e` and returns it, given the entity per slot.
    pub fn remove(&mut self, e: Entity, clusters: &[Entity]) -> Option<u32> {
        let slot = self.get(e, clusters)?;
        self.by_index[e.index_u32() as usize] = u32::MAX;
        Some(slot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy_ecs::world::World;

    #[test]
    fn cluster_slots_never_report_a_slot_to_a_reused_entity_index() {
        let mut world = World::new();
        let (a, b) = (world.spawn_empty().id(), world.spawn_empty().id());
        let mut clusters = vec![a, Entity::PLACEHOLDER, b];
        let mut slots = ClusterSlots::from_clusters(&clusters);
        assert_eq!(slots.get(a, &clusters), Some(0));
        assert_eq!(slots.get(b, &clusters), Some(2));
        // `a` despawned without its slot being freed: a later entity on its index (a new
        // generation) is not `a`
        let c = Entity::from_index_and_generation(a.index(), a.generation().after_versions(1));
        assert_eq!(slots.get(c, &clusters), None);
        // moved to slot 1; removing it forgets it, and only it
        clusters[1] = c;
        slots.insert(c, 1);
        assert_eq!(slots.get(c, &clusters), Some(1));
        assert_eq!(slots.remove(c, &clusters), Some(1));
        assert_eq!(slots.get(c, &clusters), None);
        assert_eq!(slots.remove(a, &clusters), None);
        assert_eq!(slots.get(b, &clusters), Some(2));
    }
}
