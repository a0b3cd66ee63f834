//! Static solves on a bare solver: one implicit step whose time step is so long
//! that inertia no longer counts ([`STATIC_DT`]), iterated until it settles. This is the
//! equilibrium a body reaches at rest, without running frames; `cleave bench
//! --convergence` times the solvers on it and `cleave fidelity` compares the sag of a
//! cut beam with the sag of the same geometry clustered fresh.

use crate::body::lattice::Lattice;
use crate::clusters::clustering::initial_clusters;
use crate::config::SolverMode;
use crate::cut::tool::Pose;
use crate::ecs::desc::BodyDesc;
use crate::error::Result;
use crate::math::rigid_fit::rigid_fit_error;
use crate::solver::clusters::term::{ClusterSpec, ClusterTerm};
use crate::solver::particles::Particles;
use crate::solver::registry::Terms;
use crate::solver::solve::Solver;
use crate::solver::term::{BodyTopology, ParticleKey, Substep, Topology};
use crate::solver::terms::attachments::{Attachment, Attachments};
use glam::{Quat, Vec3, Vec3A};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

/// A time step long enough that inertia weighs less than a part in 10⁶ against the
/// `cantilever` material's clusters: one solve with it is a static solve.
pub const STATIC_DT: f32 = 10.0;

/// Iterations between two measurements of a static solve.
pub const BLOCK: u32 = 5;

/// A static solve's substep of `iterations` iterations.
fn static_step(iterations: u32) -> Substep {
    Substep {
        dt: STATIC_DT,
        iterations,
        frame_span: [0.0, 1.0],
    }
}

/// A static solve of one body on a bare solver.
pub struct StaticProblem {
    solver: Solver,
    particles: Particles,
    rest: Vec<Vec3>,
    /// Particles (dense) whose mean height is the tip's: those at the largest lattice x.
    tip: Vec<usize>,
    spacing: f32,
}

impl StaticProblem {
    /// The body `desc` (its placement, material and pins) with the live particles of
    /// `lattice` and the given `clusters` (body-local member lists), under `gravity`,
    /// its particles starting at `start(rest position)` (world space).
    pub fn new<'a>(
        desc: &BodyDesc,
        lattice: &Lattice,
        clusters: impl IntoIterator<Item = &'a [u32]>,
        mode: SolverMode,
        gravity: Vec3,
        start: impl Fn(Vec3) -> Vec3,
    ) -> Self {
        let live: Vec<u32> = lattice.live_particles().collect();
        let mut dense = vec![u32::MAX; lattice.len()];
        for (d, i) in live.iter().enumerate() {
            dense[*i as usize] = d as u32;
        }
        let members: Vec<Vec<u32>> = clusters
            .into_iter()
            .map(|m| m.iter().map(|i| dense[*i as usize]).collect())
            .collect();
        let rotation = desc.rotation.normalize();
        let rest: Vec<Vec3> = live
            .iter()
            .map(|&i| desc.position + rotation * lattice.rest_position(i))
            .collect();
        let compliance = desc.material.cluster_compliance(desc.spacing);
        let specs = members.iter().map(|m| ClusterSpec {
            members: m,
            compliance,
            rotation: Quat::IDENTITY,
            plastic: None,
        });
        let mut solver = Solver::new(ClusterTerm::new(&rest, specs, mode), Terms::builtin());
        // the edges, and the pins as the engine spawns them: hard attachments
        let body = BodyTopology {
            id: 0,
            lattice,
            dense: &dense,
            material: &desc.material,
            groups: &Default::default(),
            pieces: lattice.piece_count(),
            changed: true,
        };
        let topology = Topology {
            bodies: &[body],
            relaid: true,
        };
        solver.topology(&topology);
        let pins = desc.pins.iter().map(|pin| {
            let held: Vec<u32> = live
                .iter()
                .zip(&rest)
                .filter(|(_, x)| pin.contains(**x))
                .map(|(i, _)| *i)
                .collect();
            let key = |local| ParticleKey { body: 0, local };
            Attachment {
                particles: held.iter().map(|&i| key(i)).collect(),
                offsets: held
                    .iter()
                    .map(|&i| rest[dense[i as usize] as usize])
                    .collect(),
                compliance: 0.0,
                from: Pose::at(Vec3::ZERO),
                to: Pose::at(Vec3::ZERO),
                velocity: None,
            }
        });
        let mut attachments = Attachments::default();
        attachments.set(pins.collect(), &topology);
        solver.terms.replace(attachments);
        let mut particles = Particles::at_rest(&rest);
        let inv_mass = 1.0 / desc.material.mass_at_spacing(desc.spacing);
        particles.inv_mass.iter_mut().for_each(|w| *w = inv_mass);
        solver.hold_kinematic(&mut particles.inv_mass);
        // the predictions: where gravity would take each free particle in one step
        let dt2 = STATIC_DT * STATIC_DT;
        let start: Vec<Vec3A> = rest.iter().map(|r| Vec3A::from(start(*r))).collect();
        for ((p, s), w) in particles
            .positions
            .iter_mut()
            .zip(&start)
            .zip(&particles.inv_mass)
        {
            *p = if *w == 0.0 {
                *s
            } else {
                *s + Vec3A::from(gravity * dt2)
            };
        }
        solver.solve(&mut particles, &static_step(0));
        solver.restart_from(&mut particles, &start);
        let end = live.iter().map(|&i| lattice.coord(i).x).max().unwrap_or(0);
        let tip = (0..live.len())
            .filter(|&d| lattice.coord(live[d]).x == end)
            .collect();
        StaticProblem {
            solver,
            particles,
            rest,
            tip,
            spacing: desc.spacing,
        }
    }

    /// The body `desc` as spawned (voxelised and clustered with a fixed seed), straight,
    /// under `gravity`.
    pub fn fresh(desc: &BodyDesc, solver: SolverMode, gravity: Vec3) -> Result<Self> {
        Self::fresh_from(desc, solver, gravity, |r| r)
    }

    /// The body `desc` as spawned, `length` tall, twisted a quarter turn about Y from
    /// its bottom to its top, gravity off.
    pub fn twisted(desc: &BodyDesc, length: f32, solver: SolverMode) -> Result<Self> {
        let centre = desc.position;
        let twist = move |r: Vec3| {
            let t = (r.y - centre.y) / length;
            Quat::from_rotation_y(t * std::f32::consts::FRAC_PI_2) * (r - centre) + centre
        };
        Self::fresh_from(desc, solver, Vec3::ZERO, twist)
    }

    fn fresh_from(
        desc: &BodyDesc,
        solver: SolverMode,
        gravity: Vec3,
        start: impl Fn(Vec3) -> Vec3,
    ) -> Result<Self> {
        let lattice = desc.shape.voxelise(desc.spacing)?;
        let table = initial_clusters(&lattice, &desc.material, &mut ChaCha8Rng::seed_from_u64(1));
        let clusters = table.iter().map(|(_, m)| m);
        Ok(Self::new(desc, &lattice, clusters, solver, gravity, start))
    }

    /// [`BLOCK`] more iterations.
    pub fn iterate(&mut self) {
        self.solver
            .iterate(&mut self.particles, &static_step(BLOCK), BLOCK);
    }

    /// Mean drop of the tip particles below their rest height, in spacings.
    pub fn sag(&self) -> f64 {
        let drop: f64 = self
            .tip
            .iter()
            .map(|&d| (self.rest[d].y - self.particles.positions[d].y) as f64)
            .sum();
        drop / self.tip.len().max(1) as f64 / self.spacing as f64
    }

    /// Shape error (RMS distance to the best rigid fit of the rest shape), in spacings.
    pub fn shape_error(&self) -> f64 {
        let current: Vec<Vec3> = self
            .particles
            .positions
            .iter()
            .map(|p| Vec3::from(*p))
            .collect();
        (rigid_fit_error(&self.rest, &current) / self.spacing) as f64
    }

    /// The residual: the root-sum-square net force on the free particles, newtons
    /// ([`Solver::residual`]).
    pub fn residual(&self) -> f64 {
        self.solver.residual(&self.particles, &static_step(0))
    }

    /// Iterates until the sag moves less than `tolerance` spacings in a block (at most
    /// `max_blocks` blocks); returns the sag.
    pub fn settled_sag(&mut self, max_blocks: u32, tolerance: f64) -> f64 {
        let mut sag = self.sag();
        for _ in 0..max_blocks {
            self.iterate();
            let last = std::mem::replace(&mut sag, self.sag());
            if (sag - last).abs() < tolerance {
                break;
            }
        }
        sag
    }

    /// Iterates block by block until `done(measure)` or the budget is spent; returns the
    /// milliseconds and iterations it took (if done) and the last measure.
    pub fn run(
        &mut self,
        budget_seconds: f64,
        measure: impl Fn(&Self) -> f64,
        done: impl Fn(f64) -> bool,
    ) -> (Option<f64>, Option<u32>, f64) {
        let (mut ms, mut iterations) = (0.0, 0);
        let mut last = measure(self);
        while !done(last) {
            if ms > budget_seconds * 1e3 || !last.is_finite() {
                return (None, None, last);
            }
            let start = Instant::now();
            self.iterate();
            ms += start.elapsed().as_secs_f64() * 1e3;
            iterations += BLOCK;
            last = measure(self);
        }
        (Some(ms), Some(iterations), last)
    }
}
