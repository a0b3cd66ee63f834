//! A full slice cut event (regroup + split + expand + edge-cover repair) on 32³ and 64³
//! bodies, against re-clustering the cut body from scratch with the initial clustering.

use cleave::body::lattice::Lattice;
use cleave::body::shape::Shape;
use cleave::clusters::clustering::initial_clusters;
use cleave::clusters::store::{ClusterStore, ClusterTable};
use cleave::config::Material;
use cleave::reconstruct::rebuild_after_cut;
use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use glam::UVec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// A body and its clusters before the cut, the slab of particles to cut, and the cut lattice.
fn prepared(n: u32) -> (Lattice, ClusterTable, Vec<u32>, Lattice) {
    let lattice = Shape::cuboid(UVec3::splat(n)).voxelise(1.0).unwrap();
    let table = initial_clusters(
        &lattice,
        &Material::default(),
        &mut ChaCha8Rng::seed_from_u64(1),
    );
    let slab: Vec<u32> = lattice
        .live_particles()
        .filter(|i| matches!(lattice.coord(*i).x, -1 | 0))
        .collect();
    let mut cut = lattice.clone();
    for p in &slab {
        cut.remove(*p);
    }
    (lattice, table, slab, cut)
}

fn cut_event(lattice: &Lattice, table: &mut ClusterTable, slab: &[u32], material: &Material) {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let mut cut_clusters: Vec<u32> = slab
        .iter()
        .flat_map(|p| table.clusters_of(*p).to_vec())
        .collect();
    cut_clusters.sort_unstable();
    cut_clusters.dedup();
    rebuild_after_cut(table, lattice, &cut_clusters, material, &mut rng);
}

fn cut(c: &mut Criterion) {
    let material = Material::default();
    let mut group = c.benchmark_group("cut");
    group.sample_size(10);
    for n in [32u32, 64] {
        let (_, table, slab, cut) = prepared(n);
        group.bench_function(format!("slice_event/{n}^3"), |b| {
            b.iter_batched(
                || table.clone(),
                |mut t| {
                    cut_event(&cut, &mut t, &slab, &material);
                    t // dropped outside the timing
                },
                BatchSize::LargeInput,
            )
        });
        group.bench_function(format!("recluster/{n}^3"), |b| {
            b.iter(|| initial_clusters(&cut, &material, &mut ChaCha8Rng::seed_from_u64(1)))
        });
    }
    group.finish();
}

criterion_group!(benches, cut);
criterion_main!(benches);
