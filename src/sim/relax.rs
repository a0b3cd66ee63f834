//! Relaxation (SPEC §6.1, Yuksel et al. 2012): a body spawned out of its rest shape —
//! jittered, overlapping another, loaded deformed — settles into it without drifting.
//!
//! The body is run, frame after frame, with gravity off and strong mass-proportional
//! damping (every particle's velocity decays as `exp(−damping · t)`), while
//! - hard centroid holds ([`crate::solver::terms::centroids`]) keep the centroid of every
//!   boundary set ([`crate::body::patches::boundary_sets`]) where it started, so the
//!   body cannot wander off or turn, and
//! - the anisotropic patch constraints ([`crate::solver::terms::patches`]) keep its
//!   surface in place against the body beneath it,
//!
//! until its particles' rms speed falls under the tolerance. Only the body moves: the
//! other bodies are held still by hard attachments for the while (and get their
//! positions and velocities back), no tool or collider moves, nothing is cut, and the
//! simulation's clock does not advance. Everything the relaxation set up is taken down
//! afterwards.

use crate::body::patches::boundary_sets;
use crate::config::RelaxOptions;
use crate::ecs::components::{BodyLattice, InvMass, Position, Velocity};
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{SimSettings, SubstepClock};
use crate::error::{CleaveError, Result};
use crate::math::rigid_fit::rigid_fit_error;
use crate::sim::relax_report::{RelaxReport, RelaxReports};
use crate::sim::simulation::Simulation;
use crate::systems::{SubstepSchedule, SyncSchedule, store::store_particles};
use bevy_ecs::message::message_update_system;
use bevy_ecs::prelude::*;
use glam::{DVec3, Vec3};

/// The live particles of one body: body-local indices, entities, rest positions.
struct BodyParticles {
    local: Vec<u32>,
    entities: Vec<Entity>,
    rest: Vec<Vec3>,
    spacing: f32,
}

impl BodyParticles {
    fn of(world: &World, body: Entity) -> Result<Self> {
        let lattice = world
            .get::<BodyLattice>(body)
            .ok_or_else(|| CleaveError::not_a("a body", body))?;
        let local: Vec<u32> = lattice.lattice.live_particles().collect();
        Ok(Self {
            entities: local
                .iter()
                .map(|&i| lattice.particles[i as usize])
                .collect(),
            rest: local
                .iter()
                .map(|&i| lattice.lattice.rest_position(i))
                .collect(),
            spacing: lattice.lattice.spacing(),
            local,
        })
    }

    fn read<T: Component + Copy>(&self, world: &World) -> Result<Vec<T>> {
        self.entities
            .iter()
            .map(|&e| {
                world.get::<T>(e).copied().ok_or_else(|| {
                    CleaveError::InvalidEntity(format!("particle {e} has lost its components"))
                })
            })
            .collect()
    }

    /// The centroid of each set of body-local particles.
    fn centroids(&self, world: &World, sets: &[Vec<u32>]) -> Result<Vec<DVec3>> {
        let positions = self.read::<Position>(world)?;
        Ok(sets
            .iter()
            .map(|set| {
                let sum: DVec3 = set
                    .iter()
                    .filter_map(|p| self.local.binary_search(p).ok())
                    .map(|k| positions[k].0.as_dvec3())
                    .sum();
                sum / set.len().max(1) as f64
            })
            .collect())
    }

    /// Rms distance from the best rigid placement of the rest shape, in spacings.
    fn shape_error(&self, world: &World) -> Result<f64> {
        let positions: Vec<Vec3> = self.read::<Position>(world)?.iter().map(|p| p.0).collect();
        Ok((rigid_fit_error(&self.rest, &positions) / self.spacing) as f64)
    }

    /// The kinetic energy (J) and rms speed (spacings per second).
    fn motion(&self, world: &World) -> Result<(f64, f64)> {
        let velocities = self.read::<Velocity>(world)?;
        let inv_mass = self.read::<InvMass>(world)?;
        let (mut energy, mut squares) = (0.0f64, 0.0f64);
        for (v, w) in velocities.iter().zip(&inv_mass) {
            let v2 = v.0.as_dvec3().length_squared();
            squares += v2;
            if w.0 > 0.0 {
                energy += 0.5 * v2 / w.0 as f64;
            }
        }
        let rms = (squares / self.local.len().max(1) as f64).sqrt() / self.spacing as f64;
        Ok((energy, rms))
    }
}

/// One frame of the solve alone: layout and terms brought up to date, the substeps,
/// the state stored; no pose moves, no cut, no clock.
fn relax_frame(world: &mut World) -> Result<()> {
    world.run_system_cached(message_update_system).ok();
    world.run_schedule(SyncSchedule);
    let substeps = world.resource::<SimSettings>().0.substeps;
    for index in 0..substeps {
        *world.resource_mut::<SubstepClock>() = SubstepClock {
            index,
            count: substeps,
        };
        world.run_schedule(SubstepSchedule);
    }
    world
        .run_system_cached(store_particles)
        .map_err(|e| CleaveError::InvalidEntity(format!("store stage: {e}")))
}

/// Tells the terms that `body`'s material changed.
fn material_changed(world: &mut World, body: Entity) {
    let mut cache = world.resource_mut::<SolverCache>();
    cache.layout.body_changed(body);
}

impl Simulation {
    /// Relaxes `body` into its rest shape (see [`crate::sim::relax`]); the other bodies
    /// stay where they are. An error if `body` is not a body or `options` is invalid.
    pub fn relax(&mut self, body: Entity, options: &RelaxOptions) -> Result<RelaxReport> {
        options.validate()?;
        let particles = BodyParticles::of(self.world(), body)?;
        // measured whether or not they are held
        let sets = match self.world().get::<BodyLattice>(body) {
            Some(lattice) => boundary_sets(&lattice.lattice, options.boundary_cells),
            None => Vec::new(),
        };
        let started = particles.centroids(self.world(), &sets)?;
        let shape_error_before = particles.shape_error(self.world())?;
        // the others held still, their velocities kept
        let mut others = Vec::new();
        for other in self.bodies().into_iter().filter(|&b| b != body) {
            let held = BodyParticles::of(self.world(), other)?;
            if held.local.is_empty() {
                continue;
            }
            let state = (
                held.read::<Position>(self.world())?,
                held.read::<Velocity>(self.world())?,
            );
            let pin = self.attach(other, &held.local, 0.0)?;
            others.push((held, state, pin));
        }
        let mut holds = Vec::new();
        for set in sets.iter().filter(|_| options.centroids) {
            holds.push(self.hold_centroid(body, set, 0.0)?);
        }
        let material = {
            let mut body_component = self
                .world_mut()
                .get_mut::<crate::ecs::components::Body>(body)
                .ok_or_else(|| CleaveError::not_a("a body", body))?;
            let kept = body_component.material.clone();
            if options.patches && kept.patch_normal_compliance.is_none() {
                body_component.material.patch_normal_compliance = Some(kept.compliance);
            } else if !options.patches {
                body_component.material.patch_normal_compliance = None;
            }
            kept
        };
        material_changed(self.world_mut(), body);
        let settings = self.config().clone();
        let mut relaxing = settings.clone();
        relaxing.gravity = Vec3::ZERO;
        relaxing.damping = options.damping;
        self.world_mut().resource_mut::<SimSettings>().0 = relaxing;

        let mut frames = 0;
        let mut outcome = Ok(false);
        while frames < options.max_frames {
            if let Err(e) = relax_frame(self.world_mut()) {
                outcome = Err(e);
                break;
            }
            frames += 1;
            match particles.motion(self.world()) {
                Ok((_, rms)) if rms < options.tolerance as f64 => {
                    outcome = Ok(true);
                    break;
                }
                Ok(_) => {}
                Err(e) => {
                    outcome = Err(e);
                    break;
                }
            }
        }

        // taken down whatever happened
        self.world_mut().resource_mut::<SimSettings>().0 = settings;
        if let Some(mut b) = self
            .world_mut()
            .get_mut::<crate::ecs::components::Body>(body)
        {
            b.material = material;
        }
        material_changed(self.world_mut(), body);
        let drift = particles
            .centroids(self.world(), &sets)?
            .iter()
            .zip(&started)
            .map(|(now, then)| now.distance(*then) / particles.spacing as f64)
            .fold(0.0, f64::max);
        for hold in holds {
            self.detach(hold)?;
        }
        // a pin places its particles through a pose, within rounding of where they were
        for (held, (positions, velocities), pin) in others {
            self.detach(pin)?;
            for ((e, x), v) in held.entities.iter().zip(positions).zip(velocities) {
                self.world_mut().entity_mut(*e).insert((x, v));
            }
        }
        self.update_surfaces()?;
        let converged = outcome?;
        let (kinetic_energy, rms_speed) = particles.motion(self.world())?;
        Ok(RelaxReport {
            frames,
            converged,
            rms_speed,
            kinetic_energy,
            shape_error_before,
            shape_error: particles.shape_error(self.world())?,
            boundary_sets: sets.len(),
            boundary_drift: drift,
        })
    }

    /// The reports of the relaxations [`Simulation::from_scene`] ran, by body.
    pub fn relax_reports(&self) -> &[(Entity, RelaxReport)] {
        self.world()
            .get_resource::<RelaxReports>()
            .map_or(&[], |r| r.0.as_slice())
    }
}
