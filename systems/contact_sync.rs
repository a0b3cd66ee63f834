//! Keeps the contact kind's particles in step with the bodies: after every change of the
//! solver layout (a new body, a cut), the surface particles of every body, each labelled
//! with its piece, in the layout's dense order.

use crate::body::pieces::body_pieces;
use crate::ecs::components::{Body, BodyLattice};
use crate::ecs::resources::SolverCache;
use crate::solver::{ContactGroup, ContactParticles};
use bevy_ecs::prelude::*;

/// Rebuilds the contact particles and groups from `bodies` and the cache's dense map
/// (every group is one piece of one body); with `enabled` false, there are none.
pub fn sync_contacts(
    cache: &mut SolverCache,
    bodies: &Query<(Entity, &BodyLattice)>,
    materials: &Query<&Body>,
    enabled: bool,
) {
    let mut particles = ContactParticles::default();
    let mut groups = Vec::new();
    if enabled {
        for entry in &cache.body_dense {
            let (Ok((_, body)), Ok(material)) = (bodies.get(entry.body), materials.get(entry.body))
            else {
                continue;
            };
            let (lattice, material) = (&body.lattice, &material.material);
            let radius = material.contact_radius.unwrap_or(0.5 * lattice.spacing());
            let group = ContactGroup {
                self_contact: material.self_contact,
                static_friction: material.static_friction,
                dynamic_friction: material.dynamic_friction,
            };
            let first_group = groups.len() as u32;
            // labels only where the body is in more than one piece
            let labels = (body.pieces > 1).then(|| body_pieces(lattice));
            let pieces = labels.as_ref().map_or(1, |(_, n)| *n).max(1);
            groups.extend(std::iter::repeat_n(group, pieces));
            let mut taking_part: Vec<(u32, u32)> = lattice
                .live_particles()
                .filter(|i| lattice.is_surface(*i))
                .filter_map(|i| {
                    let d = *entry.dense.get(i as usize)?;
                    (d != u32::MAX && cache.live[d as usize]).then_some((d, i))
                })
                .collect();
            taking_part.sort_unstable();
            for (d, i) in taking_part {
                let piece = labels.as_ref().map_or(0, |(l, _)| l[i as usize]);
                particles.push(d, first_group + piece, lattice.coord(i), radius);
            }
        }
    }
    cache.kinds.contacts.set(particles, groups);
    cache.contacts_built = Some(enabled);
}
