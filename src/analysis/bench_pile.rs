//! The contact rows of `cleave bench`: the `pile` scene at a fine spacing, and a crowd
//! of more bodies in a wider bin, each stepped with and without particle contacts in the
//! same run, with a blade moving far from every body to time what detection costs when
//! there is nothing to find.

use crate::analysis::bench::{median, term_seconds, time_ms};
use crate::config::SimConfig;
use crate::cut::tool::{CutMode, Path, Pose, ToolShape};
use crate::ecs::desc::Scene;
use crate::ecs::desc::ToolDesc;
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::DetectCulling;
use crate::error::Result;
use crate::io::pile_scenes::{crowd_scene, pile_scene};
use crate::sim::simulation::Simulation;
use glam::{Quat, Vec3};
use serde::Serialize;

/// A contact row of the bench: the `pile` scene at a finer spacing, or a crowd, stepped
/// with and without particle contacts in the same run.
#[derive(Clone, Debug, Serialize)]
pub struct PileRow {
    /// `"pile"` or `"crowd"` (tells the row from the size rows in JSON lines).
    pub row: &'static str,
    /// Lattice spacing of the bodies.
    pub spacing: f32,
    /// Bodies.
    pub bodies: usize,
    /// Particles over all bodies.
    pub particles: usize,
    /// Frames stepped (the medians are over the second half, when the bodies touch).
    pub frames: u32,
    /// Particles that take part in contacts (surface particles), at the end.
    pub contact_particles: usize,
    /// Contact pairs found in the last substep (each counted from both sides).
    pub contact_pairs: usize,
    /// Median step with contacts, ms.
    pub ms_per_step: f64,
    /// `ms_per_step` per particle, ns: what a particle-step costs over the whole crowd.
    pub ns_per_particle_step: f64,
    /// Median step of the same scene with contacts off, ms.
    pub ms_per_step_without_contacts: f64,
    /// `ms_per_step / ms_per_step_without_contacts`. The two runs differ in more than
    /// contacts: without them the bodies sink through each other and lie otherwise.
    pub contacts_over_without: f64,
    /// Median time the contact kind itself took in a step (pairs and projection), ms.
    pub contact_ms_per_step: f64,
    /// Median time of the contact kind's substep set-up in a step: finding the pairs
    /// (the candidate list's upkeep, its filter and the pairs' table), ms.
    pub contact_find_ms_per_step: f64,
    /// Median time of the contact kind's projections in a step (every iteration), ms.
    pub contact_projection_ms_per_step: f64,
    /// What contacts add to the rest of the same step: `contact_ms_per_step /
    /// (ms_per_step − contact_ms_per_step)`.
    pub contact_share: f64,
    /// What contacts add, per particle (all of them) and solver iteration, ns.
    pub contact_ns_per_particle_iteration: f64,
    /// Median time of the detect stage in a step with contacts, ms: a turning blade
    /// sweeps back and forth 3 m beside the bin, far from every body.
    pub far_tool_detect_ms_per_step: f64,
    /// `far_tool_detect_ms_per_step / ms_per_step`.
    pub far_tool_detect_share: f64,
}

/// A sever blade that sweeps back and forth along z, turning, 3 m beside the `pile`
/// scene's bin (2 m beside the crowd's): it never reaches a body, so detection has
/// nothing to find.
fn far_blade() -> ToolDesc {
    let at = |z: f32, turn: f32| Pose {
        position: Vec3::new(4.0, 0.5, z),
        rotation: Quat::from_rotation_y(turn),
    };
    ToolDesc {
        shape: ToolShape::Blade {
            half_width: 0.5,
            half_height: 0.3,
        },
        cut_width: 0.01,
        cut_mode: CutMode::Sever,
        path: Path {
            keys: (0..=8)
                .map(|k| {
                    (
                        k as f32 * 0.5,
                        at(if k % 2 == 0 { -1.0 } else { 1.0 }, k as f32),
                    )
                })
                .collect(),
        },
        pose: at(-1.0, 0.0),
    }
}

/// Runs the `pile` scene at `spacing` for `frames` frames twice, with and without
/// contacts, alternating steps so both see the same machine noise; a blade far from
/// every body moves in both, and the detect stage is timed in the first.
pub fn bench_pile(spacing: f32, frames: u32, config: &SimConfig) -> Result<PileRow> {
    bench_bin("pile", spacing, frames, config, |config| {
        pile_scene(config, spacing)
    })
}

/// Runs a crowd of `bodies` bodies ([`crowd_scene`]) at `spacing` for `frames` frames
/// twice, with and without contacts, as [`bench_pile`] runs the pile.
pub fn bench_crowd(
    spacing: f32,
    bodies: usize,
    frames: u32,
    config: &SimConfig,
) -> Result<PileRow> {
    bench_bin("crowd", spacing, frames, config, |config| {
        crowd_scene(config, spacing, bodies)
    })
}

/// Runs the scene `make` gives as [`bench_pile`] runs the pile, and names the row `row`.
fn bench_bin(
    row: &'static str,
    spacing: f32,
    frames: u32,
    config: &SimConfig,
    make: impl Fn(SimConfig) -> Scene,
) -> Result<PileRow> {
    let build = |contacts: bool| -> Result<Simulation> {
        let scene = make(SimConfig {
            contacts,
            ..config.clone()
        });
        let mut sim = Simulation::new(scene.config.clone())?;
        for b in &scene.bodies {
            sim.spawn_body(b)?;
        }
        for c in &scene.colliders {
            sim.spawn_collider(c)?;
        }
        sim.spawn_tool(&far_blade())?;
        sim.drop_surfaces();
        Ok(sim)
    };
    let (mut with, mut without) = (build(true)?, build(false)?);
    let (mut on, mut off, mut inside) = (Vec::new(), Vec::new(), Vec::new());
    let mut detect = Vec::new();
    let (mut find, mut project) = (Vec::new(), Vec::new());
    for frame in 0..frames.max(2) {
        let before = term_seconds(&with, "contacts");
        let (a, b) = (time_ms(1, || with.step()), time_ms(1, || without.step()));
        if frame >= frames / 2 {
            on.push(a);
            off.push(b);
            let after = term_seconds(&with, "contacts");
            inside.push((after.total() - before.total()) * 1e3);
            find.push((after.setup - before.setup) * 1e3);
            project.push((after.iterations - before.iterations) * 1e3);
            detect.push(with.world().resource::<DetectCulling>().last_ms);
        }
    }
    let cache = with.world().resource::<SolverCache>();
    let particles = cache.particles.len();
    let contacts = cache.solver.terms.extent("contacts").unwrap_or_default();
    let (ms_on, ms_off, ms_in) = (median(&mut on), median(&mut off), median(&mut inside));
    let iterations = (config.substeps * config.iterations) as f64;
    Ok(PileRow {
        row,
        spacing,
        bodies: cache.layout.bodies().len(),
        particles,
        frames,
        contact_particles: contacts.particles,
        contact_pairs: contacts.constraints,
        ms_per_step: ms_on,
        ns_per_particle_step: ms_on * 1e6 / particles as f64,
        ms_per_step_without_contacts: ms_off,
        contacts_over_without: ms_on / ms_off,
        contact_ms_per_step: ms_in,
        contact_find_ms_per_step: median(&mut find),
        contact_projection_ms_per_step: median(&mut project),
        contact_share: ms_in / (ms_on - ms_in),
        contact_ns_per_particle_iteration: (ms_on - ms_off) * 1e6 / (particles as f64 * iterations),
        far_tool_detect_ms_per_step: median(&mut detect),
        far_tool_detect_share: median(&mut detect) / ms_on,
    })
}
