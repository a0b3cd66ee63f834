//! Memory budgets: a body the budget cannot hold is refused before anything is
//! allocated (its cells counted, a mesh's too), a body whose surface would not fit
//! beside its particles is refused with the estimate, and a projective factor that would pass
//! what the budget leaves beside the particles is not built: the solver takes Jacobi
//! steps and says so.

mod common;
use common::{GOOD, assert_mentions, run_file};

#[test]
fn a_body_past_the_memory_budget_is_refused_before_anything_is_allocated() {
    let text = GOOD.replace("Cells(cells: (4, 4, 4))", "Cells(cells: (400, 400, 400))");
    let start = std::time::Instant::now();
    let (code, err) = run_file("huge.ron", &text);
    assert_eq!(code, Some(2), "{err}");
    // the entry's line and column: line 3, just after `bodies: [`
    assert_mentions(
        &err,
        &[
            "huge.ron:3:14: bodies[0]",
            "shape.cells",
            "64000000 particles",
            "memory budget",
        ],
    );
    // refused up front: well under the seconds a 38 GB allocation would take to fail
    assert!(start.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn a_memory_budget_refuses_bodies_it_cannot_hold_and_a_fine_mesh_is_refused_at_once() {
    // a budget of 1 MB refuses 8,000 particles
    let text = GOOD
        .replace(
            "frames: 2,",
            "frames: 2, settings: (memory_budget_gb: 0.001),",
        )
        .replace("Cells(cells: (4, 4, 4))", "Cells(cells: (20, 20, 20))");
    let (code, err) = run_file("small.ron", &text);
    assert_eq!(code, Some(2), "{err}");
    assert_mentions(
        &err,
        &["small.ron:3:14: bodies[0]", "memory budget of 0.001 GB"],
    );
    // a closed 3,120-triangle ball, 1 m across, at spacing 0.005: 8 million cells
    let (stacks, slices) = (40usize, 40usize);
    let mut obj = String::from("v 0 0.5 0\n");
    for i in 1..stacks {
        let theta = std::f64::consts::PI * i as f64 / stacks as f64;
        for j in 0..slices {
            let phi = std::f64::consts::TAU * j as f64 / slices as f64;
            let (s, c) = (theta.sin() * 0.5, theta.cos() * 0.5);
            obj += &format!("v {} {} {}\n", s * phi.cos(), c, s * phi.sin());
        }
    }
    obj += "v 0 -0.5 0\n";
    let ring = |i: usize, j: usize| 2 + (i - 1) * slices + j % slices;
    let last = 2 + (stacks - 1) * slices;
    let mut triangles = 0;
    for j in 0..slices {
        obj += &format!("f 1 {} {}\n", ring(1, j + 1), ring(1, j));
        obj += &format!(
            "f {last} {} {}\n",
            ring(stacks - 1, j),
            ring(stacks - 1, j + 1)
        );
        triangles += 2;
        for i in 1..stacks - 1 {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            obj += &format!("f {a} {b} {d}\nf {a} {d} {c}\n");
            triangles += 2;
        }
    }
    assert_eq!(triangles, 3120);
    let dir = std::env::temp_dir().join(format!("cleave-scene-files-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("ball.obj"), obj).unwrap();
    let text = GOOD
        .replace("Cells(cells: (4, 4, 4))", r#"Mesh(path: "ball.obj")"#)
        .replace("spacing: 0.1", "spacing: 0.005");
    let start = std::time::Instant::now();
    let (code, err) = run_file("fine.ron", &text);
    assert_eq!(code, Some(2), "{err}");
    assert_mentions(
        &err,
        &[
            "fine.ron:3:14: bodies[0]",
            "shape (mesh ",
            "ball.obj)",
            "particles",
            "memory budget of 2 GB",
        ],
    );
    assert!(start.elapsed().as_secs_f64() < 10.0);
    // at a spacing wider than the ball, nothing: the OBJ is named too
    let (code, err) = run_file("wide.ron", &text.replace("spacing: 0.005", "spacing: 5.0"));
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("empty shape") && err.contains("ball.obj"),
        "{err}"
    );
    // and at a spacing the budget allows, it runs
    let (code, err) = run_file(
        "coarse.ron",
        &text.replace("spacing: 0.005", "spacing: 0.05"),
    );
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_body_whose_surface_would_pass_the_budget_is_refused_with_the_estimate() {
    // a 200×200×1 sheet: 40,000 particles (24 MB) fit a 30 MB budget, but its 80,800
    // faces of surface (24 MB more) do not; a 30³ block (16 MB, 5,400 faces) does
    let budget = |cells: &str| {
        GOOD.replace(
            "frames: 2,",
            "frames: 2, settings: (memory_budget_gb: 0.03),",
        )
        .replace("Cells(cells: (4, 4, 4))", cells)
    };
    let (code, err) = run_file("sheet.ron", &budget("Cells(cells: (200, 200, 1))"));
    assert_eq!(code, Some(2), "{err}");
    assert_mentions(
        &err,
        &[
            "sheet.ron",
            "surface too large",
            "80800 faces",
            "about 0.024 GB",
            "memory budget is 0.03 GB",
        ],
    );
    let (code, err) = run_file("block.ron", &budget("Cells(cells: (30, 30, 30))"));
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_projective_factor_past_the_memory_budget_falls_back_to_jacobi_with_a_warning() {
    // 24³ particles take 8.3 MB of a 9.5 MB budget (their surface 1 MB more); their
    // factor would take about 2.8 MB
    let settings = "frames: 2, settings: (memory_budget_gb: 0.0095, solver: \"projective\"),";
    let text = GOOD
        .replace("frames: 2,", settings)
        .replace("Cells(cells: (4, 4, 4))", "Cells(cells: (24, 24, 24))");
    let (code, err) = run_file("factor_over_budget.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    assert_mentions(
        &err,
        &[
            "cleave: warning: projective dynamics",
            "memory_budget_gb",
            "Jacobi steps",
        ],
    );
    // within the budget, it factors and says so only as a note
    let text = text.replace("memory_budget_gb: 0.0095", "memory_budget_gb: 1.0");
    let (code, err) = run_file("factor_within_budget.ron", &text);
    assert_eq!(code, Some(0), "{err}");
    assert!(!err.contains("warning"), "{err}");
    assert!(
        err.contains("cleave: projective dynamics: factored"),
        "{err}"
    );
}

#[test]
fn a_split_past_the_memory_budget_severs_instead_and_says_so() {
    // a 16³ box diced by 8 split blades through planes of particles in frame 2: about
    // 2.9 MB as spawned, over 5 MB once split (1,024 halves more, each face drawn as
    // four quads), so a budget of 4 MB holds the box but not its split
    use cleave::analysis::bench_cutting::diced_box;
    use cleave::cut::tool::CutMode;
    use cleave::ecs::components::BodyLattice;
    use cleave::ecs::resources::{ParticlesSplit, SplitsOverBudget};
    use cleave::sim::simulation::Simulation;
    let run = |mode: CutMode, budget_gb: f32| {
        let mut scene = diced_box(16, mode).scene;
        scene.config.memory_budget_gb = budget_gb;
        let mut sim = Simulation::from_scene(&scene).unwrap();
        let body = sim.bodies()[0];
        let (mut over, mut split) = (Vec::new(), 0);
        for _ in 0..3 {
            sim.step();
            over.extend(sim.messages::<SplitsOverBudget>());
            split += sim.messages::<ParticlesSplit>().len();
        }
        let len = sim.world().get::<BodyLattice>(body).unwrap().lattice.len();
        (sim.pieces(body).unwrap(), len, over, split)
    };
    let (within, within_len, within_over, within_split) = run(CutMode::Split, 1.0);
    let (over, over_len, said, over_split) = run(CutMode::Split, 0.004);
    // within its budget the box splits: halves gained, no word of the budget
    assert!(within_len > 4096 && within_split == 1 && within_over.is_empty());
    assert_eq!(within.len(), 25);
    // past it, no particle is split, and the blades sever the edges the split would
    // have handed to new halves: the split's pieces less those halves, each particle
    // with its kept half
    assert_eq!((over_len, over_split), (4096, 0));
    let without_halves: Vec<Vec<u32>> = within
        .iter()
        .map(|piece| piece.iter().copied().filter(|&p| p < 4096).collect())
        .collect();
    assert_eq!(over, without_halves);
    assert_eq!(said.len(), 1, "{said:?}");
    let m = said[0];
    assert_eq!(m.budget, 4_000_000);
    assert!(
        m.bytes > m.budget && m.particles >= 8 * 16 * 16 / 2,
        "{m:?}"
    );
}
