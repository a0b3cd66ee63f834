//! The ECS stages of a frame (see the crate docs) as ordered system sets, and the
//! schedules that run them.
//!
//! [`CleaveSchedule`] runs once per frame, its stages chained in this order:
//!
//! 1. [`SimStage::MoveColliders`] and 2. [`SimStage::MoveAttachments`]: kinematic
//!    colliders and attachment targets placed for the frame's end, and
//!    [`SimStage::PoseHandles`]: bodies posed by handles given the velocities that take
//!    their kinematic particles to the pose ([`pose_handles`]);
//! 3. [`SimStage::Sync`]: an exclusive system that runs [`SyncSchedule`] — the solver
//!    layout brought up to date ([`layout_sync`]), every term that reads the ECS given
//!    its data ([`term_sync::TermData`]: the attachments and their targets, the contacts'
//!    settings) and every term told what changed ([`term_sync`]), the particles' state
//!    loaded into the solver ([`load`]);
//! 4. [`SimStage::Substeps`]: an exclusive system that runs [`SubstepSchedule`] —
//!    predict → the terms' substep data ([`term_sync::TermSubstepData`]: the colliders
//!    placed) → shape-match — `substeps` times;
//! 5. [`SimStage::Store`]: the particles' state written back to their components, and
//!    [`SimStage::Wrench`]: each collider's wrench and the dynamic colliders' motion
//!    ([`wrench`]);
//! 6. `MoveTools → Detect → Cut → Regroup → Split → Expand`;
//! 7. [`SimStage::Settle`]: where tools, colliders and attachment targets ended the
//!    frame becomes where the next frame moves them from (so a pose game code writes
//!    between frames is swept like a keyframed one);
//! 8. [`SimStage::Surface`]: every body's drawable surface ([`surface`]); then the
//!    optional invariant check ([`SimStage::Verify`]).
//!
//! Access contract (tested in `tests/schedule_access.rs`): predict and shape-match write
//! particle data only; detect writes only its `CutList` and its culling memory; cut
//! writes no cluster data; regroup/split/expand write no particle data; surface writes
//! surface data only; wrench writes collider data only.

pub mod cut;
pub mod detect;
pub mod ecs_store;
pub mod expand;
pub mod layout_sync;
pub mod load;
pub mod move_attachments;
pub mod move_colliders;
pub mod move_tools;
pub mod pose_handles;
pub mod predict;
pub mod regroup;
pub mod settle_poses;
pub mod shape_match;
pub mod split;
pub mod store;
pub mod surface;
pub mod term_sync;
pub mod wrench;

use crate::ecs::ecs_term::{EcsSubstepTerm, EcsTerm};
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::*;
use crate::solver::term::Term;
use crate::solver::terms::{
    attachments::Attachments, centroids::Centroids, colliders::Colliders, contacts::Contacts,
};
use bevy_ecs::message::MessageRegistry;
use bevy_ecs::prelude::*;
use bevy_ecs::schedule::{LogLevel, ScheduleBuildSettings, ScheduleLabel, SingleThreadedExecutor};
use rand::SeedableRng;

/// The stages, in order.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SimStage {
    /// Brings the solver up to date with the ECS and loads the particles' state (runs
    /// [`SyncSchedule`]).
    Sync,
    /// Forces, damping, predicted positions (in [`SubstepSchedule`]).
    Predict,
    /// Constraint iterations: cluster shape matching, then every other term
    /// (attachments, patches, centroid holds, edges, contacts, colliders) in each iteration (in
    /// [`SubstepSchedule`]).
    ShapeMatch,
    /// Advances keyframed colliders to the end of the frame (in [`CleaveSchedule`]).
    MoveColliders,
    /// Advances attachment targets (paths, velocities) to the end of the frame.
    MoveAttachments,
    /// Bodies posed by handles: their particles' velocities toward the frame's pose.
    PoseHandles,
    /// Runs the substep schedule (in [`CleaveSchedule`]).
    Substeps,
    /// Writes the particles' state back to their components.
    Store,
    /// Each collider's wrench (what the particles did to it over the frame), and the
    /// dynamic colliders' poses and velocities.
    Wrench,
    /// Advances keyframed tools.
    MoveTools,
    /// Read-only collision detection producing the `CutList` (and keeping its culling
    /// memory).
    Detect,
    /// Removes the listed particles.
    Cut,
    /// Reconstruction step 1 (see [`crate::reconstruct`]).
    Regroup,
    /// Reconstruction step 2.
    Split,
    /// Reconstruction steps 3 and 4.
    Expand,
    /// The poses tools, colliders and attachment targets reached become the next
    /// frame's start.
    Settle,
    /// Every body's drawable surface brought up to date (writes surface data only).
    Surface,
    /// Optional invariant check (debug / tests).
    Verify,
}

/// Runs once per frame.
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct CleaveSchedule;

/// Runs once at the start of each frame, and when a simulation is saved or loaded:
/// brings the solver layout and its terms up to date with the ECS and loads the
/// particles' state.
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SyncSchedule;

/// Runs `substeps` times per frame: predict → shape-match.
#[derive(ScheduleLabel, Clone, Debug, PartialEq, Eq, Hash)]
pub struct SubstepSchedule;

fn strict(schedule: &mut Schedule) {
    schedule.set_build_settings(ScheduleBuildSettings {
        ambiguity_detection: LogLevel::Error,
        ..Default::default()
    });
    schedule.set_executor(SingleThreadedExecutor::new());
}

/// Builds the substep schedule (predict → shape-match).
pub fn build_substep_schedule() -> Schedule {
    let mut s = Schedule::new(SubstepSchedule);
    strict(&mut s);
    s.configure_sets(
        (
            SimStage::Predict,
            term_sync::TermSubstepData,
            SimStage::ShapeMatch,
        )
            .chain(),
    );
    s.add_systems(predict::predict.in_set(SimStage::Predict));
    // the built-in terms that read the ECS every substep, one line each
    s.add_systems(term_sync::term_substep_system::<Colliders>());
    s.add_systems(shape_match::shape_match.in_set(SimStage::ShapeMatch));
    s
}

/// Builds the layout-update schedule.
pub fn build_sync_schedule() -> Schedule {
    let mut s = Schedule::new(SyncSchedule);
    strict(&mut s);
    s.configure_sets(
        term_sync::TermData
            .after(layout_sync::sync_solver)
            .before(term_sync::sync_terms),
    );
    s.add_systems(
        (
            layout_sync::sync_solver,
            term_sync::sync_terms,
            load::load_particles,
        )
            .chain(),
    );
    // the built-in terms that read the ECS, one line each
    s.add_systems(term_sync::term_data_system::<Contacts>());
    s.add_systems(term_sync::term_data_system::<Attachments>());
    s.add_systems(term_sync::term_data_system::<Centroids>());
    s
}

/// Builds the frame schedule (substeps, then detect → … → expand).
pub fn build_schedule() -> Schedule {
    let mut s = Schedule::new(CleaveSchedule);
    strict(&mut s);
    s.configure_sets(
        (
            SimStage::MoveColliders,
            SimStage::MoveAttachments,
            SimStage::PoseHandles,
            SimStage::Sync,
            SimStage::Substeps,
            SimStage::Store,
            SimStage::Wrench,
            SimStage::MoveTools,
            SimStage::Detect,
            SimStage::Cut,
            SimStage::Regroup,
            SimStage::Split,
            SimStage::Expand,
            SimStage::Settle,
            SimStage::Surface,
            SimStage::Verify,
        )
            .chain(),
    );
    s.add_systems(run_sync.in_set(SimStage::Sync));
    s.add_systems(move_colliders::move_colliders.in_set(SimStage::MoveColliders));
    s.add_systems(move_attachments::move_attachments.in_set(SimStage::MoveAttachments));
    s.add_systems(pose_handles::pose_handles.in_set(SimStage::PoseHandles));
    s.add_systems(run_substeps.in_set(SimStage::Substeps));
    s.add_systems(store::store_particles.in_set(SimStage::Store));
    s.add_systems((wrench::dynamic_colliders, wrench::collider_wrenches).in_set(SimStage::Wrench));
    s.add_systems(move_tools::move_tools.in_set(SimStage::MoveTools));
    s.add_systems(detect::detect.in_set(SimStage::Detect));
    s.add_systems(cut::cut.in_set(SimStage::Cut));
    s.add_systems(regroup::regroup.in_set(SimStage::Regroup));
    s.add_systems(split::split.in_set(SimStage::Split));
    s.add_systems(expand::expand.in_set(SimStage::Expand));
    s.add_systems(settle_poses::settle_poses.in_set(SimStage::Settle));
    s.add_systems(surface::update_surfaces.in_set(SimStage::Surface));
    s.add_systems(
        verify
            .in_set(SimStage::Verify)
            .run_if(invariant_checks_enabled),
    );
    s
}

/// Inserts every resource, registers the messages and adds both schedules to `world`.
/// Afterwards [`run_frame`] advances one frame.
pub fn install(world: &mut World, config: crate::config::SimConfig) {
    world.insert_resource(SimRng(rand_chacha::ChaCha8Rng::seed_from_u64(config.seed)));
    world.insert_resource(SimSettings(config));
    world.init_resource::<SimClock>();
    world.init_resource::<SceneLabel>();
    world.init_resource::<SubstepClock>();
    world.init_resource::<CutList>();
    world.init_resource::<DetectCulling>();
    world.init_resource::<CutReport>();
    world.init_resource::<RebuiltClusters>();
    world.init_resource::<SolverCache>();
    world.init_resource::<CutTimings>();
    MessageRegistry::register_message::<ParticlesCut>(world);
    MessageRegistry::register_message::<EdgesSevered>(world);
    MessageRegistry::register_message::<ParticlesSplit>(world);
    MessageRegistry::register_message::<SplitsOverBudget>(world);
    MessageRegistry::register_message::<ClustersRebuilt>(world);
    MessageRegistry::register_message::<BodySplit>(world);
    MessageRegistry::register_message::<ParticlesRepaired>(world);
    MessageRegistry::register_message::<SurfaceChanged>(world);
    MessageRegistry::register_message::<SurfaceDeferred>(world);
    MessageRegistry::register_message::<ColliderPushed>(world);
    world.add_schedule(build_sync_schedule());
    world.add_schedule(build_substep_schedule());
    world.add_schedule(build_schedule());
}

/// Registers `term` with the solver, after the terms it has: every term hears of the
/// bodies again at the next frame, the new one with them.
pub fn add_term(world: &mut World, term: impl Term) {
    let mut cache = world.resource_mut::<SolverCache>();
    cache.solver.terms.register(term);
    cache.layout.retell_terms();
}

/// Registers `term` with the solver and its ECS side with the frame: one call adds a
/// kind that reads the ECS (one term of each kind: the sync finds the first). Every
/// term hears of the bodies again at the next frame.
pub fn add_ecs_term<T: EcsTerm>(world: &mut World, term: T) {
    add_term(world, term);
    world.schedule_scope(SyncSchedule, |_, schedule| {
        schedule.add_systems(term_sync::term_data_system::<T>());
    });
}

/// [`add_ecs_term`] for a kind that takes its ECS data every substep.
pub fn add_ecs_substep_term<T: EcsSubstepTerm>(world: &mut World, term: T) {
    add_term(world, term);
    world.schedule_scope(SubstepSchedule, |_, schedule| {
        schedule.add_systems(term_sync::term_substep_system::<T>());
    });
}

/// Runs the [`CleaveSchedule`] once: one frame, on a thread of the current rayon pool.
///
/// The frame's stages run dozens of parallel passes. Called from a thread outside the
/// pool (a game's main thread, a test), each pass would be handed to the pool and
/// waited for on its own; run on a thread of the pool, the frame is handed over once
/// and its passes start where it runs. A caller already in the pool runs it in place.
/// The caller's tracing dispatcher goes with it, so that the stages' spans reach the
/// subscriber the caller set.
pub fn run_frame(world: &mut World) {
    let dispatch = tracing::dispatcher::get_default(|current| current.clone());
    rayon::scope(|_| {
        tracing::dispatcher::with_default(&dispatch, || world.run_schedule(CleaveSchedule))
    });
}

/// Exclusive system: runs the layout-update schedule.
pub fn run_sync(world: &mut World) {
    world.run_schedule(SyncSchedule);
}

/// Exclusive system: runs the substep schedule `substeps` times and advances the clock.
pub fn run_substeps(world: &mut World) {
    let config = world.resource::<SimSettings>().0.clone();
    for index in 0..config.substeps {
        *world.resource_mut::<SubstepClock>() = SubstepClock {
            index,
            count: config.substeps,
        };
        world.run_schedule(SubstepSchedule);
    }
    let mut clock = world.resource_mut::<SimClock>();
    clock.frame += 1;
    // a sum, not frame × dt, so that a frame length changed at run time (the game's
    // fixed timestep) moves time on from where it was; while dt stays the same the two
    // are equal to the bit (an f32 times a count below 2^29 is exact in f64)
    clock.time += config.dt as f64;
}

fn invariant_checks_enabled(settings: Res<SimSettings>) -> bool {
    settings.0.check_invariants_every_frame
}

/// Panics with the list of violations if any invariant is broken.
pub fn verify(world: &World) {
    let violations = crate::ecs::check::check_invariants(world);
    assert!(violations.is_empty(), "invariants violated: {violations:?}");
}
