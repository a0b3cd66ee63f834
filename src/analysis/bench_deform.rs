//! `cleave bench --deform`: what handle deformation costs on n³ boxes — the subspace's
//! weights `W` precomputed (16³ and 32³, 10 point handles), the pose `V = V̄ + W ΔH` at
//! 64³ with 20 point handles, full ARAP per iteration at 32³, and one frame of reduced
//! ARAP and of reduced projective dynamics at 64³ (their iterations and the pose of
//! every particle), each a median of timed runs.
//!
//! The 64³ box's `W` is not factored there: the smoothness energy couples particles
//! two cells apart, and its sparse factor grows past what the machine holds (at 40³ it
//! already takes 14.5 s and 1.2 GB). It is the `W` of the 32³ box of the same extent
//! (twice the spacing, the handles on its particles), interpolated to the 64³
//! particles by tensor-product linear interpolation between the coarse particles
//! (extrapolated at the faces), which reproduces affine maps exactly. What a frame
//! costs depends on the size of `W`, not on its values.

use crate::analysis::bench::time_ms;
use crate::body::lattice::Lattice;
use crate::body::shape::Shape;
use crate::clusters::clustering::clusters_on_grid;
use crate::config::Material;
use crate::deform::arap::{Arap, ArapOptions};
use crate::deform::handles::{Handle, HandleSet, HandleTarget};
use crate::deform::reduced::arap::ReducedArap;
use crate::deform::reduced::auto_handles;
use crate::deform::reduced::dynamics::{ReducedDynamics, cubature};
use crate::deform::weights::Weights;
use crate::error::Result;
use glam::{Affine3A, IVec3, Quat, UVec3, Vec3};
use serde::Serialize;
use std::time::Instant;

/// Lattice spacing of the benchmark boxes, m.
const H: f32 = 0.1;
/// Local–global iterations of a reduced frame.
const REDUCED_ITERATIONS: u32 = 10;
/// Point handles placed automatically for the reduced solves.
const AUTO_HANDLES: usize = 30;
/// Rotation groups of reduced ARAP: blocks of this many cells a side.
const GROUP_CELLS: u32 = 4;

/// The figures of `cleave bench --deform`, one run.
#[derive(Clone, Debug, Serialize)]
pub struct DeformReport {
    /// Always `"deform"`.
    pub row: &'static str,
    /// Worker threads.
    pub threads: usize,
    /// `W` at 16³ with 10 point handles, ms.
    pub weights_16_ms: f64,
    /// `W` at 32³ with 10 point handles, ms.
    pub weights_32_ms: f64,
    /// `W` at 64³ with 20 point handles, interpolated from the 32³ box's (see the
    /// module doc; once, for the pose below), ms.
    pub weights_64_ms: f64,
    /// `V = V̄ + W ΔH` at 64³ with 20 point handles, median ms.
    pub pose_64_ms: f64,
    /// Full ARAP at 32³ held by two end regions, ms per iteration (median of the
    /// iterations of one timed solve of `arap_iterations`).
    pub arap_32_iteration_ms: f64,
    /// Iterations of that solve.
    pub arap_iterations: u32,
    /// Columns of the reduced solves' subspace at 64³ (the user's handles' and the
    /// automatically placed ones').
    pub reduced_columns: usize,
    /// Reduced ARAP's precompute at 64³ (W and the groups' products), ms.
    pub reduced_arap_precompute_ms: f64,
    /// Rotation groups of reduced ARAP at 64³.
    pub reduced_arap_groups: usize,
    /// One frame of reduced ARAP at 64³ (its iterations and the pose), median ms.
    pub reduced_arap_frame_ms: f64,
    /// Reduced projective dynamics' precompute at 64³, ms.
    pub reduced_dynamics_precompute_ms: f64,
    /// Clusters of the 64³ body.
    pub reduced_dynamics_clusters: usize,
    /// The clusters of their cubature (one per block of 4³ cells): the reduced
    /// dynamics' rotation groups.
    pub reduced_dynamics_cubature: usize,
    /// One frame of reduced projective dynamics at 64³ (a step of its iterations and
    /// the pose), median ms.
    pub reduced_dynamics_frame_ms: f64,
    /// Local–global iterations per reduced frame.
    pub reduced_iterations: u32,
}

fn cube(n: u32) -> Result<(Lattice, Vec<Vec3>)> {
    cube_at(n, H)
}

fn cube_at(n: u32, h: f32) -> Result<(Lattice, Vec<Vec3>)> {
    let lattice = Shape::cuboid(UVec3::splat(n)).voxelise(h)?;
    let rest = (0..lattice.len() as u32)
        .map(|i| lattice.rest_position(i))
        .collect();
    Ok((lattice, rest))
}

fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// The weights of particles resting at `rest` interpolated from `coarse`'s weights
/// `w` (see the module doc); a particle whose coarse cell lacks a corner keeps the
/// row of its nearest corner.
fn prolong(coarse: &Lattice, w: &Weights, rest: &[Vec3]) -> Weights {
    let h = w.columns();
    let spacing = coarse.spacing();
    let (lo, hi) = coarse
        .live_particles()
        .map(|i| coarse.coord(i))
        .fold((IVec3::MAX, IVec3::MIN), |(a, b), c| (a.min(c), b.max(c)));
    let mut dense = vec![0.0f64; rest.len() * h];
    let mut row = vec![0.0f64; h];
    for (p, out) in rest.iter().zip(dense.chunks_mut(h)) {
        let u = *p / spacing - Vec3::splat(0.5);
        let base = u.floor().as_ivec3().clamp(lo, (hi - IVec3::ONE).max(lo));
        let t = u - base.as_vec3();
        for corner in 0..8 {
            let step = IVec3::new(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
            let f = step.as_vec3();
            let weight = (f * t + (Vec3::ONE - f) * (Vec3::ONE - t)).element_product();
            let at = coarse.at(base + step).or_else(|| coarse.at(base));
            if let Some(c) = at {
                w.row_into(c, &mut row);
                for (o, r) in out.iter_mut().zip(&row) {
                    *o += weight as f64 * r;
                }
            }
        }
    }
    Weights::from_dense(&dense, h, rest)
}

/// The box's two end layers along x, as region handles.
fn end_regions(lattice: &Lattice) -> Vec<Handle> {
    let xs = lattice.live_particles().map(|i| lattice.coord(i).x);
    let (lo, hi) = xs.fold((i32::MAX, i32::MIN), |(a, b), x| (a.min(x), b.max(x)));
    [lo, hi]
        .map(|end| {
            Handle::Region(
                lattice
                    .live_particles()
                    .filter(|&i| lattice.coord(i).x == end)
                    .collect(),
            )
        })
        .to_vec()
}

/// The second end region turned and moved: a bend.
fn bent_targets(set: &HandleSet, rest: &[Vec3]) -> Vec<HandleTarget> {
    let c = set.rest_centroid(1, rest);
    let map = Affine3A::from_translation(c + Vec3::new(-0.3, 0.5, 0.0))
        * Affine3A::from_quat(Quat::from_rotation_z(0.8))
        * Affine3A::from_translation(-c);
    vec![
        HandleTarget::Affine(Affine3A::IDENTITY),
        HandleTarget::Affine(map),
    ]
}

/// Runs the benchmark with `runs` timed runs of each per-frame figure.
pub fn bench_deform(runs: usize) -> Result<DeformReport> {
    let runs = runs.max(1);
    let no_limit = u64::MAX;
    let points = |lattice: &Lattice, rest: &[Vec3], count| {
        HandleSet::new(lattice, auto_handles(lattice, rest, &[], count), &[])
    };
    let mut weights_ms = [0.0; 2];
    for (ms, n) in weights_ms.iter_mut().zip([16, 32]) {
        let (lattice, rest) = cube(n)?;
        let set = points(&lattice, &rest, 10)?;
        let start = Instant::now();
        Weights::compute(&lattice, &rest, &set, no_limit)?;
        *ms = ms_since(start);
    }
    let (lattice, rest) = cube(64)?;
    let (coarse, coarse_rest) = cube_at(32, 2.0 * H)?;
    let set = points(&coarse, &coarse_rest, 20)?;
    let start = Instant::now();
    let weights = prolong(
        &coarse,
        &Weights::compute(&coarse, &coarse_rest, &set, no_limit)?,
        &rest,
    );
    let weights_64_ms = ms_since(start);
    let dh: Vec<Vec3> = (0..set.columns())
        .map(|c| Vec3::new(0.01 * c as f32, -0.02, 0.005))
        .collect();
    let mut out = vec![Vec3::ZERO; rest.len()];
    let pose_64_ms = time_ms(runs, || weights.pose(&dh, &mut out));

    let (small, small_rest) = cube(32)?;
    let ends = HandleSet::new(&small, end_regions(&small), &[])?;
    let arap = Arap::new(&small, &small_rest, &ends, no_limit)?;
    let mut x = small_rest.clone();
    let options = ArapOptions {
        tolerance: 0.0,
        max_iterations: 10,
    };
    let start = Instant::now();
    let report = arap.solve(&ends, &bent_targets(&ends, &small_rest), &mut x, &options)?;
    let arap_32_iteration_ms = ms_since(start) / report.iterations.max(1) as f64;

    // reduced ARAP at 64³: the two end regions held, 30 points solved for
    let start = Instant::now();
    let user = end_regions(&coarse);
    let mut handles = user.clone();
    handles.extend(auto_handles(&coarse, &coarse_rest, &user, AUTO_HANDLES));
    let all = HandleSet::new(&coarse, handles, &[])?;
    let ends = HandleSet::new(&coarse, user, &[])?;
    let weights = prolong(
        &coarse,
        &Weights::compute(&coarse, &coarse_rest, &all, no_limit)?,
        &rest,
    );
    let reduced = ReducedArap::new(&lattice, &rest, &weights, ends.columns(), GROUP_CELLS)?;
    let reduced_arap_precompute_ms = ms_since(start);
    let held = ends.displacements(&coarse_rest, &bent_targets(&ends, &coarse_rest))?;
    let options = ArapOptions {
        tolerance: 0.0,
        max_iterations: REDUCED_ITERATIONS,
    };
    // frames in a row, each from the one before (as a game would call it)
    let mut dh = held.clone();
    dh.resize(all.columns(), Vec3::ZERO);
    let mut rotations = reduced.rest_rotations();
    reduced.solve(&mut dh, &mut rotations, &options);
    let reduced_arap_frame_ms = time_ms(runs, || {
        reduced.solve(&mut dh, &mut rotations, &options);
        weights.pose(&dh, &mut out);
    });
    let reduced_arap_groups = crate::deform::reduced::block_groups(&lattice, GROUP_CELLS).1;

    // reduced projective dynamics at 64³: one end held, the body's own clusters
    let start = Instant::now();
    let clusters = clusters_on_grid(&lattice, &Material::default(), IVec3::ZERO).into_clusters();
    let held_end = vec![end_regions(&coarse).swap_remove(0)];
    let fixed = HandleSet::new(&coarse, held_end.clone(), &[])?.columns();
    let mut handles = held_end.clone();
    handles.extend(auto_handles(&coarse, &coarse_rest, &held_end, AUTO_HANDLES));
    let all = HandleSet::new(&coarse, handles, &[])?;
    let weights = prolong(
        &coarse,
        &Weights::compute(&coarse, &coarse_rest, &all, no_limit)?,
        &rest,
    );
    let sampled = cubature(&clusters, lattice.coords(), GROUP_CELLS);
    let dynamics = ReducedDynamics::new(&weights, &rest, &sampled, 1e-3, 1e6, 1.0 / 60.0, fixed)?;
    let reduced_dynamics_precompute_ms = ms_since(start);
    let mut state = dynamics.rest_state();
    let still = vec![Vec3::ZERO; fixed];
    let gravity = Vec3::new(0.0, -9.81, 0.0);
    let reduced_dynamics_frame_ms = time_ms(runs, || {
        dynamics.step(&mut state, &still, gravity, REDUCED_ITERATIONS);
        weights.pose(&state.displacements(), &mut out);
    });
    Ok(DeformReport {
        row: "deform",
        threads: rayon::current_num_threads(),
        weights_16_ms: weights_ms[0],
        weights_32_ms: weights_ms[1],
        weights_64_ms,
        pose_64_ms,
        arap_32_iteration_ms,
        arap_iterations: report.iterations,
        reduced_columns: all.columns(),
        reduced_arap_precompute_ms,
        reduced_arap_groups,
        reduced_arap_frame_ms,
        reduced_dynamics_precompute_ms,
        reduced_dynamics_clusters: clusters.len(),
        reduced_dynamics_cubature: sampled.len(),
        reduced_dynamics_frame_ms,
        reduced_iterations: REDUCED_ITERATIONS,
    })
}
