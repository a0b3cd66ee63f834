//! `cleave bench --model oriented`: an n³ box of each model stepped in the same run —
//! the cluster model's box and the same box of oriented particles (rigid material, the
//! bench's settings) — with each model's elastic part timed on its own: the clusters'
//! passes and the oriented groups' sweeps, per membership and iteration.

use super::bench::{kind_seconds, median, time_ms};
use crate::body::shape::Shape;
use crate::config::{Material, Model, SimConfig};
use crate::ecs::desc::BodyDesc;
use crate::ecs::layout::SolverCache;
use crate::error::Result;
use crate::sim::simulation::Simulation;
use glam::{UVec3, Vec3};
use serde::Serialize;

/// Lattice spacing of the boxes (metres).
const H: f32 = 0.05;

/// One model's box.
#[derive(Clone, Debug, Serialize)]
pub struct ModelRow {
    /// `"clusters"` or `"oriented"`.
    pub model: Model,
    /// Memberships: the sum of the clusters' or the groups' sizes.
    pub memberships: usize,
    /// Median wall time of one engine step, ms.
    pub ms_per_step: f64,
    /// Median time the model's elastic part (the clusters' passes, or the groups'
    /// sweeps) took in a step, ms.
    pub elastic_ms_per_step: f64,
    /// `elastic_ms_per_step / (memberships × iterations)`, ns.
    pub ns_per_membership_iteration: f64,
}

/// The row of one size: both models.
#[derive(Clone, Debug, Serialize)]
pub struct OrientedRow {
    /// Always `"models"`.
    pub row: &'static str,
    /// Edge length of the box in particles.
    pub size: u32,
    /// Particles.
    pub particles: usize,
    /// Solver iterations per step (substeps × iterations).
    pub iterations: u32,
    /// The cluster model's box.
    pub clusters: ModelRow,
    /// The oriented model's box.
    pub oriented: ModelRow,
    /// The oriented groups' ns per membership-iteration over the clusters'.
    pub oriented_over_clusters: f64,
}

/// Steps an n³ box of each model `steps` times after three warm-up steps (the two
/// alternating, so that both see the same machine noise).
pub fn bench_models(n: u32, steps: usize, config: &SimConfig) -> Result<OrientedRow> {
    let spawn = |model: Model| -> Result<Simulation> {
        let mut sim = Simulation::new(config.clone())?;
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(n)), H);
        desc.material = Material {
            model,
            ..Material::rigid()
        };
        desc.position = Vec3::new(0.0, n as f32 * H * 0.5 + 0.05, 0.0);
        sim.spawn_body(&desc)?;
        sim.drop_surfaces();
        for _ in 0..3 {
            sim.step();
        }
        Ok(sim)
    };
    let mut sims = [spawn(Model::Clusters)?, spawn(Model::Oriented)?];
    let parts = ["clusters", "oriented"];
    // per step: the whole step and its elastic part, both as medians (a mean lets one
    // step disturbed by the machine outweigh the rest)
    let (mut steps_ms, mut elastic_ms) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    for _ in 0..steps.max(1) {
        for (k, sim) in sims.iter_mut().enumerate() {
            let before = kind_seconds(sim, parts[k]);
            steps_ms[k].push(time_ms(1, || sim.step()));
            elastic_ms[k].push((kind_seconds(sim, parts[k]) - before) * 1e3);
        }
    }
    let iterations = config.substeps * config.iterations;
    let mut rows = sims
        .iter()
        .zip(&mut steps_ms)
        .zip(&mut elastic_ms)
        .zip([Model::Clusters, Model::Oriented])
        .map(|(((sim, steps_ms), elastic_ms), model)| {
            let cache = sim.world().resource::<SolverCache>();
            let memberships = match model {
                Model::Clusters => cache.solver.clusters.membership_count(),
                Model::Oriented => cache
                    .solver
                    .terms
                    .extent("oriented")
                    .map_or(0, |e| e.constraints),
            };
            let elastic_ms_per_step = median(elastic_ms);
            ModelRow {
                model,
                memberships,
                ms_per_step: median(steps_ms),
                elastic_ms_per_step,
                ns_per_membership_iteration: elastic_ms_per_step * 1e6
                    / (memberships.max(1) as f64 * iterations as f64),
            }
        });
    let (clusters, oriented) = (
        rows.next().expect("two models"),
        rows.next().expect("two models"),
    );
    let particles = sims[0].world().resource::<SolverCache>().particles.len();
    Ok(OrientedRow {
        row: "models",
        size: n,
        particles,
        iterations,
        oriented_over_clusters: oriented.ns_per_membership_iteration
            / clusters.ns_per_membership_iteration,
        clusters,
        oriented,
    })
}
