//! Keeps the terms in step with the ECS, once at the start of each frame (after the
//! layout, in [`crate::systems::SyncSchedule`]): every term hears of a topology change
//! of the layout ([`crate::solver::term::Topology`]); the attachments (each particle
//! held, or only a set's centroid) are taken from their entities when those change,
//! and their targets every frame; contacts follow the `contacts` and `culling` settings. Writes the
//! solver cache only.

use crate::ecs::components::{
    Attachment, AttachmentTarget, AttachmentVelocity, Body, BodyLattice, Hold,
};
use crate::ecs::resources::SimSettings;
use crate::ecs::layout::SolverCache;
use crate::solver::term::{BodyTopology, ParticleKey, Topology};
use crate::solver::terms::attachments::{self, Attachments};
use crate::solver::terms::centroids::Centroids;
use crate::solver::terms::contacts::Contacts;
use bevy_ecs::prelude::*;

/// Attachments as the term takes them.
type AttachmentItem<'a> = (
    Entity,
    &'a Attachment,
    &'a AttachmentTarget,
    Option<&'a AttachmentVelocity>,
);

/// Tells the terms what changed (see the module docs).
pub fn sync_terms(
    settings: Res<SimSettings>,
    mut cache: ResMut<SolverCache>,
    bodies: Query<(&Body, &BodyLattice)>,
    attachments: Query<AttachmentItem>,
    changed: Query<(), Changed<Attachment>>,
    mut removed: RemovedComponents<Attachment>,
) {
    let SolverCache { solver, layout, .. } = &mut *cache;
    let contacts_changed = solver.terms.get_mut::<Contacts>().is_some_and(|c| {
        c.set_culling(settings.0.culling);
        c.set_enabled(settings.0.contacts)
    });
    let attachments_changed = !changed.is_empty() || removed.read().count() > 0;
    let mut list: Vec<AttachmentItem> = attachments.iter().collect();
    list.sort_unstable_by_key(|(e, ..)| *e);
    let (each, centroids): (Vec<AttachmentItem>, Vec<AttachmentItem>) = list
        .into_iter()
        .partition(|(_, a, ..)| a.hold == Hold::Each);
    let pending = layout.take_pending_topology();
    if pending.is_some() || contacts_changed || attachments_changed {
        let pending = pending.unwrap_or_default();
        let views: Vec<BodyTopology> = layout
            .bodies()
            .iter()
            .filter_map(|b| {
                let (body, lattice) = bodies.get(b.body).ok()?;
                Some(BodyTopology {
                    id: b.body.to_bits(),
                    lattice: &lattice.lattice,
                    dense: &b.dense,
                    material: &body.material,
                    groups: &body.groups,
                    pieces: lattice.pieces,
                    changed: pending.relaid || pending.bodies.contains(&b.body),
                })
            })
            .collect();
        let topology = Topology {
            bodies: &views,
            relaid: pending.relaid,
        };
        solver.topology(&topology);
        if attachments_changed && let Some(term) = solver.terms.get_mut::<Attachments>() {
            term.set(each.iter().map(as_term).collect(), &topology);
        }
        if attachments_changed && let Some(term) = solver.terms.get_mut::<Centroids>() {
            term.set(centroids.iter().map(as_term).collect(), &topology);
        }
    }
    if let Some(term) = solver.terms.get_mut::<Attachments>() {
        for (i, (_, _, target, _)) in each.iter().enumerate() {
            term.set_poses(i, target.reached, target.pose);
        }
    }
    if let Some(term) = solver.terms.get_mut::<Centroids>() {
        for (i, (_, _, target, _)) in centroids.iter().enumerate() {
            term.set_poses(i, target.reached, target.pose);
        }
    }
}

/// An attachment entity as its term (attachments or centroid holds) takes it.
fn as_term((_, a, target, velocity): &AttachmentItem) -> attachments::Attachment {
    attachments::Attachment {
        particles: a
            .particles
            .iter()
            .map(|&local| ParticleKey {
                body: a.body.to_bits(),
                local,
            })
            .collect(),
        offsets: a.offsets.clone(),
        compliance: a.compliance,
        from: target.reached,
        to: target.pose,
        velocity: velocity.map(|v| v.0),
    }
}
