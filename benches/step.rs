//! Step time of boxes of 16³, 32³ and 48³ particles (gravity, ground, 2 substeps × 10
//! iterations). Prints memberships so ns per membership-iteration can be derived:
//! `time / (memberships × substeps × iterations)`.
//!
//! Beside it, the frame-end angular velocities of the 16³ box's particles (all in
//! clusters) on one thread: the eight-lane logarithm the step runs (with the linear
//! velocities' update), against libm's turn per particle.

use cleave::ecs::layout::SolverCache;
use cleave::math::log_map::turn;
use cleave::prelude::*;
use criterion::{Criterion, criterion_group, criterion_main};
use glam::{UVec3, Vec3, Vec3A};

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

fn frame_end_spins(c: &mut Criterion) {
    let mut group = c.benchmark_group("frame_end_spins");
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    // (the engine bench's body: rigid clusters, which the Jacobi cluster term holds)
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(16)), 0.05);
    desc.material = Material::rigid();
    desc.position = Vec3::new(0.0, 0.5, 0.0);
    sim.spawn_body(&desc).unwrap();
    for _ in 0..20 {
        sim.step();
    }
    let cache = sim.world_mut().resource_mut::<SolverCache>();
    let SolverCache {
        particles, solver, ..
    } = cache.into_inner();
    let counts = solver.clusters.member_counts().to_vec();
    let inv_dt = 120.0;
    // (this thread made the one thread of a pool, as the step runs them: from outside a
    // pool each call would first hand its passes over)
    let _pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build()
        .unwrap();
    group.bench_function("16^3/lanes", |b| {
        b.iter(|| particles.update_velocities(inv_dt, &counts, true))
    });
    group.bench_function("16^3/libm", |b| {
        b.iter(|| {
            let turns = particles
                .previous_orientations
                .iter()
                .zip(&particles.orientations);
            for (w, (from, to)) in particles.spins.iter_mut().zip(turns) {
                *w = Vec3A::from(turn(*from, *to)) * inv_dt;
            }
        })
    });
    group.finish();
}

criterion_group!(benches, step, frame_end_spins);
criterion_main!(benches);
