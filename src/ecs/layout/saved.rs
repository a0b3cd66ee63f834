//! The layout's saved state: what a loaded simulation needs to find its particles and
//! clusters at the dense indices and slots the saved solver state has them at. The maps
//! back (entity → dense index, entity → slot) are derived again on loading.

use super::{BodyDense, ClusterSlots, PendingTopology, SolverLayout};
use bevy_ecs::prelude::Entity;
use serde::{Deserialize, Serialize};

/// The saved part of a [`SolverLayout`], its entities as the saving world had them.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LayoutState {
    entities: Vec<Entity>,
    locals: Vec<u32>,
    live: Vec<bool>,
    bodies: Vec<BodyDense>,
    clusters: Vec<Entity>,
}

impl SolverLayout {
    /// The state to save (a valid layout's: bring it up to date first).
    pub fn saved_state(&self) -> LayoutState {
        LayoutState {
            entities: self.entities.clone(),
            locals: self.locals.clone(),
            live: self.live.clone(),
            bodies: self.bodies.clone(),
            clusters: self.clusters.clone(),
        }
    }

    /// The layout of a loaded simulation: `saved`, for `particles` dense particles, with
    /// each saved entity mapped to the loaded world's by `map` (a placeholder for one
    /// the save does not hold — a particle cut before the save), which must hold every
    /// body. The loaded entities count as seen by the next update, and every term hears
    /// of the whole layout. The error says what in `saved` does not fit.
    pub fn restore(
        saved: LayoutState,
        particles: usize,
        map: impl Fn(Entity) -> Entity,
    ) -> Result<Self, String> {
        if [saved.entities.len(), saved.locals.len(), saved.live.len()] != [particles; 3] {
            return Err("the solver's particle tables disagree in length".into());
        }
        let entities: Vec<Entity> = saved.entities.iter().map(|e| map(*e)).collect();
        let clusters: Vec<Entity> = saved.clusters.iter().map(|e| map(*e)).collect();
        let mut bodies = saved.bodies;
        for b in &mut bodies {
            let saved_body = b.body;
            b.body = map(saved_body);
            if b.body == Entity::PLACEHOLDER {
                return Err(format!(
                    "the solver layout names entity {saved_body}, which is not saved"
                ));
            }
        }
        let max_index = entities
            .iter()
            .filter(|e| **e != Entity::PLACEHOLDER)
            .map(|e| e.index_u32() as usize + 1)
            .max()
            .unwrap_or(0);
        let mut dense_of = vec![u32::MAX; max_index];
        for (d, e) in entities.iter().enumerate() {
            if *e != Entity::PLACEHOLDER {
                dense_of[e.index_u32() as usize] = d as u32;
            }
        }
        Ok(SolverLayout {
            slot_of: ClusterSlots::from_clusters(&clusters),
            entities,
            locals: saved.locals,
            dense_of,
            live: saved.live,
            bodies,
            clusters,
            valid: true,
            adopt_changes: true,
            stamp: super::fresh_stamp(),
            pending: Some(PendingTopology {
                relaid: true,
                bodies: Vec::new(),
            }),
            ..Default::default()
        })
    }
}
