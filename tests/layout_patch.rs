//! After every cut the shape-match stage patches its dense layout instead of rebuilding
//! it. The patched layout must hold exactly what a full rebuild would: the same clusters
//! with the same members, rest offsets and weights; cut particles frozen.

use bevy_ecs::prelude::*;
use cleave::ecs::layout::{BodyItem, ClusterItem, SolverCache};
use cleave::ecs::resources::CutReport;
use cleave::io::scene::builtin;
use cleave::prelude::*;
use glam::Vec4;
use std::collections::BTreeMap;

/// Per cluster entity: `(body-local particle, rest offset and weight)` sorted by particle.
type Clusters = BTreeMap<Entity, Vec<(u32, Vec4)>>;

fn clusters_of(cache: &SolverCache) -> Clusters {
    cache
        .solver
        .clusters
        .clusters()
        .map(|(k, members)| {
            let mut list: Vec<(u32, Vec4)> = members
                .iter()
                .zip(cache.solver.clusters.member_moments(k))
                .map(|(d, q)| (cache.layout.locals()[*d as usize], q))
                .collect();
            list.sort_by_key(|(p, _)| *p);
            (cache.layout.cluster_entities()[k], list)
        })
        .collect()
}

fn fresh_rebuild(world: &mut World, mode: SolverMode) -> SolverCache {
    let mut bodies = world.query::<BodyItem>();
    let mut clusters = world.query::<ClusterItem>();
    SolverCache::laid_out(bodies.iter(world), clusters.iter(world), mode)
}

fn check_scene(name: &str, mode: SolverMode) -> usize {
    let scene = builtin(name, 7).unwrap();
    let mut config = scene.config.clone();
    config.solver = mode;
    let mut sim = Simulation::new(config).unwrap();
    for body in &scene.bodies {
        sim.spawn_body(body).unwrap();
    }
    for tool in &scene.tools {
        sim.spawn_tool(tool).unwrap();
    }
    let mut patches = 0;
    for _ in 0..scene.frames.min(240) {
        sim.world_mut()
            .resource_mut::<SolverCache>()
            .layout
            .forget_last_update();
        sim.step();
        let world = sim.world_mut();
        let Some(update) = world.resource::<SolverCache>().layout.last_update() else {
            continue;
        };
        // the layout is patched in the first substep after a cut; compare it when this
        // frame's own cut stage changed nothing after it
        if !update.patched || !world.resource::<CutReport>().bodies.is_empty() {
            continue;
        }
        patches += 1;
        let fresh = fresh_rebuild(world, mode);
        let cache = world.resource::<SolverCache>();
        let (patched, rebuilt) = (clusters_of(cache), clusters_of(&fresh));
        assert_eq!(
            patched.keys().collect::<Vec<_>>(),
            rebuilt.keys().collect::<Vec<_>>(),
            "{name}: same cluster entities"
        );
        for (e, members) in &patched {
            let other = &rebuilt[e];
            assert_eq!(members.len(), other.len(), "{name}: members of {e}");
            for ((p, q), (r, s)) in members.iter().zip(other) {
                assert_eq!(p, r, "{name}: members of {e}");
                assert!(
                    (*q - *s).length() < 1e-5,
                    "{name} {e} particle {p}: {q} vs {s}"
                );
            }
        }
        // every particle a cut removed is frozen and hidden from detection
        for d in 0..cache.layout.len() {
            let (body, local) = cache.layout.owner(d).unwrap();
            let lattice = &world.get::<BodyLattice>(body).unwrap().lattice;
            assert_eq!(cache.layout.live()[d], lattice.is_live(local));
            if !cache.layout.live()[d] {
                assert_eq!(cache.particles.inv_mass[d], 0.0);
            }
        }
    }
    patches
}

#[test]
fn patched_layouts_match_full_rebuilds_jacobi() {
    assert!(check_scene("dice", SolverMode::Jacobi) > 0);
    assert!(check_scene("random", SolverMode::Jacobi) > 0);
}

#[test]
fn patched_layouts_match_full_rebuilds_projective() {
    assert!(check_scene("random", SolverMode::Projective) > 0);
}

#[test]
fn patched_layouts_match_full_rebuilds_gauss_seidel() {
    assert!(check_scene("random", SolverMode::GaussSeidel) > 0);
}

/// Particles removed from a lattice without a cut report (or beyond what the report
/// lists) are found by looking at the whole body: the report is only a hint.
#[test]
fn particles_lost_outside_a_cut_report_are_still_frozen() {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let body = sim
        .spawn_body(&BodyDesc::new(
            Shape::cuboid(glam::UVec3::new(6, 4, 4)),
            0.1,
        ))
        .unwrap();
    sim.step();
    for (round, reported) in [(0u32, false), (1, true)] {
        let world = sim.world_mut();
        let mut lattice = world.get_mut::<BodyLattice>(body).unwrap();
        let (a, b) = (10 + 2 * round, 11 + 2 * round);
        assert!(lattice.lattice.remove(a) && lattice.lattice.remove(b));
        // the second round's report names one of the two
        world.resource_mut::<CutReport>().bodies = if reported {
            vec![cleave::ecs::resources::BodyCutReport {
                body,
                removed: vec![a],
                severed: Vec::new(),
                splits: Vec::new(),
                relinked: Vec::new(),
                cut_clusters: Vec::new(),
            }]
        } else {
            Vec::new()
        };
        world
            .resource_mut::<SolverCache>()
            .layout
            .forget_last_update();
        sim.step();
        let world = sim.world();
        let cache = world.resource::<SolverCache>();
        assert!(cache.layout.last_update().is_some_and(|u| u.patched));
        let lattice = &world.get::<BodyLattice>(body).unwrap().lattice;
        for (d, local) in cache.layout.locals().iter().enumerate() {
            assert_eq!(
                cache.layout.live()[d],
                lattice.is_live(*local),
                "round {round}, particle {local}"
            );
        }
    }
}
