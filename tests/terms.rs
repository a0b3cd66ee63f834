//! The term seam from outside the solver: kinds written here, registered by one call,
//! solved under every scheme; and the built-in kinds checked against what their
//! definitions predict.

use cleave::analysis::stats::body_stats;
use cleave::bevy_ecs::entity::Entity;
use cleave::bevy_ecs::query::With;
use cleave::ecs::layout::SolverCache;
use cleave::prelude::*;
use cleave::solver::term::{
    ParticleKey, ParticleState, ProjectiveTerm, Substep, Term, Topology, Unknowns,
};
use glam::{DVec3, Vec3A};

/// A floor this test file defines: no particle goes below `height` (a constraint that
/// changes every substep: projected after projective dynamics' global step).
struct Floor {
    height: f32,
}

impl Term for Floor {
    fn name(&self) -> &'static str {
        "floor"
    }

    fn is_empty(&self) -> bool {
        false
    }

    fn project(&mut self, _step: &Substep, state: &mut ParticleState) {
        for i in 0..state.positions.len() {
            let below = self.height - state.positions[i].y;
            if below > 0.0 && state.inv_mass[i] > 0.0 {
                state.shift(i, Vec3A::new(0.0, below, 0.0));
            }
        }
    }
}

/// A spring this test file defines: one particle held to a fixed point by a spring of
/// `compliance` (m/N), with its projective form (the point is the projection).
struct Tether {
    key: ParticleKey,
    anchor: Vec3A,
    compliance: f32,
    dense: Option<u32>,
    lambda: Vec3A,
    version: u64,
}

impl Term for Tether {
    fn name(&self) -> &'static str {
        "tether"
    }

    fn is_empty(&self) -> bool {
        self.dense.is_none()
    }

    fn topology(&mut self, change: &Topology) {
        self.dense = change.dense(self.key);
        self.version += 1;
    }

    fn begin_substep(&mut self, _step: &Substep, _state: &mut ParticleState) {
        self.lambda = Vec3A::ZERO;
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        let Some(i) = self.dense.map(|d| d as usize) else {
            return;
        };
        let (w, alpha) = (state.inv_mass[i], step.scaled(self.compliance));
        let delta = (self.anchor - state.positions[i] - self.lambda * alpha) / (w + alpha);
        self.lambda += delta;
        state.shift(i, delta * w);
    }

    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        Some(self)
    }
}

impl ProjectiveTerm for Tether {
    fn version(&self) -> u64 {
        self.version
    }

    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    ) {
        if let Some(row) = self.dense.and_then(|d| unknowns.row(d)) {
            let w = unknowns.weight(self.compliance, &[self.dense.unwrap_or(0)], step.dt);
            entries.push((row, row, w));
        }
    }

    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        _orientations: &mut [cleave::glam::Quat],
        forces: &mut [DVec3],
    ) {
        if let Some(d) = self.dense {
            let w = unknowns.weight(self.compliance, &[d], step.dt);
            forces[d as usize] += (self.anchor - positions[d as usize]).as_dvec3() * w;
        }
    }
}

fn block(sim: &mut Simulation, cells: UVec3, y: f32) -> Entity {
    let mut desc = BodyDesc::new(Shape::cuboid(cells), 0.1);
    desc.position = Vec3::new(0.0, y, 0.0);
    sim.spawn_body(&desc).expect("a block")
}

fn lowest(sim: &Simulation, body: Entity) -> f32 {
    let positions = sim.positions(body).expect("a body");
    positions
        .iter()
        .map(|(_, p)| p.y)
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn a_term_of_our_own_is_registered_by_one_call_and_solved_under_every_scheme() {
    for solver in SolverMode::ALL {
        let config = SimConfig {
            ground: None,
            solver,
            ..SimConfig::default()
        };
        // a block dropped onto the floor this file defines rests on it
        let mut sim = Simulation::new(config.clone()).expect("a simulation");
        let body = block(&mut sim, UVec3::new(6, 3, 3), 1.0);
        sim.add_term(Floor { height: 0.5 });
        sim.run(120);
        let rest = lowest(&sim, body);
        assert!((rest - 0.5).abs() < 0.01, "{solver}: rests at {rest}");
        let cache = sim.world().resource::<SolverCache>();
        let floor = cache
            .solver
            .seconds()
            .into_iter()
            .find(|(n, _)| *n == "floor");
        assert!(
            floor.is_some_and(|(_, s)| s > 0.0),
            "{solver}: timed by name"
        );
        // without it the block falls through
        let mut free = Simulation::new(config.clone()).expect("a simulation");
        let body = block(&mut free, UVec3::new(6, 3, 3), 1.0);
        free.run(120);
        assert!(lowest(&free, body) < -1.0, "{solver}: no floor, no rest");
        // a rigid block of 54 kg hung by one particle from a spring of 1e-3 m/N: the
        // spring stretches by M g α (projective dynamics holds it in its matrix)
        let mut sim = Simulation::new(config).expect("a simulation");
        let body = block(&mut sim, UVec3::new(6, 3, 3), 1.0);
        let (top, at) = sim
            .positions(body)
            .expect("a body")
            .into_iter()
            .max_by(|a, b| {
                (a.1.y - a.1.x.abs() - a.1.z.abs()).total_cmp(&(b.1.y - b.1.x.abs() - b.1.z.abs()))
            })
            .expect("particles");
        sim.add_term(Tether {
            key: ParticleKey {
                body: body.to_bits(),
                local: top,
            },
            anchor: Vec3A::from(at),
            compliance: 1e-3,
            dense: None,
            lambda: Vec3A::ZERO,
            version: 0,
        });
        sim.run(360);
        let stretch = at.y - sim.positions(body).expect("a body")[top as usize].1.y;
        let expected = 54.0 * 9.81 * 1e-3;
        assert!(
            (stretch - expected).abs() < 0.1 * expected,
            "{solver}: stretch {stretch} m, M g α = {expected} m"
        );
    }
}

/// The targets of attachment `e` now: its pose applied to each particle's offset.
fn targets(sim: &Simulation, e: Entity) -> Vec<(u32, Vec3)> {
    let world = sim.world();
    let (a, target) = (
        world.get::<Attachment>(e).expect("an attachment"),
        world.get::<AttachmentTarget>(e).expect("a target"),
    );
    let pose = target.pose;
    a.particles
        .iter()
        .zip(&a.offsets)
        .map(|(p, o)| (*p, pose.position + pose.rotation * *o))
        .collect()
}

#[test]
fn a_block_dragged_by_a_soft_attachment_follows_and_stretches_it_as_its_compliance_says() {
    for solver in SolverMode::ALL {
        let config = SimConfig {
            ground: None,
            solver,
            damping: 2.0,
            ..SimConfig::default()
        };
        let mut sim = Simulation::new(config).expect("a simulation");
        // a rigid 8×4×4 block of 128 kg held by its top layer (32 particles), each on a
        // spring of 1e-4 m/N, whose target moves 1 m along x at 2 m/s
        let at = |x: f32| Pose::at(Vec3::new(x, 1.2, 0.0));
        let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(8, 4, 4)), 0.1);
        desc.position = Vec3::new(0.0, 1.0, 0.0);
        desc.attachments = vec![AttachmentDesc {
            region: Region {
                min: Vec3::new(-1.0, 1.1, -1.0),
                max: Vec3::new(1.0, 2.0, 1.0),
            },
            path: Path {
                keys: vec![(0.1, at(0.0)), (0.6, at(1.0))],
            },
            compliance: 1e-4,
            hold: Hold::Each,
        }];
        let body = sim.spawn_body(&desc).expect("a body");
        let start = sim.positions(body).expect("a body");
        let centroid = |p: &[(u32, Vec3)]| p.iter().map(|(_, x)| *x).sum::<Vec3>() / p.len() as f32;
        sim.run(240);
        let end = sim.positions(body).expect("a body");
        let moved = centroid(&end) - centroid(&start);
        assert!((moved.x - 1.0).abs() < 0.02, "{solver}: moved {moved}");
        // the springs carry the weight: each stretches by M g α / n
        let attachment = sim
            .world_mut()
            .query_filtered::<Entity, With<Attachment>>()
            .single(sim.world())
            .expect("one attachment");
        let held = targets(&sim, attachment);
        assert_eq!(held.len(), 32);
        let stretch: f32 = held
            .iter()
            .map(|(p, t)| t.y - end[*p as usize].1.y)
            .sum::<f32>()
            / held.len() as f32;
        let expected = 128.0 * 9.81 * 1e-4 / 32.0;
        assert!(
            (stretch - expected).abs() < 0.1 * expected,
            "{solver}: stretch {stretch} m, expected {expected} m"
        );
    }
}

#[test]
fn a_hard_attachment_holds_like_a_pin_and_a_despawned_one_lets_go() {
    let scene = cleave::io::scene::builtin("cantilever", 0).expect("built in");
    let tip_drop = |desc: &BodyDesc| {
        let mut sim = Simulation::new(scene.config.clone()).expect("a simulation");
        let body = sim.spawn_body(desc).expect("a body");
        let tip = |sim: &Simulation| {
            let p = sim.positions(body).expect("a body");
            p.iter()
                .filter(|(_, x)| x.x > 1.1)
                .map(|(_, x)| x.y)
                .sum::<f32>()
        };
        let before = tip(&sim);
        sim.run(300);
        (before - tip(&sim), sim)
    };
    let pinned = scene.bodies[0].clone();
    let mut attached = pinned.clone();
    attached.attachments = pinned
        .pins
        .iter()
        .map(|p| AttachmentDesc {
            region: p.region(),
            path: Path::default(),
            compliance: 0.0,
            hold: Hold::Each,
        })
        .collect();
    attached.pins.clear();
    let (by_pin, _) = tip_drop(&pinned);
    let (by_attachment, mut sim) = tip_drop(&attached);
    assert!(by_pin > 0.5, "the beam sags: {by_pin}");
    assert!(
        (by_attachment - by_pin).abs() <= 0.01 * by_pin,
        "pins {by_pin}, hard attachment {by_attachment}"
    );
    // let go: the beam falls
    let attachment = sim
        .world_mut()
        .query_filtered::<Entity, With<Attachment>>()
        .single(sim.world())
        .expect("one attachment");
    let body = sim.bodies()[0];
    let held = lowest(&sim, body);
    sim.world_mut().despawn(attachment);
    sim.run(30);
    let fallen = held - lowest(&sim, body);
    assert!(fallen > 0.5, "it fell {fallen} m");
}

/// The `soft_beam`'s tip sag at the end (h) and its largest edge strain over the run,
/// under `solver`, with its edges (`edges`) or without.
fn soft_beam(solver: SolverMode, edges: bool) -> (f32, f64) {
    let mut scene = cleave::io::scene::builtin("soft_beam", 0).expect("built in");
    scene.config.solver = solver;
    if !edges {
        scene.bodies[0].material.edge_compliance = None;
    }
    let mut sim = Simulation::from_scene(&scene).expect("a simulation");
    let body = sim.bodies()[0];
    let tip = |sim: &Simulation| {
        let world = sim.world();
        let lattice = &world.get::<BodyLattice>(body).expect("a body").lattice;
        let end = lattice.live_particles().map(|i| lattice.coord(i).x).max();
        let tip: Vec<f32> = sim
            .positions(body)
            .expect("a body")
            .into_iter()
            .filter(|(i, _)| Some(lattice.coord(*i).x) == end)
            .map(|(_, p)| p.y)
            .collect();
        tip.iter().sum::<f32>() / tip.len() as f32
    };
    let start = tip(&sim);
    let mut strain: f64 = 0.0;
    for _ in 0..scene.frames / 5 {
        sim.run(5);
        let stats = body_stats(sim.world_mut(), body).expect("a body");
        strain = strain.max(stats.max_edge_strain);
    }
    ((start - tip(&sim)) / 0.1, strain)
}

#[test]
fn a_soft_beam_with_stiff_edges_bends_but_barely_stretches_under_every_scheme() {
    let runs: Vec<(SolverMode, f32, f64)> = SolverMode::ALL
        .into_iter()
        .map(|solver| {
            let (sag, strain) = soft_beam(solver, true);
            (solver, sag, strain)
        })
        .collect();
    let (_, jacobi_sag, _) = runs[0];
    for &(solver, sag, strain) in &runs {
        assert!(sag >= 5.0, "{solver}: sags {sag} h");
        assert!(strain < 0.01, "{solver}: edges stretched {strain}");
        assert!(
            (sag - jacobi_sag).abs() <= 0.05 * jacobi_sag,
            "{solver}: sag {sag} h against Jacobi's {jacobi_sag} h"
        );
    }
    // the same bar without its edges: its soft clusters let it stretch
    let (sag, strain) = soft_beam(SolverMode::Jacobi, false);
    let with = runs.iter().map(|r| r.2).fold(0.0, f64::max);
    assert!(
        strain > 5.0 * with,
        "edges off: strain {strain}, on: {with}"
    );
    assert!(sag > jacobi_sag, "edges off: sag {sag} h");
}

#[test]
fn severed_edges_lose_their_constraint_at_once() {
    // the soft beam cut through by a severing blade at its middle: its far half drops
    // away instead of hanging on by the edges
    let mut scene = cleave::io::scene::builtin("soft_beam", 0).expect("built in");
    let at = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    scene.tools = vec![ToolDesc {
        shape: ToolShape::Blade {
            half_width: 1.0,
            half_height: 0.3,
        },
        cut_width: 0.05,
        cut_mode: CutMode::Sever,
        path: Path {
            keys: vec![(0.0, at(1.6)), (0.05, at(0.4))],
        },
        pose: at(1.6),
    }];
    scene.bodies[0].material.edge_compliance = Some(0.0);
    let mut sim = Simulation::from_scene(&scene).expect("a simulation");
    let body = sim.bodies()[0];
    sim.run(60);
    let pieces = sim.pieces(body).expect("a body");
    assert_eq!(pieces.len(), 2);
    let positions: Vec<Vec3> = sim
        .positions(body)
        .expect("a body")
        .iter()
        .map(|p| p.1)
        .collect();
    let gap = pieces[0]
        .iter()
        .flat_map(|&a| pieces[1].iter().map(move |&b| (a, b)))
        .map(|(a, b)| positions[a as usize].distance(positions[b as usize]))
        .fold(f32::INFINITY, f32::min);
    assert!(gap > 1.0, "the far half fell away: {gap} m apart");
    assert!(check_invariants(sim.world()).is_empty());
}

#[test]
fn bad_attachments_and_edge_compliances_are_errors_naming_the_field() {
    let err = |r: cleave::error::Result<Entity>| r.expect_err("refused").to_string();
    let mut sim = Simulation::new(SimConfig::default()).expect("a simulation");
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(4, 4, 4)), 0.1);
    desc.position = Vec3::new(0.0, 0.5, 0.0);
    for bad in [-1e-6, f32::NAN, f32::INFINITY] {
        let mut d = desc.clone();
        d.material.edge_compliance = Some(bad);
        assert!(
            err(sim.spawn_body(&d)).contains("material.edge_compliance"),
            "{bad}"
        );
        let mut d = desc.clone();
        d.attachments = vec![AttachmentDesc {
            region: Region {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            },
            path: Path::default(),
            compliance: bad,
            hold: Hold::Each,
        }];
        assert!(
            err(sim.spawn_body(&d)).contains("body.attachments[0].compliance"),
            "{bad}"
        );
    }
    let attached = |region: Region, path: Path| {
        let mut d = desc.clone();
        d.attachments = vec![AttachmentDesc {
            region,
            path,
            compliance: 0.0,
            hold: Hold::Each,
        }];
        d
    };
    let everywhere = Region {
        min: Vec3::splat(-1.0),
        max: Vec3::splat(1.0),
    };
    let nowhere = Region {
        min: Vec3::splat(5.0),
        max: Vec3::splat(6.0),
    };
    assert!(
        err(sim.spawn_body(&attached(nowhere, Path::default())))
            .contains("body.attachments[0].region")
    );
    let keys = |times: [f32; 2]| Path {
        keys: times.map(|t| (t, Pose::at(Vec3::ZERO))).to_vec(),
    };
    for times in [[1.0, 0.5], [0.0, f32::NAN]] {
        let e = err(sim.spawn_body(&attached(everywhere, keys(times))));
        assert!(
            e.contains("body.attachments[0].path[1].time"),
            "{times:?}: {e}"
        );
    }
    // at run time: a body, live particles and a compliance are required
    let body = sim.spawn_body(&desc).expect("a body");
    assert!(err(sim.attach(body, &[0], f32::NAN)).contains("attachment.compliance"));
    assert!(err(sim.attach(body, &[], 0.0)).contains("at least one particle"));
    assert!(err(sim.attach(body, &[999], 0.0)).contains("not live"));
    let tool = sim.world_mut().spawn_empty().id();
    assert!(err(sim.attach(tool, &[0], 0.0)).contains("is not a body"));
    assert!(sim.move_attachment(tool, Pose::at(Vec3::ZERO)).is_err());
    let ok = sim.attach(body, &[0, 1], 1e-3).expect("attached");
    assert!(sim.move_attachment(ok, Pose::at(Vec3::Y)).is_ok());
    sim.run(2);
    assert!(check_invariants(sim.world()).is_empty());
}
