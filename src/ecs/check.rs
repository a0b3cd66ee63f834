//! The invariants of every body in a world: its clusters' ([`crate::clusters::invariants`]),
//! its particle → clusters index, finite positions.

use crate::clusters::invariants::{Violation, check_body, check_index};
use crate::config::Model;
use crate::ecs::components::*;
use bevy_ecs::prelude::*;

/// Checks the invariants ([`crate::clusters::invariants`]) of every body in `world`, that each body's particle →
/// clusters index matches its clusters' members, and that every live particle has a
/// finite position; returns `(body, violation)`.
pub fn check_invariants(world: &World) -> Vec<(Entity, Violation)> {
    let Some(mut bodies) =
        world.try_query::<(Entity, &Body, &BodyLattice, Option<&ParticleClusters>)>()
    else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (e, body, lattice, clusters) in bodies.iter(world) {
        // each body's clusters by key, as its key table names them
        let mut listed: Vec<(u32, &[u32])> = Vec::new();
        if let Some(clusters) = clusters {
            for (k, entity) in clusters.keys.iter() {
                let of_body = world
                    .get::<ClusterOf>(entity)
                    .is_some_and(|of| of.body == e);
                match world.get::<ClusterMembers>(entity) {
                    Some(m) if of_body => listed.push((k, m.0.as_slice())),
                    _ => out.push((e, Violation::MissingCluster { cluster: k as u64 })),
                }
            }
            let violations = check_index(listed.iter().copied(), clusters.index.iter());
            out.extend(violations.into_iter().map(|v| (e, v)));
        }
        if body.material.model == Model::Oriented {
            // its groups are derived from the lattice; it holds no clusters
            out.extend(listed.iter().map(|(k, _)| {
                let cluster = *k as u64;
                (e, Violation::ClusterOfOrientedBody { cluster })
            }));
        } else {
            for v in check_body(
                &lattice.lattice,
                listed.iter().map(|(k, m)| (*k as u64, *m)),
                body.material.max_cluster_size as usize,
            ) {
                out.push((e, v));
            }
        }
        for i in lattice.lattice.live_particles() {
            let position = world.get::<Position>(lattice.particles[i as usize]);
            if !position.is_some_and(|p| p.0.is_finite()) {
                out.push((e, Violation::NonFinite { particle: i }));
            }
        }
    }
    out
}
