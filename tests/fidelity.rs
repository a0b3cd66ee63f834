//! The reconstruction keeps a cut body's clusters what a fresh clustering of the same
//! geometry makes (SPEC §3's goal: the number and size of clusters, and with them the
//! body's stiffness, stay what they were), checked against that fresh clustering: on the
//! engine's seeded block of 50 random cuts, on a scooped cantilever's static sag, and on
//! cuts made here on plain data; and `recluster` gives that reference.

use cleave::analysis::cluster_shape::ClusterShape;
use cleave::analysis::fidelity::{FidelityOptions, fidelity};
use cleave::body::lattice::Lattice;
use cleave::body::shape::Shape;
use cleave::clusters::clustering::{clusters_on_grid, seed_grid_offset};
use cleave::clusters::store::{ClusterStore, ClusterTable};
use cleave::config::Material;
use cleave::prelude::*;
use cleave::reconstruct::rebuild_after_cut;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn fifty_random_cuts_keep_the_clusters_a_fresh_clustering_makes() {
    for (seed, cut_mode) in [
        (0, CutMode::Remove),
        (1, CutMode::Remove),
        (2, CutMode::Remove),
        (3, CutMode::Sever),
    ] {
        let report = fidelity(FidelityOptions {
            seed,
            cut_mode,
            scoops: 0,
            ..FidelityOptions::default()
        })
        .unwrap();
        let block = &report.block;
        assert_eq!(block.violations, 0, "seed {seed}");
        assert!(
            block.pieces > 1,
            "seed {seed}: the through-blades part the block"
        );
        if cut_mode == CutMode::Remove {
            assert!(
                block.particles < 6500,
                "seed {seed}: {} left",
                block.particles
            );
        }
        assert!(
            block.ratio.worst() <= 0.10,
            "seed {seed} {cut_mode}: {:?}\nrebuilt {:?}\nfresh {:?}",
            block.ratio,
            block.rebuilt,
            block.fresh
        );
    }
}

#[test]
fn split_cuts_leave_the_pieces_sever_cuts_leave_and_keep_the_clusters() {
    // the same 50 blades and scoops in `split` and in `sever` mode: a split separates
    // exactly the edges a sever does, so the pieces are sever's plus the slivers of
    // cells between two passes less than a cell apart (split once shattered this block
    // into 3,672 pieces, against sever's 54); and the clusters grown again around each
    // split are what a fresh clustering makes (the pieces of the cut clusters were 19 %
    // more numerous and 11 % smaller)
    let block = |cut_mode| {
        fidelity(FidelityOptions {
            seed: 1,
            cut_mode,
            scoops: 0,
            ..FidelityOptions::default()
        })
        .unwrap()
        .block
    };
    let (split, sever) = (block(CutMode::Split), block(CutMode::Sever));
    assert_eq!(split.violations, 0);
    assert!(
        split.particles > sever.particles,
        "split halves add particles"
    );
    assert!(
        split.pieces <= 2 * sever.pieces,
        "split {} pieces, sever {}",
        split.pieces,
        sever.pieces
    );
    let ratio = split.ratio;
    assert!(
        ratio.worst() <= 0.10 && (ratio.clusters - 1.0).abs() <= 0.10,
        "{ratio:?}\nrebuilt {:?}\nfresh {:?}",
        split.rebuilt,
        split.fresh
    );
}

#[test]
fn a_scooped_cantilever_sags_like_the_same_holes_built_fresh() {
    for seed in 0..3 {
        let c = fidelity(FidelityOptions {
            seed,
            cuts: 1,
            ..FidelityOptions::default()
        })
        .unwrap()
        .cantilever;
        assert!(
            c.particles < 24 * 6 * 6 - 60,
            "seed {seed}: {} left",
            c.particles
        );
        assert!((c.ratio - 1.0).abs() <= 0.10, "seed {seed}: {c:?}");
        // holes soften a beam
        assert!(c.rebuilt_sag_h > c.intact_sag_h, "seed {seed}: {c:?}");
    }
}

/// A random cut on plain data, in lattice units of a `cells` block: a slab one cell
/// thick through the block (`kind` 0) or 2–8 cells into it (1), or a ball of radius
/// 1.5–3 centred on a face (2); every cut enters a random face along its normal.
fn random_cut(rng: &mut impl Rng, lattice: &Lattice, half: glam::Vec3, kind: u32) -> Vec<u32> {
    let axis = rng.random_range(0..3);
    let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let mut inward = Vec3::ZERO;
    inward[axis] = -sign;
    let mut entry = Vec3::new(
        rng.random_range(-0.9..0.9),
        rng.random_range(-0.9..0.9),
        rng.random_range(-0.9..0.9),
    ) * half;
    entry[axis] = sign * half[axis];
    let t = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let normal = (t - inward * inward.dot(t)).normalize_or(inward.any_orthonormal_vector());
    let (depth, radius) = (rng.random_range(2.0..8.0), rng.random_range(1.5..3.0));
    lattice
        .live_particles()
        .filter(|&p| {
            let x = lattice.rest_position(p) - entry;
            match kind {
                0 => normal.dot(x).abs() <= 0.5,
                1 => normal.dot(x).abs() <= 0.5 && inward.dot(x) <= depth,
                _ => x.length() <= radius,
            }
        })
        .collect()
}

#[test]
fn cuts_on_plain_data_keep_the_clusters_a_fresh_clustering_makes() {
    let material = Material::default();
    for seed in 0..4 {
        let cells = UVec3::new(32, 16, 16);
        let mut lattice = Shape::cuboid(cells).voxelise(1.0).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let grid = seed_grid_offset(&material, &mut rng);
        let mut table = clusters_on_grid(&lattice, &material, grid);
        for i in 0..50 {
            let kind = if i % 10 == 0 { 0 } else { 1 + i % 2 };
            let chosen = random_cut(&mut rng, &lattice, cells.as_vec3() * 0.5, kind);
            let mut cut = Vec::new();
            for &p in &chosen {
                cut.extend_from_slice(table.clusters_of(p));
                lattice.remove(p);
            }
            cut.sort_unstable();
            cut.dedup();
            rebuild_after_cut(&mut table, &lattice, &cut, &material, &mut rng);
        }
        assert!(lattice.live_count() < 7000 && lattice.piece_count() > 1);
        let fresh = clusters_on_grid(&lattice, &material, grid);
        let shape = |t: &ClusterTable| ClusterShape::of(&lattice, t.iter().map(|(_, m)| m));
        let ratio = shape(&table).ratios_to(&shape(&fresh));
        assert!(ratio.worst() <= 0.10, "seed {seed}: {ratio:?}");
    }
}

#[test]
fn recluster_gives_the_initial_clustering_of_the_current_geometry() {
    let mut scene = cleave::io::scene::builtin("cuts", 4).unwrap();
    scene.tools.truncate(6);
    let mut sim = Simulation::new(scene.config.clone()).unwrap();
    let body = sim.spawn_body(&scene.bodies[0]).unwrap();
    let sorted = |sim: &mut Simulation| {
        let mut lists: Vec<Vec<u32>> = sim
            .clusters(body)
            .unwrap()
            .into_iter()
            .map(|(_, m)| m)
            .collect();
        lists.sort();
        lists
    };
    // an uncut body is already clustered as it would be afresh
    let spawned = sorted(&mut sim);
    sim.recluster(body).unwrap();
    assert_eq!(sorted(&mut sim), spawned);
    for tool in &scene.tools {
        sim.spawn_tool(tool).unwrap();
    }
    sim.run(45);
    let cut = sorted(&mut sim);
    let (lattice, material, grid) = {
        let world = sim.world();
        let b = world.get::<Body>(body).unwrap();
        (
            world.get::<BodyLattice>(body).unwrap().lattice.clone(),
            b.material.clone(),
            b.seed_grid,
        )
    };
    assert!(lattice.live_count() < 8192);
    let mut expected: Vec<Vec<u32>> = clusters_on_grid(&lattice, &material, grid).into_clusters();
    expected.sort();
    assert_ne!(
        cut, expected,
        "six cuts leave some rebuilt cluster unlike a fresh one"
    );
    let entities = sim.recluster(body).unwrap();
    assert_eq!(entities.len(), expected.len());
    assert_eq!(sorted(&mut sim), expected);
    assert!(check_invariants(sim.world()).is_empty());
    // the body goes on as before: at rest, and legal after more cuts
    let before = sim.positions(body).unwrap();
    sim.run(10);
    let after = sim.positions(body).unwrap();
    let moved = before
        .iter()
        .zip(&after)
        .map(|((_, a), (_, b))| a.distance(*b))
        .fold(0.0f32, f32::max);
    assert!(moved < 1e-3, "moved {moved} m");
    assert!(check_invariants(sim.world()).is_empty());
    let tool = sim.world_mut().spawn_empty().id();
    assert!(
        sim.recluster(tool)
            .unwrap_err()
            .to_string()
            .contains("is not a body")
    );
}
