//! The access contract of every stage, read from the systems' own access sets: predict
//! and shape-match (with every term) write only the solver's dense particle state; load,
//! the term sync and the terms' ECS sides write only the solver; store writes only
//! particle positions and velocities; the tool, collider and attachment movers and the settle stage write their
//! poses only; detect writes only its CutList (and its culling memory) and spawns
//! nothing; cut writes no cluster data; regroup/split/expand write no particle data; the
//! surface stage writes only the surfaces (and its message); the wrench stage only the
//! colliders' wrenches and dynamic state (and its message).

use bevy_ecs::component::ComponentId;
use bevy_ecs::message::Messages;
use bevy_ecs::prelude::*;
use bevy_ecs::system::{IntoSystem, System};
use cleave::config::SimConfig;
use cleave::ecs::components::*;
use cleave::ecs::layout::SolverCache;
use cleave::ecs::resources::*;
use cleave::solver::terms::{
    attachments::Attachments, centroids::Centroids, colliders::Colliders, contacts::Contacts,
};
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

/// Asserts that `access` writes exactly `expected` (in any order) and defers nothing.
fn writes_only(access: Access, mut expected: Vec<ComponentId>) {
    let mut writes = access.writes;
    expected.sort();
    writes.sort();
    assert_eq!(writes, expected);
    assert!(!access.deferred);
}

fn ids(world: &mut World) -> (Vec<ComponentId>, Vec<ComponentId>) {
    let particle = vec![
        world.register_component::<Particle>(),
        world.register_component::<Position>(),
        world.register_component::<Velocity>(),
        world.register_component::<InvMass>(),
        world.register_component::<BodyLattice>(),
        world.register_component::<Orientation>(),
        world.register_component::<AngularVelocity>(),
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
fn predict_shape_match_load_and_the_term_sync_write_only_the_solver() {
    let mut w = world();
    ids(&mut w);
    let accesses = [
        access_of(&mut w, predict::predict),
        access_of(&mut w, shape_match::shape_match),
        access_of(&mut w, load::load_particles),
        access_of(&mut w, term_sync::sync_terms),
        // every built-in term's ECS side, per frame and per substep
        access_of(&mut w, term_sync::sync_term::<Attachments>),
        access_of(&mut w, term_sync::sync_term::<Centroids>),
        access_of(&mut w, term_sync::sync_term::<Contacts>),
        access_of(&mut w, term_sync::substep_term::<Colliders>),
    ];
    let solver = w.component_id::<SolverCache>().expect("registered");
    for access in accesses {
        // (shape-match also sends its repair messages)
        let writes: Vec<ComponentId> = access
            .writes
            .into_iter()
            .filter(|id| Some(*id) != w.component_id::<Messages<ParticlesRepaired>>())
            .collect();
        assert_eq!(writes, vec![solver]);
        assert!(!access.deferred, "must not spawn or despawn");
    }
}

#[test]
fn store_writes_the_particles_motion_only() {
    let mut w = world();
    let (particle, _) = ids(&mut w);
    let access = access_of(&mut w, store::store_particles);
    // positions, velocities, orientations, angular velocities
    writes_only(
        access,
        vec![particle[1], particle[2], particle[5], particle[6]],
    );
}

#[test]
fn moving_and_settling_kinematic_things_writes_their_poses_only() {
    let mut w = world();
    ids(&mut w);
    let tool = w.register_component::<ToolPose>();
    let collider = w.register_component::<ColliderPose>();
    let target = w.register_component::<AttachmentTarget>();
    let access = access_of(&mut w, move_tools::move_tools);
    assert_eq!(access.writes, vec![tool]);
    assert!(!access.deferred);
    let access = access_of(&mut w, move_colliders::move_colliders);
    assert_eq!(access.writes, vec![collider]);
    assert!(!access.deferred);
    let access = access_of(&mut w, move_attachments::move_attachments);
    assert_eq!(access.writes, vec![target]);
    assert!(!access.deferred);
    let access = access_of(&mut w, settle_poses::settle_poses);
    writes_only(access, vec![tool, collider, target]);
}

#[test]
fn detect_writes_only_its_cut_list_and_culling_memory_and_spawns_nothing() {
    let mut w = world();
    ids(&mut w);
    let mut access = access_of(&mut w, detect::detect);
    let cut_list = w.component_id::<CutList>().expect("registered");
    let culling = w.component_id::<DetectCulling>().expect("registered");
    let mut expected = vec![cut_list, culling];
    expected.sort();
    access.writes.sort();
    assert_eq!(access.writes, expected);
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
fn the_wrench_stage_writes_colliders_only() {
    let mut w = world();
    ids(&mut w);
    let wrench = w.register_component::<ColliderWrench>();
    let pose = w.register_component::<ColliderPose>();
    let dynamic = w.register_component::<DynamicCollider>();
    let access = access_of(&mut w, wrench::collider_wrenches);
    let message = w
        .component_id::<Messages<ColliderPushed>>()
        .expect("registered");
    writes_only(access, vec![wrench, message]);
    let access = access_of(&mut w, wrench::dynamic_colliders);
    writes_only(access, vec![pose, dynamic]);
}

#[test]
fn the_surface_stage_writes_surfaces_only() {
    let mut w = world();
    ids(&mut w);
    let surface = w.register_component::<cleave::ecs::surface_mesh::SurfaceMesh>();
    let access = access_of(&mut w, surface::update_surfaces);
    let changed = w
        .component_id::<Messages<SurfaceChanged>>()
        .expect("registered");
    let deferred = w
        .component_id::<Messages<cleave::ecs::resources::SurfaceDeferred>>()
        .expect("registered");
    writes_only(access, vec![surface, changed, deferred]);
}

#[test]
fn schedules_build_with_ambiguity_detection_as_error() {
    let mut w = world();
    w.run_schedule(CleaveSchedule);
    assert_eq!(w.resource::<SimClock>().frame, 1);
}
