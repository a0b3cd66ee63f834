//! The Jacobi scheme: fit every cluster to the same positions (parallel over clusters),
//! then move every particle by the average of its clusters' pulls (parallel over
//! particles) and apply the colliders.

use super::{
    CLUSTERS_PER_TASK, ClusterFrame, Colliders, PARTICLES_PER_TASK, SolverLayout, fit_cluster,
    resolve_colliders,
};
use glam::Vec3A;
use rayon::prelude::*;

impl SolverLayout {
    /// Cluster pass: one frame per cluster from the current positions.
    pub(super) fn fit_all_clusters(&mut self) {
        let mut frames = std::mem::take(&mut self.frames);
        let mut rotations = std::mem::take(&mut self.rotations);
        let this = &*self;
        frames
            .par_chunks_mut(CLUSTERS_PER_TASK)
            .zip(rotations.par_chunks_mut(CLUSTERS_PER_TASK))
            .enumerate()
            .for_each(|(task, (frames, rotations))| {
                let first = task * CLUSTERS_PER_TASK;
                for (i, (frame, rotation)) in frames.iter_mut().zip(rotations).enumerate() {
                    let k = first + i;
                    let range = this.cluster_start[k] as usize..this.cluster_start[k + 1] as usize;
                    *frame = fit_cluster(
                        &this.member_particle[range.clone()],
                        &this.member_moment[range],
                        |m| this.positions[m],
                        this.constants(k),
                        rotation,
                    );
                }
            });
        self.frames = frames;
        self.rotations = rotations;
    }

    /// Particle pass: `pᵢ += (1/nᵢ) Σₖ sₖ (gᵢₖ − pᵢ)`, then the colliders.
    pub(super) fn move_particles_jacobi(&mut self, colliders: &Colliders) {
        let frames: &[ClusterFrame] = &self.frames;
        let (starts, clusters, inv_count, stiffness_sum, inv_mass, previous, rest) = (
            &self.particle_start,
            &self.particle_clusters,
            &self.inv_count,
            &self.stiffness_sum,
            &self.inv_mass,
            &self.previous,
            &self.rest,
        );
        let collide = colliders.ground.is_some() || !colliders.boxes.is_empty();
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, (chunk, corrections))| {
                let base = task * PARTICLES_PER_TASK;
                for (j, (p, correction)) in chunk.iter_mut().zip(corrections).enumerate() {
                    let i = base + j;
                    if inv_mass[i] == 0.0 {
                        continue;
                    }
                    let (x, r) = (*p, rest[i]);
                    let mut goals = Vec3A::ZERO;
                    for &k in &clusters[starts[i] as usize..starts[i + 1] as usize] {
                        goals += frames[k as usize].scaled_goal(r);
                    }
                    let step = (goals - x * stiffness_sum[i]) * inv_count[i];
                    *p = x + step;
                    *correction += step;
                    if collide {
                        let unconstrained = *p;
                        resolve_colliders(p, previous[i], colliders);
                        *correction += *p - unconstrained;
                    }
                }
            });
    }
}
