//! Oriented particles (SPEC §5), checked against rigid motions and the cluster model: a
//! clamped rod holds out under every solver where the cluster model's hangs, twist
//! about a straight rod's axis is free, a bend at its root carries to its far end, a
//! lone particle keeps its orientation, and in the cluster model particles turn with
//! their clusters.

use cleave::analysis::stats::rigid_fit;
use cleave::ecs::desc::Scene;
use cleave::glam::EulerRot;
use cleave::io::scene::builtin;
use cleave::prelude::*;

/// The simulation of `scene` and its first body.
fn start(scene: &Scene) -> (Simulation, Entity) {
    let mut sim = Simulation::from_scene(scene).unwrap();
    let body = sim.bodies()[0];
    (sim, body)
}

/// The lowest drop below its rest height of any particle of `scene`'s first body, in
/// spacings, after `frames` frames.
fn sag(scene: &Scene, frames: u32) -> f32 {
    let (mut sim, body) = start(scene);
    let rest = sim.positions(body).unwrap();
    for _ in 0..frames {
        sim.step();
    }
    let now = sim.positions(body).unwrap();
    let h = scene.bodies[0].spacing;
    rest.iter()
        .zip(&now)
        .map(|((_, r), (_, x))| (r.y - x.y) / h)
        .fold(f32::MIN, f32::max)
}

/// The entity of particle `i` of `body`.
fn particle(sim: &Simulation, body: Entity, i: u32) -> Entity {
    sim.world().get::<BodyLattice>(body).unwrap().particles[i as usize]
}

/// Every live particle's orientation, by index.
fn orientations(sim: &Simulation, body: Entity) -> Vec<(u32, Quat)> {
    let lattice = sim.world().get::<BodyLattice>(body).unwrap();
    lattice
        .lattice
        .live_particles()
        .map(|i| {
            let e = lattice.particles[i as usize];
            (i, sim.world().get::<Orientation>(e).unwrap().0)
        })
        .collect()
}

/// The angle between two orientations, in degrees.
fn degrees_between(a: Quat, b: Quat) -> f32 {
    a.angle_between(b).to_degrees()
}

#[test]
fn a_clamped_rod_holds_out_under_every_solver_where_clusters_hang() {
    let mut clusters = builtin("rod", 0).unwrap();
    clusters.bodies[0].material.model = Model::Clusters;
    let hanging = sag(&clusters, 600);
    eprintln!("cluster model: rod tip sag {hanging:.2} h");
    assert!(hanging > 15.0, "the cluster model's rod hangs: {hanging} h");
    for (solver, limit) in [
        (SolverMode::Jacobi, 5.0),
        (SolverMode::GaussSeidel, 5.0),
        (SolverMode::Projective, 2.0),
    ] {
        let mut scene = builtin("rod", 0).unwrap();
        scene.config.solver = solver;
        let s = sag(&scene, 600);
        eprintln!("{solver:?}: rod tip sag {s:.3} h");
        assert!(s < limit, "{solver:?}: {s} h");
    }
}

/// The `rod` scene with gravity off and only its first particle pinned: its root held in
/// place and, being held still, in orientation.
fn weightless_rod() -> (Simulation, Entity) {
    let mut scene = builtin("rod", 0).unwrap();
    scene.config.gravity = Vec3::ZERO;
    let pin = &mut scene.bodies[0].pins[0];
    pin.max.x = pin.min.x + 0.15;
    start(&scene)
}

#[test]
fn turning_the_root_about_a_straight_rods_axis_moves_no_particle() {
    let (mut sim, body) = weightless_rod();
    let h = 0.1;
    let rest = sim.positions(body).unwrap();
    let root = particle(&sim, body, 0);
    let twist = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    sim.world_mut().get_mut::<Orientation>(root).unwrap().0 = twist;
    let mut moved = 0.0f32;
    for _ in 0..300 {
        sim.step();
        let now = sim.positions(body).unwrap();
        for ((_, r), (_, x)) in rest.iter().zip(&now) {
            moved = moved.max((*x - *r).length() / h);
        }
    }
    let turned: Vec<f32> = orientations(&sim, body)
        .iter()
        .map(|(_, q)| degrees_between(Quat::IDENTITY, *q))
        .collect();
    eprintln!(
        "twist: largest move {moved:.2e} h; orientations turned {:.1}° (next to the root) … {:.1}° (tip)",
        turned[1],
        turned[turned.len() - 1]
    );
    assert!(moved < 0.01, "{moved} h");
    // the twist spreads along the rod: nothing holds its particles' turn about the axis
    // but their neighbours'
    assert!(turned[1] > 45.0, "{turned:?}");
}

#[test]
fn bending_the_root_turns_the_far_end() {
    let (mut sim, body) = weightless_rod();
    let root = particle(&sim, body, 0);
    let bend = Quat::from_rotation_z(30f32.to_radians());
    sim.world_mut().get_mut::<Orientation>(root).unwrap().0 = bend;
    for _ in 0..300 {
        sim.step();
    }
    let all = orientations(&sim, body);
    let tip = all.last().unwrap().1;
    let turned = degrees_between(Quat::IDENTITY, tip);
    // the tip's direction from the root, as a check on the orientations
    let x = sim.positions(body).unwrap();
    let chord = (x.last().unwrap().1 - x[0].1).normalize();
    let chord_angle = chord.y.atan2(chord.x).to_degrees();
    eprintln!("bend: the tip turned {turned:.1}°; the rod's chord {chord_angle:.1}°");
    assert!(turned >= 20.0, "{turned}°");
    assert!(chord_angle > 15.0, "{chord_angle}°");
}

#[test]
fn a_lone_particle_keeps_its_orientation_and_spin() {
    let mut scene = builtin("rod", 0).unwrap();
    scene.config.gravity = Vec3::ZERO;
    scene.config.damping = 0.0;
    let body = &mut scene.bodies[0];
    body.shape = Shape::cuboid(UVec3::ONE);
    body.pins.clear();
    let (mut sim, body) = start(&scene);
    let p = particle(&sim, body, 0);
    let start_turn = Quat::from_euler(EulerRot::XYZ, 0.4, -0.9, 1.3);
    let spin = Vec3::new(0.0, 3.0, -1.0);
    sim.world_mut().get_mut::<Orientation>(p).unwrap().0 = start_turn;
    sim.world_mut().get_mut::<AngularVelocity>(p).unwrap().0 = spin;
    let frames = 60;
    for _ in 0..frames {
        sim.step();
    }
    let t = frames as f32 * scene.config.dt;
    let expected = Quat::from_scaled_axis(spin * t) * start_turn;
    let got = sim.world().get::<Orientation>(p).unwrap().0;
    let off = degrees_between(expected, got);
    eprintln!("lone particle: {off:.4}° from the free spin's turn");
    assert!(off < 0.05, "{off}°");
    let w = sim.world().get::<AngularVelocity>(p).unwrap().0;
    assert!((w - spin).length() < 1e-3 * spin.length(), "{w}");
}

#[test]
fn a_turned_body_at_rest_stays_at_rest() {
    use cleave::ecs::desc::{BodyDesc, GroupDesc, Region};
    // a block spawned turned, weightless and still, of implicit groups and of one large
    // rigid explicit group: its particles start turned with it (else the fit weighs their
    // orientations against their places and twists the block), and the large group's fit
    // must carry no rounding bias (else a rotation error recurring every substep spins
    // it up)
    for explicit in [false, true] {
        let mut body = BodyDesc::new(Shape::cuboid(UVec3::new(40, 6, 12)), 0.025);
        body.rotation = Quat::from_rotation_z(-0.2);
        body.material = Material {
            model: Model::Oriented,
            ..Material::rigid()
        };
        if explicit {
            body.groups = vec![GroupDesc {
                region: Region {
                    min: Vec3::splat(-1.0),
                    max: Vec3::splat(1.0),
                },
                compliance: 0.0,
            }];
        }
        let scene = Scene {
            config: SimConfig {
                gravity: Vec3::ZERO,
                ground: None,
                ..SimConfig::default()
            },
            bodies: vec![body],
            tools: vec![],
            colliders: vec![],
            frames: 120,
        };
        let (mut sim, body) = start(&scene);
        let rest = sim.positions(body).unwrap();
        sim.run(scene.frames);
        let moved = rest
            .iter()
            .zip(&sim.positions(body).unwrap())
            .map(|((_, r), (_, x))| (*x - *r).length() / 0.025)
            .fold(0.0f32, f32::max);
        eprintln!("turned block, explicit group {explicit}: moved {moved:.5} h in 2 s");
        assert!(moved < 1e-3, "explicit {explicit}: {moved} h");
    }
}

#[test]
fn in_the_cluster_model_particles_turn_with_a_rigidly_spinning_body() {
    let mut scene = builtin("drop", 0).unwrap();
    scene.config.gravity = Vec3::ZERO;
    scene.config.ground = None;
    scene.config.damping = 0.0;
    scene.bodies[0].material = Material::rigid();
    let (mut sim, body) = start(&scene);
    // spin the body about y at 1 rad/s: v = ω × (x − centre)
    let spin = Vec3::new(0.0, 1.0, 0.0);
    let x = sim.positions(body).unwrap();
    let centre = x.iter().map(|(_, p)| *p).sum::<Vec3>() / x.len() as f32;
    let lattice = sim.world().get::<BodyLattice>(body).unwrap().clone();
    for (i, p) in &x {
        let e = lattice.particles[*i as usize];
        sim.world_mut().get_mut::<Velocity>(e).unwrap().0 = spin.cross(*p - centre);
    }
    let frames = 30;
    for _ in 0..frames - 1 {
        sim.step();
    }
    // the body's turn, fitted to its positions apart from the engine, and its spin in
    // the last frame
    let points = |x: &[(u32, Vec3)]| x.iter().map(|(_, p)| *p).collect::<Vec<_>>();
    let before = sim.positions(body).unwrap();
    sim.step();
    let now = sim.positions(body).unwrap();
    let (expected, ..) = rigid_fit(&points(&x), &points(&now));
    let (last, ..) = rigid_fit(&points(&before), &points(&now));
    let spun = last.to_scaled_axis() / scene.config.dt;
    let t = frames as f32 * scene.config.dt;
    eprintln!(
        "clusters: the body turned {:.2}° ({:.2}° at the spin it was given)",
        expected.to_axis_angle().1.to_degrees(),
        (spin.length() * t).to_degrees()
    );
    let worst = orientations(&sim, body)
        .iter()
        .map(|(_, q)| degrees_between(expected, *q))
        .fold(0.0f32, f32::max);
    eprintln!("clusters: orientations within {worst:.3}° of the body's turn");
    assert!(worst < 1.0, "{worst}°");
    for (i, _) in &x {
        let e = lattice.particles[*i as usize];
        let w = sim.world().get::<AngularVelocity>(e).unwrap().0;
        assert!(
            (w - spun).length() < 0.02 * spun.length(),
            "particle {i}: {w} vs {spun}"
        );
    }
}

#[test]
fn a_clamped_sheet_holds_out_where_clusters_fold() {
    let sheet = builtin("sheet", 0).unwrap();
    let shape_error = |scene: &Scene| {
        let (mut sim, body) = start(scene);
        let rest: Vec<Vec3> = sim.positions(body).unwrap().iter().map(|p| p.1).collect();
        sim.run(600);
        let now: Vec<Vec3> = sim.positions(body).unwrap().iter().map(|p| p.1).collect();
        cleave::analysis::stats::rigid_fit_error(&rest, &now) / scene.bodies[0].spacing
    };
    let mut clusters = sheet.clone();
    clusters.bodies[0].material.model = Model::Clusters;
    let folded = shape_error(&clusters);
    let oriented_sag = sag(&sheet, 600);
    let oriented = shape_error(&sheet);
    eprintln!(
        "sheet: oriented free edge sag {oriented_sag:.2} h, shape error {oriented:.2} h; cluster model shape error {folded:.2} h"
    );
    assert!(oriented_sag < 3.0, "{oriented_sag} h");
    assert!(folded > 2.0 * oriented, "{folded} vs {oriented}");
}

/// The mean curvature of the cantilever's centreline over its stiff (root) half and its
/// soft (outer) half, gravity off and its tip pushed down 3 h by a hard centroid hold:
/// a tip force, whose moment falls from the root to the tip (`M = F (L − x)`, a mean of
/// `3FL/4` over the root half and `FL/4` over the outer half). The turn of the slope
/// across each half over its length.
fn half_curvatures(scene: &Scene) -> (f32, f32) {
    let mut scene = scene.clone();
    scene.config.gravity = Vec3::ZERO;
    let h = scene.bodies[0].spacing;
    let tip = Vec3::new(1.2 - 0.5 * h, 1.0, 0.0);
    scene.bodies[0].attachments = vec![AttachmentDesc {
        region: Region {
            min: Vec3::new(1.2 - h, 0.0, -1.0),
            max: Vec3::new(1.3, 2.0, 1.0),
        },
        path: Path {
            keys: vec![
                (0.0, Pose::at(tip)),
                (1.0, Pose::at(tip - Vec3::new(0.0, 3.0 * h, 0.0))),
            ],
        },
        compliance: 0.0,
        hold: Hold::Centroid,
    }];
    let (mut sim, body) = start(&scene);
    let lattice = sim
        .world()
        .get::<BodyLattice>(body)
        .unwrap()
        .lattice
        .clone();
    sim.run(300);
    let (mut sum, mut count) = (vec![Vec3::ZERO; 24], vec![0.0f32; 24]);
    let first = lattice.coords().iter().map(|c| c.x).min().unwrap();
    for (i, x) in sim.positions(body).unwrap() {
        let column = (lattice.coord(i).x - first) as usize;
        sum[column] += x;
        count[column] += 1.0;
    }
    let centre: Vec<Vec3> = sum.iter().zip(&count).map(|(s, n)| *s / *n).collect();
    let slope = |a: usize| {
        let d = centre[a + 1] - centre[a];
        d.y.atan2(d.x)
    };
    // inside each half, clear of the pinned columns, the held one and the two columns
    // either side of the halves' boundary (a cluster there holds both materials)
    let stiff = (slope(9) - slope(2)).abs() / (7.0 * h);
    let soft = (slope(21) - slope(14)).abs() / (7.0 * h);
    (stiff, soft)
}

#[test]
fn a_beam_soft_on_its_outer_half_bends_more_there_in_both_models() {
    for (model, solver) in [
        (Model::Clusters, SolverMode::Jacobi),
        (Model::Clusters, SolverMode::GaussSeidel),
        (Model::Clusters, SolverMode::Projective),
        (Model::Oriented, SolverMode::Jacobi),
        (Model::Oriented, SolverMode::Projective),
    ] {
        let mut scene = builtin("cantilever", 0).unwrap();
        scene.bodies[0].material.model = model;
        scene.config.solver = solver;
        let (stiff, soft) = half_curvatures(&scene);
        let uniform = soft / stiff;
        let compliance = 20.0 * scene.bodies[0].material.compliance;
        scene.bodies[0].stiffness_regions = vec![StiffnessRegion {
            region: Region {
                min: Vec3::new(0.0, -10.0, -10.0),
                max: Vec3::splat(10.0),
            },
            compliance,
        }];
        let (stiff, soft) = half_curvatures(&scene);
        eprintln!(
            "{model} {solver}: curvature soft/stiff half {:.2} with the outer half 20× as compliant ({uniform:.2} uniform)",
            soft / stiff
        );
        assert!(soft >= 2.0 * stiff, "{model}: {soft} vs {stiff}");
        assert!(
            uniform < 1.0,
            "{model}: a uniform cantilever bends most at its root"
        );
    }
}

#[test]
fn a_wheel_on_its_axle_keeps_its_spin_and_shape_for_ten_turns() {
    let scene = builtin("wheel", 0).unwrap();
    let (wheel_h, wheel_spin) = (scene.bodies[0].spacing, scene.bodies[0].angular_velocity.z);
    let (mut sim, body) = start(&scene);
    let rest = sim.positions(body).unwrap();
    // the axle: the particles of the column the disc turns about
    let on_axle = |x: Vec3| x.x > 0.0 && x.x < wheel_h && x.y > 1.0 && x.y < 1.0 + wheel_h;
    let axis = Vec3::new(0.5 * wheel_h, 1.0 + 0.5 * wheel_h, 0.0);
    let radius = |x: &[(u32, Vec3)]| {
        x.iter()
            .map(|(_, p)| (*p - axis).truncate().length())
            .fold(0.0f32, f32::max)
    };
    let points = |x: &[(u32, Vec3)]| x.iter().map(|(_, p)| *p).collect::<Vec<_>>();
    sim.run(scene.frames - 1);
    let before = sim.positions(body).unwrap();
    sim.step();
    let now = sim.positions(body).unwrap();
    let (turn, ..) = rigid_fit(&points(&before), &points(&now));
    let spin = turn.to_scaled_axis().z / scene.config.dt;
    let axle_off = rest
        .iter()
        .zip(&now)
        .filter(|((_, r), _)| on_axle(*r))
        .map(|((_, r), (_, x))| (*x - *r).length() / wheel_h)
        .fold(0.0f32, f32::max);
    let stretch = radius(&now) / radius(&rest) - 1.0;
    eprintln!(
        "wheel after 10 turns: spin {:.2}% of 2 rev/s, radius {:+.3}%, axle off by {axle_off:.3} h",
        100.0 * spin / wheel_spin,
        100.0 * stretch
    );
    assert!(spin >= 0.95 * wheel_spin, "{spin} rad/s");
    assert!(stretch.abs() < 0.01, "{stretch}");
    assert!(axle_off < 0.1, "{axle_off} h");
}
