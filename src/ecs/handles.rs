//! A body's handles in the simulation. Simulated, a body is driven by its handles as
//! soft attachments (spawned with it, [`spawn_handle_attachments`]). Posed
//! ([`pose_by_handles`]), its particles are kinematic and follow the handles exactly:
//! each frame the pose stage (`systems/pose_handles.rs`) places them at the subspace's
//! pose `V̄ + W ΔH`, at ARAP's, or at reduced ARAP's, by giving each the velocity that
//! brings it there by the frame's end; contacts and other bodies meet it as a
//! kinematic mover.

use crate::body::lattice::Lattice;
use crate::config::SimConfig;
use crate::cut::tool::{Path, Pose};
use crate::deform::arap::{Arap, ArapOptions};
use crate::deform::handles::{Handle, HandleSet, HandleTarget};
use crate::deform::keys::HandlePath;
use crate::deform::reduced::arap::ReducedArap;
use crate::deform::reduced::auto_handles;
use crate::deform::weights::Weights;
use crate::ecs::attach::{TargetMotion, check_compliance, pinned_particles, spawn_attachment};
use crate::ecs::components::*;
use crate::ecs::desc::HandleDesc;
use crate::ecs::resources::SimSettings;
use crate::error::{CleaveError, Result};
use bevy_ecs::prelude::*;
use glam::{DMat3, Vec3};

/// How a posed body follows its handles.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PoseMethod {
    /// The linear subspace's pose `V̄ + W ΔH` (SPEC §6.3).
    #[default]
    Linear,
    /// As rigid as possible (SPEC §6.4), from the subspace's pose, to these options.
    Arap(ArapOptions),
    /// As rigid as possible in the span of the subspace (SPEC §6.3's reduction):
    /// `auto_handles` point handles placed automatically are solved for, one rotation
    /// per block of `group_cells`³ cells, each frame from the last.
    Reduced {
        /// Point handles placed automatically (farthest-point sampling).
        auto_handles: usize,
        /// Edge of a rotation group's block, in cells.
        group_cells: u32,
        /// When each frame's solve stops.
        options: ArapOptions,
    },
}

impl PoseMethod {
    /// Reduced ARAP with 24 automatic handles and groups of 2³ cells, 10 iterations a
    /// frame.
    pub fn reduced() -> Self {
        PoseMethod::Reduced {
            auto_handles: 24,
            group_cells: 2,
            options: ArapOptions {
                tolerance: 0.0,
                max_iterations: 10,
            },
        }
    }
}

/// What poses a body: the subspace's weights, and what solves on them.
#[derive(Debug)]
pub(crate) enum Poser {
    /// `V̄ + W ΔH`.
    Linear(Weights),
    /// ARAP from `V̄ + W ΔH`.
    Arap(Weights, Arap, ArapOptions),
    /// Reduced ARAP: the weights of the user's handles and the automatic ones, the
    /// solver, and the last frame's parameters and rotations to start from.
    Reduced {
        weights: Weights,
        solver: ReducedArap,
        options: ArapOptions,
        dh: Vec<Vec3>,
        rotations: Vec<DMat3>,
    },
}

/// A body posed by its handles: the handles, their paths, the precomputed subspace
/// (and ARAP problem), rebuilt when a cut changes the body.
#[derive(Component, Debug)]
pub struct HandlePose {
    /// The handles, checked against the body.
    pub set: HandleSet,
    /// Each handle's path (an empty one leaves the target to game code).
    pub paths: Vec<HandlePath>,
    /// Each handle's target: set from its path each frame, or by game code.
    pub targets: Vec<HandleTarget>,
    /// How the body follows them.
    pub method: PoseMethod,
    /// The particles' rest positions `V̄` (world space, when posing began), by index.
    pub rest: Vec<Vec3>,
    pub(crate) poser: Poser,
    /// The lattice's live particles and links when the subspace was computed.
    pub(crate) topology: (usize, usize),
}

/// A [`HandlePose`] as a save keeps it (see [`HandlePose::saved`]).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub(crate) struct SavedHandlePose {
    handles: Vec<Handle>,
    paths: Vec<HandlePath>,
    targets: Vec<HandleTarget>,
    method: PoseMethod,
    rest: Vec<Vec3>,
    topology: (usize, usize),
    /// Reduced ARAP's parameters and rotations of the last frame.
    warm: Option<(Vec<Vec3>, Vec<DMat3>)>,
}

/// Checks a body's handle descriptions (finite regions, compliances, paths); errors
/// name `body.handles[i]`.
pub fn check_handles(handles: &mut [HandleDesc]) -> Result<()> {
    for (i, h) in handles.iter_mut().enumerate() {
        let field = format!("body.handles[{i}]");
        h.region.validate(&format!("{field}.region"))?;
        check_compliance(&field, h.compliance)?;
        h.path.validate(&field, h.point)?;
    }
    Ok(())
}

/// The particles of each handle: those of `live` whose position `at(i)` lies in its
/// region (a point handle: the one nearest the region's centre; ties to the lowest
/// index). A handle that selects none is an error naming it.
pub fn select_handles(
    handles: &[HandleDesc],
    live: &[u32],
    at: impl Fn(u32) -> Vec3,
) -> Result<Vec<Vec<u32>>> {
    let mut out = Vec::with_capacity(handles.len());
    for (i, h) in handles.iter().enumerate() {
        let inside: Vec<u32> = live
            .iter()
            .copied()
            .filter(|&p| h.region.contains(at(p)))
            .collect();
        if inside.is_empty() {
            return Err(crate::error::out_of_range(
                &format!("body.handles[{i}].region"),
                (h.region.min, h.region.max),
                "a region holding at least one of the body's particles",
            ));
        }
        out.push(if h.point {
            let centre = 0.5 * (h.region.min + h.region.max);
            let nearest = inside.iter().copied().fold(inside[0], |best, p| {
                if at(p).distance_squared(centre) < at(best).distance_squared(centre) {
                    p
                } else {
                    best
                }
            });
            vec![nearest]
        } else {
            inside
        });
    }
    Ok(out)
}

/// Checks that a simulated body's handles move rigidly (a key that scales is an error:
/// attachments hold particles to a rigid pose; `cleave deform` poses by scaling) and
/// as an attachment's path may (no faster than [`crate::error::MAX_SPEED`]).
pub fn check_rigid_keys(handles: &[HandleDesc]) -> Result<()> {
    for (i, h) in handles.iter().enumerate() {
        if let Some(k) = h
            .path
            .keys
            .iter()
            .position(|(_, key)| key.scale != Vec3::ONE)
        {
            return Err(CleaveError::InvalidEntity(format!(
                "body.handles[{i}].path[{k}].scale: a simulated body's handle moves it rigidly \
                 (scale 1); `cleave deform` poses a body by scaling handles"
            )));
        }
        rigid_path(h).validate(&format!("body.handles[{i}]"))?;
    }
    Ok(())
}

/// A handle's keys as an attachment's path (position and rotation).
fn rigid_path(h: &HandleDesc) -> Path {
    let keys = h.path.keys.iter().map(|(t, key)| {
        let pose = Pose {
            position: key.position,
            rotation: key.rotation,
        };
        (*t, pose)
    });
    Path {
        keys: keys.collect(),
    }
}

/// Spawns a simulated body's handles as soft attachments: each holds its particles to
/// a target at their centroid that its path moves (checked by [`check_rigid_keys`]).
pub fn spawn_handle_attachments(
    world: &mut World,
    body: Entity,
    handles: &[HandleDesc],
    particles: Vec<Vec<u32>>,
    at: impl Fn(u32) -> Vec3,
) {
    for (h, particles) in handles.iter().zip(particles) {
        let positions: Vec<Vec3> = particles.iter().map(|&p| at(p)).collect();
        let centroid = positions.iter().sum::<Vec3>() / positions.len() as f32;
        let path = rigid_path(h);
        let motion = if path.keys.is_empty() {
            TargetMotion::Still
        } else {
            TargetMotion::Path(path)
        };
        spawn_attachment(
            world.spawn_empty(),
            body,
            particles,
            &positions,
            h.compliance,
            Hold::Each,
            Pose::at(centroid),
            motion,
        );
    }
}

/// The particles' positions of `body` now, by index (removed ones at their last).
fn positions(world: &World, lattice: &BodyLattice) -> Vec<Vec3> {
    lattice
        .particles
        .iter()
        .map(|&e| world.get::<Position>(e).map_or(Vec3::ZERO, |p| p.0))
        .collect()
}

/// Poses `body` by `handles` from now on: its particles become kinematic (inverse mass
/// 0) and follow the handles by `method` each frame; the handles' particles are chosen
/// where the particles are now, which is also the rest pose `V̄`. The body's hard
/// attachments (pins) still place their particles, and a handle may not hold one;
/// spawn a body to be posed without handles of its own (they would be attachments).
pub fn pose_by_handles(
    world: &mut World,
    body: Entity,
    handles: &[HandleDesc],
    method: PoseMethod,
) -> Result<()> {
    let mut handles = handles.to_vec();
    check_handles(&mut handles)?;
    let pinned = pinned_particles(world, body);
    let lattice = world
        .get::<BodyLattice>(body)
        .ok_or_else(|| CleaveError::not_a("a body", body))?;
    let rest = positions(world, lattice);
    let live: Vec<u32> = lattice.lattice.live_particles().collect();
    let selected = select_handles(&handles, &live, |p| rest[p as usize])?;
    let list = handles
        .iter()
        .zip(selected)
        .map(|(h, ps)| {
            if h.point {
                Handle::Point(ps[0])
            } else {
                Handle::Region(ps)
            }
        })
        .collect();
    let set = HandleSet::new(&lattice.lattice, list, &pinned)?;
    let limit = memory_limit(world);
    let poser = precompute(&lattice.lattice, &rest, &set, method, limit)?;
    let targets = set
        .handles()
        .iter()
        .enumerate()
        .map(|(k, h)| handles[k].path.target(h, set.rest_centroid(k, &rest), 0.0))
        .collect();
    let topology = signature(&lattice.lattice);
    let entities: Vec<Entity> = live
        .iter()
        .map(|&p| lattice.particles[p as usize])
        .collect();
    for e in entities {
        if let Some(mut w) = world.get_mut::<InvMass>(e) {
            w.0 = 0.0;
        }
    }
    world.entity_mut(body).insert(HandlePose {
        set,
        paths: handles.into_iter().map(|h| h.path).collect(),
        targets,
        method,
        rest,
        poser,
        topology,
    });
    Ok(())
}

/// The memory a body's factor may take, bytes.
pub(crate) fn memory_limit(world: &World) -> u64 {
    world.get_resource::<SimSettings>().map_or_else(
        || SimConfig::default().memory_budget_bytes(),
        |s| s.0.memory_budget_bytes(),
    )
}

/// The subspace (and what solves on it) of `set` on `lattice`.
pub(crate) fn precompute(
    lattice: &Lattice,
    rest: &[Vec3],
    set: &HandleSet,
    method: PoseMethod,
    limit: u64,
) -> Result<Poser> {
    Ok(match method {
        PoseMethod::Linear => Poser::Linear(Weights::compute(lattice, rest, set, limit)?),
        PoseMethod::Arap(options) => Poser::Arap(
            Weights::compute(lattice, rest, set, limit)?,
            Arap::new(lattice, rest, set, limit)?,
            options,
        ),
        PoseMethod::Reduced {
            auto_handles: count,
            group_cells,
            options,
        } => {
            // as many automatic handles as the particles leave room for
            let room = lattice.live_count().saturating_sub(set.columns() + 1);
            let mut all = set.handles().to_vec();
            all.extend(auto_handles(lattice, rest, set.handles(), count.min(room)));
            let all = HandleSet::new(lattice, all, &[])?;
            let weights = Weights::compute(lattice, rest, &all, limit)?;
            let solver = ReducedArap::new(lattice, rest, &weights, set.columns(), group_cells)?;
            Poser::Reduced {
                dh: vec![Vec3::ZERO; all.columns()],
                rotations: solver.rest_rotations(),
                weights,
                solver,
                options,
            }
        }
    })
}

/// What a cut changes of a lattice: its live particles and its links.
pub(crate) fn signature(lattice: &Lattice) -> (usize, usize) {
    let links = lattice
        .live_particles()
        .map(|i| lattice.neighbours(i).len())
        .sum();
    (lattice.live_count(), links)
}

impl HandlePose {
    /// The handles' targets at time `t` from their paths (handles without a path keep
    /// the targets game code gave them).
    pub fn follow_paths(&mut self, t: f32) {
        for (k, (path, target)) in self.paths.iter().zip(&mut self.targets).enumerate() {
            if !path.keys.is_empty() {
                let centroid = self.set.rest_centroid(k, &self.rest);
                *target = path.target(&self.set.handles()[k], centroid, t);
            }
        }
    }

    /// After a cut: the handles keep their surviving particles (a handle left with none
    /// is dropped, with its path) and the subspace is computed again for the pieces.
    pub(crate) fn rebuild(&mut self, lattice: &Lattice, memory: u64) -> Result<()> {
        let handles = self.set.handles().to_vec();
        *self = Self::surviving(
            handles,
            self.paths.clone(),
            self.targets.clone(),
            self.method,
            self.rest.clone(),
            lattice,
            memory,
        )?;
        Ok(())
    }

    /// The pose of `handles` (with their paths and targets) on `lattice` as it is now:
    /// each handle keeps its live particles, a handle with none is dropped.
    fn surviving(
        handles: Vec<Handle>,
        paths: Vec<HandlePath>,
        targets: Vec<HandleTarget>,
        method: PoseMethod,
        rest: Vec<Vec3>,
        lattice: &Lattice,
        memory: u64,
    ) -> Result<Self> {
        let mut kept = Vec::new();
        for ((h, path), target) in handles.into_iter().zip(paths).zip(targets) {
            let live: Vec<u32> = h
                .particles()
                .iter()
                .copied()
                .filter(|&p| lattice.is_live(p))
                .collect();
            if live.is_empty() {
                continue;
            }
            let handle = match h {
                Handle::Point(_) => Handle::Point(live[0]),
                Handle::Region(_) => Handle::Region(live),
            };
            kept.push((handle, path, target));
        }
        let set = HandleSet::new(lattice, kept.iter().map(|k| k.0.clone()).collect(), &[])?;
        let poser = precompute(lattice, &rest, &set, method, memory)?;
        Ok(HandlePose {
            set,
            paths: kept.iter().map(|k| k.1.clone()).collect(),
            targets: kept.iter().map(|k| k.2).collect(),
            method,
            rest,
            poser,
            topology: signature(lattice),
        })
    }

    /// The pose as a save keeps it: what it was given and what it carries from frame
    /// to frame (the subspace is computed again on loading).
    pub(crate) fn saved(&self) -> SavedHandlePose {
        SavedHandlePose {
            handles: self.set.handles().to_vec(),
            paths: self.paths.clone(),
            targets: self.targets.clone(),
            method: self.method,
            rest: self.rest.clone(),
            topology: self.topology,
            warm: match &self.poser {
                Poser::Reduced { dh, rotations, .. } => Some((dh.clone(), rotations.clone())),
                _ => None,
            },
        }
    }

    /// The pose a save kept, on the loaded `lattice`: the subspace computed again as
    /// the saved one was. When a cut changed the body after the pose last saw it, the
    /// pose is rebuilt at once, as the saved run's next frame would have.
    pub(crate) fn restore(saved: SavedHandlePose, lattice: &Lattice, memory: u64) -> Result<Self> {
        let SavedHandlePose {
            handles,
            mut paths,
            targets,
            method,
            rest,
            topology,
            warm,
        } = saved;
        let n = handles.len();
        let rest_fits = rest.len() <= lattice.len() && rest.iter().all(|x| x.is_finite());
        let targets_finite = targets.iter().all(|t| match t {
            HandleTarget::Point(x) => x.is_finite(),
            HandleTarget::Affine(map) => map.is_finite(),
        });
        if paths.len() != n || targets.len() != n || !rest_fits || !targets_finite {
            return Err(CleaveError::InvalidEntity(
                "handle pose: its handles, paths, targets and rest places disagree".into(),
            ));
        }
        for path in &mut paths {
            path.validate("handle pose", false)?;
        }
        let mut pose = Self::surviving(handles, paths, targets, method, rest, lattice, memory)?;
        if pose.topology == topology
            && let (Poser::Reduced { dh, rotations, .. }, Some((warm_dh, warm_rotations))) =
                (&mut pose.poser, warm)
        {
            let finite = warm_dh.iter().all(|v| v.is_finite())
                && warm_rotations.iter().all(|r| r.is_finite());
            if !(finite && warm_dh.len() == dh.len() && warm_rotations.len() == rotations.len()) {
                return Err(CleaveError::InvalidEntity(
                    "handle pose: the reduced solve's last frame does not fit it".into(),
                ));
            }
            *dh = warm_dh;
            *rotations = warm_rotations;
        }
        Ok(pose)
    }

    /// Where the body's particles go for the current targets (by index). Reduced ARAP
    /// starts from the last frame's solution and keeps this one for the next.
    pub fn posed(&mut self) -> Result<Vec<Vec3>> {
        let dh = self.set.displacements(&self.rest, &self.targets)?;
        let mut out = vec![Vec3::ZERO; self.rest.len()];
        match &mut self.poser {
            Poser::Linear(weights) => weights.pose(&dh, &mut out),
            Poser::Arap(weights, arap, options) => {
                weights.pose(&dh, &mut out);
                arap.solve(&self.set, &self.targets, &mut out, options)?;
            }
            Poser::Reduced {
                weights,
                solver,
                options,
                dh: all,
                rotations,
            } => {
                all[..dh.len()].copy_from_slice(&dh);
                solver.solve(all, rotations, options);
                weights.pose(all, &mut out);
            }
        }
        Ok(out)
    }
}
