//! Stage cut (SPEC §2.4): removes the detected particles from their bodies, severs the
//! detected edges, and reports both and the cut clusters. Writes particle data only (it
//! reads the particle → clusters index to name the cut clusters).
//!
//! A particle entity despawned from outside (by a game, say) is removed the same way,
//! as if cut: its body's lattice and clusters are rebuilt around the hole, instead of
//! listing a particle that no longer exists.

use crate::components::{Body, BodyLattice, Particle, ParticleClusters, cluster_entity};
use crate::resources::{
    BodyCut, BodyCutReport, BodySplit, CutList, CutReport, EdgesSevered, ParticlesCut,
};
use crate::tear::sever_keeping_pieces;
use bevy_ecs::entity::Entities;
use bevy_ecs::prelude::*;
use std::borrow::Cow;

/// Deletes the particles of the `CutList` and any particle despawned from outside, and
/// severs the `CutList`'s edges.
#[allow(clippy::too_many_arguments)]
pub fn cut(
    mut commands: Commands,
    entities: &Entities,
    list: Res<CutList>,
    mut report: ResMut<CutReport>,
    mut bodies: Query<(Entity, &Body, &mut BodyLattice, &ParticleClusters)>,
    mut despawned: RemovedComponents<Particle>,
    mut despawned_here: Local<Vec<Entity>>,
    mut particles_cut: MessageWriter<ParticlesCut>,
    mut edges_severed: MessageWriter<EdgesSevered>,
    mut body_split: MessageWriter<BodySplit>,
) {
    report.bodies.clear();
    let cuts = with_despawned(&list, &mut despawned, &mut despawned_here, &bodies);
    despawned_here.clear();
    for cut in cuts.iter() {
        let Ok((_, material, mut body, index)) = bodies.get_mut(cut.body) else {
            continue;
        };
        let mut removed = Vec::new();
        let mut cut_clusters = Vec::new();
        for &p in &cut.particles {
            if body.lattice.remove(p) {
                removed.push(p);
                let particle = body.particles[p as usize];
                // (one despawned from outside is gone already)
                if let Ok(mut e) = commands.get_entity(particle) {
                    e.despawn();
                    despawned_here.push(particle);
                }
                cut_clusters.extend_from_slice(index.0.clusters_of(p));
            }
        }
        let severed: Vec<(u32, u32)> = cut
            .edges
            .iter()
            .copied()
            .filter(|&(a, b)| body.lattice.sever(a, b))
            .collect();
        let min_piece = material.material.tear_min_piece as usize;
        let torn = sever_keeping_pieces(&mut body.lattice, &cut.torn, min_piece);
        for &(a, b) in severed.iter().chain(&torn) {
            // only a cluster holding both ends may fall apart
            let of_b = index.0.clusters_of(b);
            cut_clusters.extend(index.0.clusters_of(a).iter().filter(|k| of_b.contains(k)));
        }
        if removed.is_empty() && severed.is_empty() && torn.is_empty() {
            continue;
        }
        cut_clusters.sort_unstable();
        cut_clusters.dedup();
        let cut_clusters = cut_clusters
            .into_iter()
            .map(|k| cluster_entity(entities, k))
            .collect();
        let before = body.pieces;
        body.pieces = body.lattice.piece_count();
        if body.pieces != before {
            body_split.write(BodySplit {
                body: cut.body,
                pieces_before: before,
                pieces_after: body.pieces,
            });
        }
        if !removed.is_empty() {
            particles_cut.write(ParticlesCut {
                body: cut.body,
                particles: removed.clone(),
            });
        }
        if !(severed.is_empty() && torn.is_empty()) {
            edges_severed.write(EdgesSevered {
                body: cut.body,
                edges: severed.clone(),
                torn: torn.clone(),
            });
        }
        report.bodies.push(BodyCutReport {
            body: cut.body,
            removed,
            severed: [severed, torn].concat(),
            cut_clusters,
        });
    }
}

/// The `CutList`'s cuts plus, per body, its live particles whose entities were despawned
/// from outside (not by this stage last time, `despawned_here`), by body entity.
fn with_despawned<'a>(
    list: &'a CutList,
    despawned: &mut RemovedComponents<Particle>,
    despawned_here: &mut [Entity],
    bodies: &Query<(Entity, &Body, &mut BodyLattice, &ParticleClusters)>,
) -> Cow<'a, [BodyCut]> {
    despawned_here.sort_unstable();
    let mut outside: Vec<Entity> = despawned
        .read()
        .filter(|e| despawned_here.binary_search(e).is_err())
        .collect();
    if outside.is_empty() {
        return Cow::Borrowed(&list.cuts);
    }
    outside.sort_unstable();
    let mut cuts = list.cuts.clone();
    for (body, _, lattice, _) in bodies.iter() {
        let lost: Vec<u32> = lattice
            .lattice
            .live_particles()
            .filter(|&p| {
                outside
                    .binary_search(&lattice.particles[p as usize])
                    .is_ok()
            })
            .collect();
        if lost.is_empty() {
            continue;
        }
        match cuts.iter_mut().find(|c| c.body == body) {
            Some(cut) => {
                cut.particles.extend(lost);
                cut.particles.sort_unstable();
                cut.particles.dedup();
            }
            None => cuts.push(BodyCut {
                body,
                particles: lost,
                edges: Vec::new(),
                torn: Vec::new(),
            }),
        }
    }
    cuts.sort_by_key(|c| c.body);
    Cow::Owned(cuts)
}
