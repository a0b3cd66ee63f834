//! Step time of boxes of 16³, 32³ and 48³ particles (gravity, ground, 2 substeps × 10
//! iterations). Prints memberships so ns per membership-iteration can be derived:
//! `time / (memberships × substeps × iterations)`.

use cleave::prelude::*;
use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3};

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("step");
    group.sample_size(10);
    for n in [16u32, 32, 48] {
        let config = SimConfig::default();
        let mut sim = Simulation::new(config.clone()).unwrap();
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(n)), 0.1);
        desc.position = Vec3::new(0.0, n as f32 * 0.05 + 0.2, 0.0);
        sim.spawn_body(&desc).unwrap();
        sim.step();
        let memberships: usize = sim
            .world_mut()
            .query::<&ClusterMembers>()
            .iter(sim.world())
            .map(|m| m.0.len())
            .sum();
        let per_step = memberships as u64 * (config.substeps * config.iterations) as u64;
        eprintln!(
            "step/{n}: {} particles, {memberships} memberships, {per_step} membership-iterations per step",
            n * n * n
        );
        group.bench_function(format!("{n}^3"), |b| b.iter(|| sim.step()));
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
