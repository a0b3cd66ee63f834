//! The access contract of every stage, read from the systems' own access sets: predict
//! and shape-match (with its contacts and colliders) write particle data only; the
//! collider mover writes collider poses only; detect writes only its CutList and spawns
//! nothing; cut writes no cluster data; regroup/split/expand write no particle data.

use bevy_ecs::component::ComponentId;
use bevy_ecs::prelude::*;
use bevy_ecs::system::{IntoSystem, System};
use cleave::config::SimConfig;
use cleave::ecs::components::*;
use cleave::ecs::resources::*;
use cleave::systems::*;

struct Access {
    writes: Vec<ComponentId>,
    deferred: bool,
}

fn access_of<M>(world: &mut World, system: impl IntoSystem<(), (), M>) -> Access {
    let mut system = IntoSystem::into_system(system);
    let access = system.initialize(world);
    assert!(
        !access.is_exclusive(),
        "{} must not take the whole world",
        system.name()
    );
    let set = access.to_filtered_access_set();
    let combined = set.combined_access();
    assert!(
        !combined.has_write_all(),
        "{} writes everything",
        system.name()
    );
    let all: Vec<ComponentId> = world
        .components()
        .iter_registered()
        .map(|(id, _)| id)
        .collect();
    Access {
        writes: all
            .into_iter()
            .filter(|id| combined.has_write(*id))
            .collect(),
        deferred: system.has_deferred(),
    }
}

fn ids(world: &mut World) -> (Vec<ComponentId>, Vec<ComponentId>) {
    let particle = vec![
        world.register_component::<Particle>(),
        world.register_component::<Position>(),
        world.register_component::<PrevPosition>(),
        world.register_component::<Velocity>(),
        world.register_component::<InvMass>(),
        world.register_component::<BodyLattice>(),
    ];
    let cluster = vec![
        world.register_component::<ClusterMembers>(),
        world.register_component::<ClusterOf>(),
        world.register_component::<Compliance>(),
        world.register_component::<ParticleClusters>(),
    ];
    (particle, cluster)
}

fn world() -> World {
    let mut w = World::new();
    install(&mut w, SimConfig::default());
    w
}

#[test]
fn predict_and_shape_match_write_particle_data_only() {
    let mut w = world();
    let (particle, cluster) = ids(&mut w);
    for access in [
        access_of(&mut w, predict::predict),
        access_of(&mut w, shape_match::shape_match),
    ] {
        assert!(
            access.writes.iter().all(|id| !cluster.contains(id)),
            "writes cluster data"
        );
        assert!(access.writes.contains(&particle[1]), "must write Position");
        assert!(!access.deferred, "must not spawn or despawn");
    }
}

#[test]
fn moving_colliders_writes_collider_poses_only() {
    let mut w = world();
    ids(&mut w);
    let access = access_of(&mut w, move_colliders::move_colliders);
    let pose = w.register_component::<ColliderPose>();
    assert_eq!(access.writes, vec![pose]);
    assert!(!access.deferred);
}

#[test]
fn detect_writes_only_its_cut_list_and_spawns_nothing() {
    let mut w = world();
    ids(&mut w);
    let access = access_of(&mut w, detect::detect);
    let cut_list = w.component_id::<CutList>().expect("registered");
    assert_eq!(access.writes, vec![cut_list]);
    assert!(!access.deferred);
}

#[test]
fn cut_writes_no_cluster_data() {
    let mut w = world();
    let (_, cluster) = ids(&mut w);
    let lattice = w.register_component::<BodyLattice>();
    let access = access_of(&mut w, cut::cut);
    assert!(access.writes.iter().all(|id| !cluster.contains(id)));
    assert!(access.writes.contains(&lattice), "cut edits the lattice");
}

#[test]
fn regroup_split_expand_write_no_particle_data() {
    let mut w = world();
    let (particle, cluster) = ids(&mut w);
    for access in [
        access_of(&mut w, regroup::regroup),
        access_of(&mut w, split::split),
        access_of(&mut w, expand::expand),
    ] {
        assert!(
            access.writes.iter().all(|id| !particle.contains(id)),
            "writes particle data"
        );
        assert!(
            access.writes.contains(&cluster[0]),
            "must write ClusterMembers"
        );
    }
}

#[test]
fn schedules_build_with_ambiguity_detection_as_error() {
    let mut w = world();
    w.run_schedule(CleaveSchedule);
    assert_eq!(w.resource::<SimClock>().frame, 1);
}
