//! The detect stage's tests on a 64³ box: a blade that sweeps down through the middle
//! in one frame (the bench's slice), the same blade at 2,000 m/s (33 m in a 60 Hz
//! frame, across the box), and a sphere carving along the top, with the block culling
//! of `particles_hit` against testing every particle (in parallel too); and the edge
//! test of a severing blade (`edges_separated`).

use cleave::body::shape::Shape;
use cleave::cut::blocks::{Blocks, DenseParticles};
use cleave::cut::detection::{Reported, edges_separated, particles_hit};
use cleave::cut::tool::{CutMode, Pose, ToolShape};
use cleave::cut::tool_sweep::ToolSweep;
use cleave::ecs::components::Tool;
use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Quat, UVec3, Vec3, Vec3A};
use rayon::prelude::*;

const H: f32 = 0.1;

fn detect(c: &mut Criterion) {
    let n = 64;
    let lattice = Shape::cuboid(UVec3::splat(n)).voxelise(H).unwrap();
    // the solver layout's order: Morton order of the lattice
    let positions: Vec<Vec3A> = lattice
        .live_in_morton_order()
        .into_iter()
        .map(|i| Vec3A::from(lattice.rest_position(i)))
        .collect();
    let live = vec![true; positions.len()];
    let blocks = Blocks::uniform(positions.len());
    let particles = DenseParticles {
        positions: &positions,
        live: &live,
        blocks: &blocks,
    };
    let half = n as f32 * H * 0.5;
    let blade_at = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    let blade = Tool {
        shape: ToolShape::Blade {
            half_width: half + 1.0,
            half_height: 0.05,
        },
        cut_width: 2.0 * H,
        mode: CutMode::Remove,
    };
    let sphere = Tool {
        shape: ToolShape::Sphere { radius: 4.0 * H },
        cut_width: 2.0 * H,
        mode: CutMode::Remove,
    };
    // 2,000 m/s for one 60 Hz frame, along its own plane (XY) across the box
    let fast_at = |x: f32| Pose::at(Vec3::new(x, 0.3 * H, 0.0));
    let fast = 2000.0 / 60.0 / 2.0;
    let cases = [
        (
            "slice",
            ToolSweep::new(&blade, &blade_at(half + 1.0), &blade_at(-half - 1.0)),
        ),
        (
            "blade_2000m_s",
            ToolSweep::new(&blade, &fast_at(-fast), &fast_at(fast)),
        ),
        (
            "scoop",
            ToolSweep::new(
                &sphere,
                &Pose::at(Vec3::new(-half, half, 0.0)),
                &Pose::at(Vec3::new(-half + 8.0 * H, half, 0.0)),
            ),
        ),
    ];
    let mut group = c.benchmark_group("detect");
    group.sample_size(10);
    for (name, sweep) in cases {
        let sweep = sweep.unwrap();
        let tools = [&sweep];
        let hits = particles_hit(particles, &tools, None);
        eprintln!(
            "detect/{name}: {} of {} particles hit",
            hits.len(),
            positions.len()
        );
        group.bench_function(format!("{name}/{n}^3/blocks"), |b| {
            b.iter(|| particles_hit(particles, &tools, None))
        });
        group.bench_function(format!("{name}/{n}^3/every_particle"), |b| {
            b.iter(|| {
                (0..positions.len())
                    .into_par_iter()
                    .with_min_len(4096)
                    .filter(|&i| live[i] && tools[0].hits(Vec3::from(positions[i])))
                    .collect::<Vec<usize>>()
            })
        });
    }
    // the slice's edges, as a severing blade finds them: each particle's +x, +y, +z
    // partners in the Morton-ordered dense numbering
    let order = lattice.live_in_morton_order();
    let mut dense = vec![u32::MAX; lattice.len()];
    for (d, &p) in order.iter().enumerate() {
        dense[p as usize] = d as u32;
    }
    let partners = |i: usize| {
        [1, 3, 5].map(|d| match lattice.link(order[i], d) {
            u32::MAX => u32::MAX,
            n => dense[n as usize],
        })
    };
    let sever = Tool {
        mode: CutMode::Sever,
        ..blade
    };
    let sweep = ToolSweep::new(&sever, &blade_at(half + 1.0), &blade_at(-half - 1.0)).unwrap();
    let sever_all = || {
        edges_separated(
            particles,
            0..positions.len(),
            partners,
            &[&sweep],
            None,
            Reported::FirstTool,
        )
    };
    eprintln!("detect/sever_slice: {} edges", sever_all().len());
    group.bench_function(format!("sever_slice/{n}^3/blocks"), |b| b.iter(sever_all));
    group.finish();
}

criterion_group!(benches, detect);
criterion_main!(benches);
