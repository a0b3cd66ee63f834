//! Cutting and grabbing a running simulation by pointer, as a viewer or a game's input
//! drives them. A stroke across the view becomes a blade that turns about the eye
//! through the stroke's plane over a few frames ([`crate::cut::stroke`]); a press on a
//! body grabs the particles under the pointer by a stiff spring whose target then
//! follows the pointer at the depth it grabbed them.
//!
//! Call [`Interaction::before_step`] before every [`Simulation::step`]: it moves the
//! blades of strokes under way and lets go of a blade whose sweep is done.

use super::simulation::Simulation;
use crate::cut::stroke::stroke_cut;
use crate::cut::tool::{CutMode, Path, Pose};
use crate::ecs::components::{AttachmentTarget, BodyLattice};
use crate::ecs::desc::ToolDesc;
use crate::error::{CleaveError, MAX_COORDINATE, Result, check_vec_within};
use bevy_ecs::prelude::*;
use glam::Vec3;
use std::collections::VecDeque;

/// Compliance of a grab's springs, m/N: stiff enough that a grabbed block of a few
/// tonnes hangs within a millimetre of the pointer, soft enough that a grab never
/// fights the body's own constraints as a pin would.
pub const GRAB_COMPLIANCE: f32 = 1e-7;

/// How far from the grabbed particle (in lattice spacings, in the body's current
/// shape) the particles a grab holds reach.
pub const GRAB_RADIUS: f32 = 1.6;

/// Cut width of a stroke's blade, in lattice spacings of the coarsest body: a little
/// over one, so that a sever or a removal parts the body along the whole stroke.
pub const STROKE_CUT_WIDTH: f32 = 1.01;

/// What a grab holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grab {
    /// The grabbed body.
    pub body: Entity,
    /// The attachment holding it ([`Simulation::attach`]).
    pub attachment: Entity,
    /// How far along the pointer's ray the grabbed particle was, m.
    pub depth: f32,
    /// Where the attachment's target sits from the grabbed particle (the target is at
    /// the held particles' centroid).
    pub offset: Vec3,
}

/// The strokes under way and the grab, if any, of one simulation.
#[derive(Debug, Default)]
pub struct Interaction {
    strokes: Vec<(Entity, VecDeque<Pose>)>,
    grab: Option<Grab>,
}

impl Interaction {
    /// No strokes, no grab.
    pub fn new() -> Self {
        Self::default()
    }

    /// The grab, if one is held.
    pub fn grab(&self) -> Option<Grab> {
        self.grab
    }

    /// How many strokes are still sweeping.
    pub fn strokes_under_way(&self) -> usize {
        self.strokes.len()
    }

    /// Starts a cut along a stroke seen from `eye`, from the ray toward `from` to the
    /// ray toward `to`, cutting in `mode`: a blade reaching past every body turns
    /// through the stroke's plane over the next frames. Errors as
    /// [`stroke_cut`]'s.
    pub fn stroke(
        &mut self,
        sim: &mut Simulation,
        eye: Vec3,
        from: Vec3,
        to: Vec3,
        mode: CutMode,
    ) -> Result<()> {
        let (mut far, mut spacing) = (0.0f32, 0.0f32);
        for body in sim.bodies() {
            for (_, x) in sim.positions(body)? {
                far = far.max(x.distance(eye));
            }
            if let Some(l) = sim.world().get::<BodyLattice>(body) {
                spacing = spacing.max(l.lattice.spacing());
            }
        }
        if spacing == 0.0 {
            return Err(CleaveError::InvalidEntity(
                "stroke: there is no body to cut".into(),
            ));
        }
        let cut = stroke_cut(
            eye,
            from,
            to,
            0.0,
            (far + 2.0 * spacing).min(MAX_COORDINATE),
        )?;
        let mut poses: VecDeque<Pose> = cut.poses.into();
        // a stroke has a pose per frame plus its start, at least two
        let start = poses.pop_front().expect("a sweep has poses");
        let tool = sim.spawn_tool(&ToolDesc {
            shape: cut.shape,
            cut_width: STROKE_CUT_WIDTH * spacing,
            cut_mode: mode,
            path: Path::default(),
            pose: start,
        })?;
        self.strokes.push((tool, poses));
        Ok(())
    }

    /// Grabs the particle nearest the eye among those within one lattice spacing of
    /// the ray from `eye` along `direction`, with the particles of its piece around it
    /// ([`GRAB_RADIUS`]); lets go of any earlier grab first. `Ok(None)`: nothing under
    /// the pointer. An error for a non-finite or zero ray.
    pub fn press(
        &mut self,
        sim: &mut Simulation,
        eye: Vec3,
        direction: Vec3,
    ) -> Result<Option<Grab>> {
        let direction = ray(eye, direction)?;
        self.release(sim)?;
        let mut best: Option<Picked> = None;
        for body in sim.bodies() {
            let Some(h) = sim
                .world()
                .get::<BodyLattice>(body)
                .map(|l| l.lattice.spacing())
            else {
                continue;
            };
            let positions = sim.positions(body)?;
            let nearest = positions
                .iter()
                .map(|&(p, x)| ((x - eye).dot(direction), p, x))
                .filter(|&(t, _, x)| t > 0.0 && (x - eye - t * direction).length() <= h)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((depth, particle, at)) = nearest
                && best.as_ref().is_none_or(|b| depth < b.depth)
            {
                best = Some(Picked {
                    depth,
                    particle,
                    at,
                    body,
                    positions,
                    spacing: h,
                });
            }
        }
        let Some(Picked {
            depth,
            particle: picked,
            at,
            body,
            positions,
            spacing: h,
        }) = best
        else {
            return Ok(None);
        };
        let piece = &sim
            .world()
            .get::<BodyLattice>(body)
            .ok_or_else(|| CleaveError::not_a("a body", body))?
            .lattice
            .pieces()
            .label;
        let held: Vec<u32> = positions
            .into_iter()
            .filter(|&(p, x)| {
                piece[p as usize] == piece[picked as usize] && x.distance(at) <= GRAB_RADIUS * h
            })
            .map(|(p, _)| p)
            .collect();
        let attachment = sim.attach(body, &held, GRAB_COMPLIANCE)?;
        let target = sim
            .world()
            .get::<AttachmentTarget>(attachment)
            .ok_or_else(|| CleaveError::not_a("an attachment", attachment))?
            .pose;
        let grab = Grab {
            body,
            attachment,
            depth,
            offset: target.position - at,
        };
        self.grab = Some(grab);
        Ok(Some(grab))
    }

    /// Moves the grab's target to the grabbed depth along the ray from `eye` along
    /// `direction` (the held particles follow over the next frame); nothing without a
    /// grab. An error for a non-finite or zero ray.
    pub fn drag(&mut self, sim: &mut Simulation, eye: Vec3, direction: Vec3) -> Result<()> {
        let direction = ray(eye, direction)?;
        let Some(grab) = self.grab else {
            return Ok(());
        };
        let target = eye + grab.depth * direction + grab.offset;
        sim.move_attachment(grab.attachment, Pose::at(target))
    }

    /// Lets go of the grab, if any.
    pub fn release(&mut self, sim: &mut Simulation) -> Result<()> {
        if let Some(grab) = self.grab.take() {
            sim.detach(grab.attachment)?;
        }
        Ok(())
    }

    /// Moves every stroke's blade to its pose at the end of the coming frame, and lets
    /// go of the blades whose sweep the last frame finished.
    pub fn before_step(&mut self, sim: &mut Simulation) -> Result<()> {
        let mut result = Ok(());
        self.strokes
            .retain_mut(|(tool, poses)| match poses.pop_front() {
                Some(pose) => {
                    if let Err(e) = sim.set_tool_pose(*tool, pose) {
                        result = Err(e);
                    }
                    true
                }
                None => {
                    sim.world_mut().despawn(*tool);
                    false
                }
            });
        result
    }
}

/// The particle nearest the eye along a pointer's ray, with its body's positions.
struct Picked {
    /// How far along the ray it is.
    depth: f32,
    particle: u32,
    at: Vec3,
    body: Entity,
    positions: Vec<(u32, Vec3)>,
    spacing: f32,
}

/// `direction` normalised, after checking the ray.
fn ray(eye: Vec3, direction: Vec3) -> Result<Vec3> {
    check_vec_within("ray.eye", eye, &crate::error::POSITION)?;
    direction
        .try_normalize()
        .ok_or_else(|| CleaveError::InvalidEntity(format!("ray: {direction} is not a direction")))
}
