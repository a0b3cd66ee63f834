//! Handles in the simulation: a posed body lands on the linear subspace's pose computed
//! apart from the ECS, ARAP's pose keeps its end regions on their targets, a cut
//! through a posed bar leaves each piece following its handle, a body dragged by a
//! handle while simulating follows it the same on one and two threads, and bad handles
//! are errors naming them.

use cleave::deform::handles::{Handle, HandleSet};
use cleave::deform::weights::Weights;
use cleave::io::scene::builtin;
use cleave::prelude::*;

/// The `bend` scene's simulation with its bar posed by its handles by `method`.
fn posed_bend(method: PoseMethod) -> (Simulation, Entity, Vec<HandleDesc>) {
    let mut scene = builtin("bend", 0).unwrap();
    let handles = std::mem::take(&mut scene.bodies[0].handles);
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    sim.pose_by_handles(body, &handles, method).unwrap();
    (sim, body, handles)
}

/// The affine map of the bar's right end region (`handles[1]`, its particles at `rest`)
/// at time `t`.
fn right_end_map(rest: &[(u32, Vec3)], handles: &[HandleDesc], t: f32) -> glam::Affine3A {
    let right: Vec<Vec3> = rest
        .iter()
        .filter(|(_, x)| handles[1].region.contains(*x))
        .map(|(_, x)| *x)
        .collect();
    let centroid = right.iter().sum::<Vec3>() / right.len() as f32;
    handles[1].path.sample(t).unwrap().map(centroid)
}

fn lattice_of(sim: &Simulation, body: Entity) -> cleave::body::lattice::Lattice {
    sim.world()
        .get::<BodyLattice>(body)
        .unwrap()
        .lattice
        .clone()
}

fn spacing(sim: &Simulation, body: Entity) -> f32 {
    sim.world()
        .get::<BodyLattice>(body)
        .unwrap()
        .lattice
        .spacing()
}

#[test]
fn a_posed_bar_lands_on_the_subspace_pose_computed_apart() {
    let (mut sim, body, handles) = posed_bend(PoseMethod::Linear);
    let rest: Vec<(u32, Vec3)> = sim.positions(body).unwrap();
    let h = spacing(&sim, body);
    // the same pose from the plain algorithm: handles chosen by the same regions
    let lattice = lattice_of(&sim, body);
    let mut at = vec![Vec3::ZERO; lattice.len()];
    for &(i, x) in &rest {
        at[i as usize] = x;
    }
    let list: Vec<Handle> = handles
        .iter()
        .map(|d| {
            Handle::Region(
                rest.iter()
                    .filter(|(_, x)| d.region.contains(*x))
                    .map(|(i, _)| *i)
                    .collect(),
            )
        })
        .collect();
    let set = HandleSet::new(&lattice, list, &[]).unwrap();
    let weights = Weights::compute(&lattice, &at, &set, u64::MAX).unwrap();
    let frames = 45; // three quarters of the way to the bend
    sim.run(frames);
    let t = frames as f32 / 60.0;
    let targets: Vec<_> = (0..2)
        .map(|k| {
            handles[k]
                .path
                .target(&set.handles()[k], set.rest_centroid(k, &at), t)
        })
        .collect();
    let dh = set.displacements(&at, &targets).unwrap();
    let mut want = vec![Vec3::ZERO; lattice.len()];
    weights.pose(&dh, &mut want);
    let worst = sim
        .positions(body)
        .unwrap()
        .iter()
        .map(|(i, x)| x.distance(want[*i as usize]))
        .fold(0.0f32, f32::max);
    assert!(
        worst < 1e-4 * h,
        "posed {:e} h off the subspace's pose",
        worst / h
    );
    assert!(check_invariants(sim.world()).is_empty());
}

#[test]
fn arap_keeps_the_end_regions_on_their_targets_and_the_bar_its_length() {
    let (mut sim, body, handles) = posed_bend(PoseMethod::Arap(Default::default()));
    let h = spacing(&sim, body);
    let rest = sim.positions(body).unwrap();
    sim.run(60); // bent a quarter turn
    let posed = sim.positions(body).unwrap();
    let map = right_end_map(&rest, &handles, 1.0);
    for ((_, r), (_, x)) in rest.iter().zip(&posed) {
        assert!(x.is_finite());
        if handles[0].region.contains(*r) {
            assert!(x.distance(*r) < 1e-3 * h);
        }
        if handles[1].region.contains(*r) {
            assert!(
                x.distance(map.transform_point3(*r)) < 1e-3 * h,
                "{x} vs {}",
                map.transform_point3(*r)
            );
        }
    }
    // a quarter circle of radius 19 h stretches the outer fibres of a 4 h thick bar by
    // 1.5/19 = 8 %: ARAP's edges keep their length within that, the linear subspace's
    // do not (it shrinks the bend's inside and swells its outside)
    let (linear, _, _) = {
        let (mut sim, body, handles) = posed_bend(PoseMethod::Linear);
        sim.run(60);
        (sim.positions(body).unwrap(), body, handles)
    };
    let lattice = lattice_of(&sim, body);
    let worst = |pose: &[(u32, Vec3)]| {
        let at = |i: u32| pose.iter().find(|(j, _)| *j == i).unwrap().1;
        lattice
            .edges()
            .iter()
            .map(|&(a, b)| (at(a).distance(at(b)) / h - 1.0).abs())
            .fold(0.0f32, f32::max)
    };
    let (arap, linear) = (worst(&posed), worst(&linear));
    eprintln!(
        "largest change of an edge's length: ARAP {:.1} %, linear {:.1} %",
        100.0 * arap,
        100.0 * linear
    );
    assert!(arap < 0.1 && arap < linear, "ARAP {arap}, linear {linear}");
}

#[test]
fn a_cut_through_a_posed_bar_leaves_each_piece_following_its_own_handle() {
    for mode in [CutMode::Sever, CutMode::Split, CutMode::Remove] {
        cut_posed_bar(mode);
    }
}

fn cut_posed_bar(mode: CutMode) {
    // the bend held back half a second: the blade cuts the bar while it is still
    let mut scene = builtin("bend", 0).unwrap();
    let mut handles = std::mem::take(&mut scene.bodies[0].handles);
    for (t, _) in &mut handles[1].path.keys {
        *t += 0.5;
    }
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    sim.pose_by_handles(body, &handles, PoseMethod::Linear)
        .unwrap();
    let h = spacing(&sim, body);
    let rest = sim.positions(body).unwrap();
    let down = |y: f32| Pose {
        position: Vec3::new(0.0, y, 0.0),
        rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
    };
    sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Blade {
            half_width: 1.0,
            half_height: 0.2,
        },
        cut_width: 0.051,
        cut_mode: mode,
        path: Path {
            keys: vec![(0.0, down(1.5)), (0.1, down(0.5))],
        },
        pose: down(1.5),
    })
    .unwrap();
    sim.run(90);
    let pieces = sim.pieces(body).unwrap();
    let sizes: Vec<usize> = pieces.iter().map(Vec::len).collect();
    assert_eq!(pieces.len(), 2, "the blade cuts the bar in two: {sizes:?}");
    let posed = sim.positions(body).unwrap();
    let map = right_end_map(&rest, &handles, 1.5);
    // the piece of the right end is carried rigidly by its handle, the other stays with
    // the still left handle
    let right_end = rest
        .iter()
        .find(|(_, x)| handles[1].region.contains(*x))
        .unwrap()
        .0;
    let carried = pieces.iter().find(|p| p.contains(&right_end)).unwrap();
    assert!(
        carried.len() > 200 && carried.len() < 312,
        "{mode:?}: {sizes:?}"
    );
    let rest: std::collections::HashMap<u32, Vec3> = rest.into_iter().collect();
    for (i, x) in &posed {
        assert!(x.is_finite());
        // a split's new half rests where it was made: only the others are compared
        let Some(r) = rest.get(i) else { continue };
        let want = if carried.contains(i) {
            map.transform_point3(*r)
        } else {
            *r
        };
        assert!(
            x.distance(want) < 1e-3 * h,
            "{mode:?}: {r} went to {x}, not {want}"
        );
    }
}

/// The positions of `grab` after `frames` frames on `threads` threads.
fn grab(frames: u32, threads: usize) -> (Vec<(u32, Vec3)>, Vec3, usize) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let scene = builtin("grab", 0).unwrap();
        let target = scene.bodies[0].handles[0]
            .path
            .sample(frames as f32 / 60.0)
            .unwrap()
            .position;
        let mut sim = Simulation::from_scene(&scene).unwrap();
        let body = sim.bodies()[0];
        sim.run(frames);
        let violations = check_invariants(sim.world()).len();
        (sim.positions(body).unwrap(), target, violations)
    })
}

#[test]
fn a_dragged_block_follows_its_handle_the_same_on_one_and_two_threads() {
    let (one, target, violations) = grab(150, 1);
    let (two, _, _) = grab(150, 2);
    assert_eq!(violations, 0);
    let bits = |p: &[(u32, Vec3)]| {
        p.iter()
            .map(|(i, x)| (*i, x.to_array().map(f32::to_bits)))
            .collect::<Vec<_>>()
    };
    assert!(bits(&one) == bits(&two), "1 and 2 threads differ");
    // the grabbed particle is the top face's middle one: the nearest to the target
    let h = 0.05;
    let nearest = one
        .iter()
        .map(|(_, x)| x.distance(target))
        .fold(f32::INFINITY, f32::min);
    assert!(
        nearest < 0.5 * h,
        "the block is {:.2} h from its handle",
        nearest / h
    );
    assert!(one.iter().all(|(_, x)| x.is_finite()));
}

#[test]
fn bad_handles_are_errors_naming_them() {
    let mut scene = builtin("grab", 0).unwrap();
    let mut sim = Simulation::new(scene.config.clone()).unwrap();
    // a region beside the body
    let mut body = scene.bodies[0].clone();
    body.handles[0].region = Region {
        min: Vec3::splat(5.0),
        max: Vec3::splat(6.0),
    };
    let e = sim.spawn_body(&body).unwrap_err().to_string();
    assert!(e.contains("body.handles[0].region"), "{e}");
    // a simulated body cannot be stretched by its handle
    let body = &mut scene.bodies[0];
    body.handles[0].point = false;
    body.handles[0].path.keys[1].1.scale = Vec3::new(2.0, 1.0, 1.0);
    let e = sim.spawn_body(body).unwrap_err().to_string();
    assert!(e.contains("body.handles[0].path[1].scale"), "{e}");
    // a point handle's key neither turns nor scales
    body.handles[0].point = true;
    let e = sim.spawn_body(body).unwrap_err().to_string();
    assert!(
        e.contains("body.handles[0].path[1]") && e.contains("point handle"),
        "{e}"
    );
    // a NaN key
    body.handles[0].path.keys[1].1 = HandleKey::at(Vec3::new(f32::NAN, 0.0, 0.0));
    let e = sim.spawn_body(body).unwrap_err().to_string();
    assert!(e.contains("body.handles[0].path[1].position"), "{e}");
    assert!(sim.bodies().is_empty(), "no body spawned half");
}

#[test]
fn reduced_arap_poses_the_bent_bar_within_five_percent_of_full_arap() {
    // bent a quarter turn (frame 60), then bent and twisted a quarter turn (frame 180)
    for frames in [60, 180] {
        let pose_at = |method| {
            let (mut sim, body, _) = posed_bend(method);
            sim.run(frames);
            sim.positions(body).unwrap()
        };
        let full = pose_at(PoseMethod::Arap(Default::default()));
        let reduced = pose_at(PoseMethod::reduced());
        let linear = pose_at(PoseMethod::Linear);
        let rms = |a: &[(u32, Vec3)], b: &[(u32, Vec3)]| {
            let sum: f32 = a
                .iter()
                .zip(b)
                .map(|((_, x), (_, y))| x.distance_squared(*y))
                .sum();
            (sum / a.len() as f32).sqrt()
        };
        let length = 32.0 * 0.05;
        let (off, linear_off) = (rms(&reduced, &full) / length, rms(&linear, &full) / length);
        eprintln!(
            "bend at frame {frames}: reduced ARAP {:.2} % of the bar's length from full ARAP, \
             the linear subspace {:.2} %",
            100.0 * off,
            100.0 * linear_off
        );
        assert!(off < 0.05, "frame {frames}: {:.2} %", 100.0 * off);
    }
}

#[test]
fn game_code_moves_a_posed_body_by_its_handles_targets() {
    let mut scene = builtin("bend", 0).unwrap();
    let mut handles = std::mem::take(&mut scene.bodies[0].handles);
    handles[1].path.keys.clear(); // the right end is left to game code
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    sim.pose_by_handles(body, &handles, PoseMethod::Linear)
        .unwrap();
    let rest = sim.positions(body).unwrap();
    let lift = glam::Affine3A::from_translation(Vec3::new(0.0, 0.3, 0.0));
    sim.world_mut().get_mut::<HandlePose>(body).unwrap().targets[1] =
        cleave::deform::handles::HandleTarget::Affine(lift);
    sim.run(2);
    let posed = sim.positions(body).unwrap();
    let h = spacing(&sim, body);
    for ((_, r), (_, x)) in rest.iter().zip(&posed) {
        if handles[1].region.contains(*r) {
            assert!(x.distance(lift.transform_point3(*r)) < 1e-4 * h);
        }
        if handles[0].region.contains(*r) {
            assert!(x.distance(*r) < 1e-4 * h);
        }
    }
}

#[test]
fn a_simulated_handle_faster_than_any_path_may_go_is_refused() {
    let mut scene = builtin("grab", 0).unwrap();
    let body = &mut scene.bodies[0];
    body.handles[0].path.keys[1].1.position = Vec3::new(1e5, 0.0, 0.0);
    let mut sim = Simulation::new(scene.config.clone()).unwrap();
    let e = sim.spawn_body(body).unwrap_err().to_string();
    assert!(e.contains("body.handles[0].path"), "{e}");
}
