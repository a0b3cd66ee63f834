//! `cleave bench --surface`: what a body's drawable surface costs on an n³ box — the
//! surface stage's per-frame update (particles' frames, vertex positions and normals;
//! and, at rest, the test that keeps the surface),
//! the extraction of the whole surface, intact and after a slice through its middle,
//! and the local update that brings the intact surface up to date after that slice.

use crate::analysis::bench::median;
use crate::body::shape::Shape;
use crate::ecs::components::BodyLattice;
use crate::ecs::desc::BodyDesc;
use crate::ecs::layout::SolverCache;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::error::{CleaveError, Result};
use crate::sim::simulation::Simulation;
use crate::surface::extract;
use crate::surface::update::update;
use crate::systems::surface::update_surfaces;
use glam::{UVec3, Vec3, Vec3A};
use serde::Serialize;
use std::time::Instant;

/// One `--surface` row.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceRow {
    /// Always `"surface"`.
    pub row: &'static str,
    /// Edge length of the box in particles.
    pub size: u32,
    /// Particles.
    pub particles: usize,
    /// Surface vertices of the intact box.
    pub vertices: usize,
    /// Surface triangles of the intact box.
    pub triangles: usize,
    /// Median wall time of the surface stage's update in a frame without a topology
    /// change, the body moving (every particle a hundredth of a spacing further each
    /// frame, so that the whole surface is carried), ms.
    pub frame_ms: f64,
    /// The same with the body at rest (the stage tests that nothing moved and keeps
    /// the surface), ms.
    pub resting_frame_ms: f64,
    /// Median wall time of extracting the intact box's surface, ms.
    pub extract_ms: f64,
    /// Median wall time of extracting the surface after a slice severed every edge
    /// across the box's middle, ms.
    pub sliced_extract_ms: f64,
    /// Triangles after the slice.
    pub sliced_triangles: usize,
    /// Median wall time of bringing the intact surface up to date after the slice by a
    /// local update ([`crate::surface::update`]), ms.
    pub local_update_ms: f64,
}

/// How far every particle moves between the moving body's frames, in spacings (ten
/// times [`SurfaceMesh::STILL`]).
const MOVE: f32 = 1e-2;

/// Times the surface of an n³ box: `steps` frames' updates at rest and as many moving,
/// and `steps` extractions intact and after the slice (medians).
pub fn bench_surface(
    n: u32,
    steps: usize,
    config: &crate::config::SimConfig,
) -> Result<SurfaceRow> {
    let h = 0.1;
    let mut sim = Simulation::new(config.clone())?;
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::splat(n)), h);
    desc.position = Vec3::new(0.0, n as f32 * h, 0.0);
    let body = sim.spawn_body(&desc)?;
    sim.run(3);
    let world = sim.world_mut();
    let stage = world.register_system(update_surfaces);
    let run = |sim: &mut Simulation| -> Result<f64> {
        // (each run a new frame's: the stage carries a surface once per frame)
        sim.world_mut()
            .resource_mut::<crate::ecs::resources::SimClock>()
            .frame += 1;
        let start = Instant::now();
        sim.world_mut()
            .run_system(stage)
            .map_err(|e| CleaveError::InvalidEntity(format!("surface stage: {e}")))?;
        Ok(start.elapsed().as_secs_f64() * 1e3)
    };
    run(&mut sim)?;
    let mut resting = (0..steps.max(1))
        .map(|_| run(&mut sim))
        .collect::<Result<Vec<f64>>>()?;
    let step = Vec3A::splat(MOVE * h);
    let mut frames = (0..steps.max(1))
        .map(|_| {
            let mut cache = sim.world_mut().resource_mut::<SolverCache>();
            cache
                .particles
                .positions
                .iter_mut()
                .for_each(|x| *x += step);
            run(&mut sim)
        })
        .collect::<Result<Vec<f64>>>()?;
    let mesh = sim
        .world()
        .get::<SurfaceMesh>(body)
        .ok_or_else(|| CleaveError::not_a("a body with a surface", body))?;
    let (vertices, triangles) = (mesh.positions.len(), mesh.triangles().len());
    let mut lattice = sim
        .world()
        .get::<BodyLattice>(body)
        .ok_or_else(|| CleaveError::not_a("a body", body))?
        .lattice
        .clone();
    let particles = lattice.live_count();
    let extraction = |lattice: &crate::body::lattice::Lattice| {
        let mut samples: Vec<f64> = (0..steps.max(1))
            .map(|_| {
                let start = Instant::now();
                let t = extract(lattice);
                std::hint::black_box(&t);
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        (median(&mut samples), extract(lattice).triangles.len())
    };
    let (extract_ms, _) = extraction(&lattice);
    let middle = lattice.coord(0).x + n as i32 / 2;
    let crossing: Vec<(u32, u32)> = lattice
        .edges()
        .into_iter()
        .filter(|&(a, b)| lattice.coord(a).x.min(lattice.coord(b).x) == middle - 1)
        .filter(|&(a, b)| lattice.coord(a).x != lattice.coord(b).x)
        .collect();
    let intact = extract(&lattice);
    let mut touched = Vec::new();
    for (a, b) in crossing {
        lattice.sever(a, b);
        touched.extend([a, b]);
    }
    // the cut stage counts the pieces in the frame it cuts, labelling them; the surface
    // stage after it reads the same labels
    lattice.piece_count();
    let (sliced_extract_ms, sliced_triangles) = extraction(&lattice);
    let mut samples: Vec<f64> = (0..steps.max(1))
        .map(|_| {
            // (the update edits the surface it is given: each run a copy, made first)
            let old = intact.clone();
            let start = Instant::now();
            let t = update(&lattice, old, &touched);
            std::hint::black_box(&t);
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let local_update_ms = median(&mut samples);
    Ok(SurfaceRow {
        row: "surface",
        size: n,
        particles,
        vertices,
        triangles,
        frame_ms: median(&mut frames),
        resting_frame_ms: median(&mut resting),
        extract_ms,
        sliced_extract_ms,
        sliced_triangles,
        local_update_ms,
    })
}
