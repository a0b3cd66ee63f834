//! Stage cut (SPEC §2.4): removes the detected particles from their bodies and reports
//! the removed particles and the cut clusters. Writes particle data only (it reads the
//! particle → clusters index to name the cut clusters).

use crate::components::{BodyLattice, ParticleClusters, cluster_entity};
use crate::resources::{BodyCutReport, BodySplit, CutList, CutReport, ParticlesCut};
use bevy_ecs::entity::Entities;
use bevy_ecs::prelude::*;

/// Deletes the particles of the `CutList`.
pub fn cut(
    mut commands: Commands,
    entities: &Entities,
    list: Res<CutList>,
    mut report: ResMut<CutReport>,
    mut bodies: Query<(&mut BodyLattice, &ParticleClusters)>,
    mut particles_cut: MessageWriter<ParticlesCut>,
    mut body_split: MessageWriter<BodySplit>,
) {
    report.bodies.clear();
    for cut in &list.cuts {
        let Ok((mut body, index)) = bodies.get_mut(cut.body) else {
            continue;
        };
        let mut removed = Vec::new();
        let mut cut_clusters = Vec::new();
        for &p in &cut.particles {
            if body.lattice.remove(p) {
                removed.push(p);
                commands.entity(body.particles[p as usize]).despawn();
                cut_clusters.extend_from_slice(index.0.clusters_of(p));
            }
        }
        if removed.is_empty() {
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
        particles_cut.write(ParticlesCut {
            body: cut.body,
            particles: removed.clone(),
        });
        report.bodies.push(BodyCutReport {
            body: cut.body,
            removed,
            cut_clusters,
        });
    }
}
