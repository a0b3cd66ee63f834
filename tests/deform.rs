//! Handle deformation against cases outside the code: affine maps reproduced, point
//! handles interpolated, a clamped bar's centreline against the cubic Hermite curve,
//! ARAP's energy and rigid motions, reduced ARAP against full ARAP.

use cleave::body::lattice::Lattice;
use cleave::body::shape::Shape;
use cleave::deform::handles::{Handle, HandleSet, HandleTarget};
use cleave::deform::weights::Weights;
use glam::{Affine3A, Mat3, Quat, UVec3, Vec3};

const H: f32 = 0.1;
const NO_LIMIT: u64 = u64::MAX;

fn rest(lattice: &Lattice) -> Vec<Vec3> {
    (0..lattice.len() as u32)
        .map(|i| lattice.rest_position(i))
        .collect()
}

/// The live particles whose coordinate passes `keep`.
fn select(lattice: &Lattice, keep: impl Fn(glam::IVec3) -> bool) -> Vec<u32> {
    lattice
        .live_particles()
        .filter(|&i| keep(lattice.coord(i)))
        .collect()
}

/// A `length`×4×4 bar and its two end regions (two layers each) as handles.
fn clamped_bar(length: u32) -> (Lattice, Vec<Vec3>, HandleSet) {
    let lattice = Shape::cuboid(UVec3::new(length, 4, 4)).voxelise(H).unwrap();
    let rest = rest(&lattice);
    let lo = lattice
        .live_particles()
        .map(|i| lattice.coord(i).x)
        .min()
        .unwrap();
    let hi = lo + length as i32 - 1;
    let left = select(&lattice, |c| c.x <= lo + 1);
    let right = select(&lattice, |c| c.x >= hi - 1);
    let set = HandleSet::new(
        &lattice,
        vec![Handle::Region(left), Handle::Region(right)],
        &[],
    )
    .unwrap();
    (lattice, rest, set)
}

/// The clusters a body of `lattice` spawns with (seed grid at the origin), each of
/// weight 1.
fn unit_clusters(lattice: &Lattice) -> Vec<(f64, Vec<u32>)> {
    cleave::clusters::clustering::clusters_on_grid(
        lattice,
        &cleave::config::Material::default(),
        glam::IVec3::ZERO,
    )
    .into_clusters()
    .into_iter()
    .map(|c| (1.0, c))
    .collect()
}

fn pose(weights: &Weights, set: &HandleSet, rest: &[Vec3], targets: &[HandleTarget]) -> Vec<Vec3> {
    let dh = set.displacements(rest, targets).unwrap();
    let mut out = vec![Vec3::ZERO; rest.len()];
    weights.pose(&dh, &mut out);
    out
}

#[test]
fn one_affine_map_on_every_handle_moves_every_particle_by_it() {
    let lattice = Shape::Sphere { radius: 0.5 }.voxelise(H).unwrap();
    let rest = rest(&lattice);
    let caps = |sign: i32| select(&lattice, move |c| c.y * sign >= 3);
    let points: Vec<u32> = select(&lattice, |c| {
        c.y.abs() <= 1 && (c.x.abs() == 4 || c.z.abs() == 4)
    })
    .into_iter()
    .step_by(5)
    .take(4)
    .collect();
    let mut handles = vec![Handle::Region(caps(1)), Handle::Region(caps(-1))];
    handles.extend(points.iter().map(|&p| Handle::Point(p)));
    let set = HandleSet::new(&lattice, handles, &[]).unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let map = Affine3A::from_mat3_translation(
        Mat3::from_quat(Quat::from_axis_angle(
            Vec3::new(1.0, 2.0, 0.5).normalize(),
            0.7,
        )) * Mat3::from_cols(
            Vec3::new(1.2, 0.1, 0.0),
            Vec3::new(0.0, 0.9, 0.05),
            Vec3::new(0.0, 0.0, 1.1),
        ),
        Vec3::new(0.3, -0.2, 0.4),
    );
    let targets: Vec<HandleTarget> = set
        .handles()
        .iter()
        .map(|h| match h {
            Handle::Point(p) => HandleTarget::Point(map.transform_point3(rest[*p as usize])),
            Handle::Region(_) => HandleTarget::Affine(map),
        })
        .collect();
    let posed = pose(&weights, &set, &rest, &targets);
    let worst = lattice
        .live_particles()
        .map(|i| posed[i as usize].distance(map.transform_point3(rest[i as usize])))
        .fold(0.0f32, f32::max);
    eprintln!("affine reproduction: worst {:e} h", worst / H);
    assert!(worst < 1e-5 * H, "worst {:e} h", worst / H);
}

#[test]
fn point_handles_are_interpolated_exactly() {
    let lattice = Shape::cuboid(UVec3::new(10, 6, 5)).voxelise(H).unwrap();
    let rest = rest(&lattice);
    let corners = select(&lattice, |c| {
        [-5, 4].contains(&c.x) && [-3, 2].contains(&c.y) && [-2, 2].contains(&c.z)
    });
    assert_eq!(corners.len(), 8);
    let set = HandleSet::new(
        &lattice,
        corners.iter().map(|&p| Handle::Point(p)).collect(),
        &[],
    )
    .unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let targets: Vec<HandleTarget> = corners
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            HandleTarget::Point(
                rest[p as usize] + Vec3::new(0.1 * k as f32, -0.05, 0.02 * (k * k) as f32),
            )
        })
        .collect();
    let posed = pose(&weights, &set, &rest, &targets);
    for (&p, t) in corners.iter().zip(&targets) {
        let HandleTarget::Point(t) = t else {
            unreachable!()
        };
        assert!(posed[p as usize].distance(*t) < 1e-6 * H);
    }
    // and the weights are a partition of unity (constant precision)
    for i in lattice.live_particles() {
        let sum: f64 = weights.row(i).iter().sum();
        assert!((sum - 1.0).abs() < 1e-5, "particle {i}: Σw = {sum}");
    }
}

#[test]
fn a_bar_clamped_at_both_ends_bends_along_the_cubic_hermite_curve() {
    let (lattice, rest, set) = clamped_bar(48);
    let lo = lattice
        .live_particles()
        .map(|i| lattice.coord(i).x)
        .min()
        .unwrap();
    let hi = lo + 47;
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let delta = 0.8f32;
    let targets = [
        HandleTarget::Affine(Affine3A::IDENTITY),
        HandleTarget::Affine(Affine3A::from_translation(Vec3::new(0.0, delta, 0.0))),
    ];
    let posed = pose(&weights, &set, &rest, &targets);
    // the clamps hold at the middle of each two-layer end region
    let (x0, x1) = (lo as f32 + 0.5, hi as f32 - 0.5);
    let mut worst = 0.0f32;
    for x in lo..=hi {
        let layer = select(&lattice, |c| c.x == x);
        let sag: f32 = layer
            .iter()
            .map(|&i| posed[i as usize].y - rest[i as usize].y)
            .sum::<f32>()
            / layer.len() as f32;
        let s = ((x as f32 - x0) / (x1 - x0)).clamp(0.0, 1.0);
        let hermite = delta * s * s * (3.0 - 2.0 * s);
        worst = worst.max((sag - hermite).abs());
    }
    eprintln!(
        "Hermite: centreline within {:.3} % of δ",
        100.0 * worst / delta
    );
    assert!(
        worst < 0.02 * delta,
        "centreline off the Hermite curve by {:.2} % of δ",
        100.0 * worst / delta
    );
}

#[test]
fn bad_handles_are_errors_naming_the_handle() {
    let mut lattice = Shape::cuboid(UVec3::new(4, 4, 4)).voxelise(H).unwrap();
    let check = |lattice: &Lattice, handles: Vec<Handle>, pinned: &[u32], want: &str| {
        let e = HandleSet::new(lattice, handles, pinned)
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "{e:?} should say {want:?}");
    };
    check(&lattice, vec![], &[], "at least one handle");
    check(
        &lattice,
        vec![Handle::Point(0), Handle::Region(vec![])],
        &[],
        "handles[1]: selects no particle",
    );
    check(
        &lattice,
        vec![Handle::Region(vec![1, 2]), Handle::Point(2)],
        &[],
        "handles[1]: overlaps handles[0]",
    );
    check(
        &lattice,
        vec![Handle::Point(3)],
        &[3],
        "handles[0]: particle 3 is pinned",
    );
    check(
        &lattice,
        vec![Handle::Point(999)],
        &[],
        "not a live particle",
    );
    check(
        &lattice,
        (0..64).map(Handle::Point).collect(),
        &[],
        "fewer parameters than particles",
    );
    lattice.remove(5);
    check(
        &lattice,
        vec![Handle::Point(5)],
        &[],
        "handles[0]: particle 5 is not a live particle",
    );
    let set = HandleSet::new(&lattice, vec![Handle::Region(vec![0, 1, 2, 3])], &[]).unwrap();
    let rest = rest(&lattice);
    let nan = Affine3A::from_translation(Vec3::new(f32::NAN, 0.0, 0.0));
    let e = set
        .displacements(&rest, &[HandleTarget::Affine(nan)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("targets[0]") && e.contains("not finite"), "{e}");
}

#[test]
fn a_piece_without_a_handle_follows_its_nearest_handle() {
    let mut lattice = Shape::cuboid(UVec3::new(12, 4, 4)).voxelise(H).unwrap();
    let lo = lattice
        .live_particles()
        .map(|i| lattice.coord(i).x)
        .min()
        .unwrap();
    // cut the bar in two across x = lo + 6
    for (a, b) in lattice.edges() {
        if lattice.coord(a).x == lo + 5 && lattice.coord(b).x == lo + 6 {
            lattice.sever(a, b);
        }
    }
    let rest = rest(&lattice);
    let left = select(&lattice, |c| c.x <= lo + 1);
    let set = HandleSet::new(&lattice, vec![Handle::Region(left)], &[]).unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let map =
        Affine3A::from_rotation_translation(Quat::from_rotation_z(0.4), Vec3::new(0.1, 0.2, 0.0));
    let posed = pose(&weights, &set, &rest, &[HandleTarget::Affine(map)]);
    for i in lattice.live_particles() {
        let want = map.transform_point3(rest[i as usize]);
        assert!(posed[i as usize].distance(want) < 1e-5, "particle {i}");
    }
}

use cleave::deform::arap::{Arap, ArapOptions};
use cleave::deform::reduced::arap::ReducedArap;
use cleave::deform::reduced::auto_handles;
use cleave::deform::reduced::dynamics::ReducedDynamics;

/// A 32×4×4 bar held by its two end regions (two layers each), the right one moved by
/// `map` about its centroid.
struct Bar {
    lattice: Lattice,
    rest: Vec<Vec3>,
    set: HandleSet,
    targets: Vec<HandleTarget>,
}

fn bent_bar(turn: Quat, stretch: f32) -> Bar {
    let (lattice, rest, set) = clamped_bar(32);
    let c = set.rest_centroid(1, &rest);
    let map = Affine3A::from_translation(c + Vec3::new(stretch, 0.0, 0.0))
        * Affine3A::from_quat(turn)
        * Affine3A::from_translation(-c);
    let targets = vec![
        HandleTarget::Affine(Affine3A::IDENTITY),
        HandleTarget::Affine(map),
    ];
    Bar {
        lattice,
        rest,
        set,
        targets,
    }
}

fn assert_never_rises(energies: &[f64]) {
    for (k, w) in energies.windows(2).enumerate() {
        assert!(
            w[1] <= w[0] * (1.0 + 1e-12),
            "step {k}: energy rose {:e} → {:e}",
            w[0],
            w[1]
        );
    }
}

#[test]
fn arap_energy_never_rises_while_it_bends_and_twists_a_bar() {
    let bar = bent_bar(Quat::from_rotation_z(1.0) * Quat::from_rotation_x(1.2), 0.0);
    let arap = Arap::new(&bar.lattice, &bar.rest, &bar.set, NO_LIMIT).unwrap();
    let mut x = bar.rest.clone();
    // a tolerance too small to stop it: every iteration's energy is recorded
    let options = ArapOptions {
        tolerance: 1e-300,
        max_iterations: 60,
    };
    let report = arap
        .solve(&bar.set, &bar.targets, &mut x, &options)
        .unwrap();
    assert_eq!(report.energies.len(), 61);
    assert_never_rises(&report.energies);
    let (first, last) = (report.energies[1], *report.energies.last().unwrap());
    assert!(report.energies.windows(2).any(|w| w[1] < w[0]));
    assert!(
        last < 0.5 * first,
        "ARAP barely moved: {first:e} → {last:e}"
    );
}

#[test]
fn a_rigid_motion_of_every_handle_gives_that_rigid_motion() {
    let bar = bent_bar(Quat::IDENTITY, 0.0);
    let motion = Affine3A::from_rotation_translation(
        Quat::from_axis_angle(Vec3::new(0.3, 1.0, -0.2).normalize(), 0.5),
        Vec3::new(0.2, -0.1, 0.3),
    );
    let targets = vec![HandleTarget::Affine(motion); 2];
    let arap = Arap::new(&bar.lattice, &bar.rest, &bar.set, NO_LIMIT).unwrap();
    // from the linear subspace's pose, ARAP's first guess (from the rest pose a long
    // bar takes thousands of iterations to turn: 8e-6 after 400)
    let weights = Weights::compute(&bar.lattice, &bar.rest, &bar.set, NO_LIMIT).unwrap();
    let mut x = pose(&weights, &bar.set, &bar.rest, &targets);
    let options = ArapOptions {
        tolerance: 0.0,
        max_iterations: 20,
    };
    let report = arap.solve(&bar.set, &targets, &mut x, &options).unwrap();
    let energy = *report.energies.last().unwrap();
    let worst = bar
        .lattice
        .live_particles()
        .map(|i| x[i as usize].distance(motion.transform_point3(bar.rest[i as usize])))
        .fold(0.0f32, f32::max);
    eprintln!("rigid motion: energy {energy:e}, worst {:e} h", worst / H);
    assert!(energy < 1e-8, "energy {energy:e}");
    assert!(worst < 1e-4 * H, "worst {:e} h", worst / H);
}

/// Root mean square distance between two poses of the live particles.
fn rms(lattice: &Lattice, a: &[Vec3], b: &[Vec3]) -> f32 {
    let (sum, n) = lattice.live_particles().fold((0.0f32, 0), |(s, n), i| {
        (s + a[i as usize].distance_squared(b[i as usize]), n + 1)
    });
    (sum / n as f32).sqrt()
}

#[test]
fn reduced_arap_is_within_five_percent_of_full_arap_on_a_bent_twisted_stretched_bar() {
    let bar = bent_bar(Quat::from_rotation_z(0.9) * Quat::from_rotation_x(1.0), 0.3);
    let length = 3.2;
    let arap = Arap::new(&bar.lattice, &bar.rest, &bar.set, NO_LIMIT).unwrap();
    let mut full = bar.rest.clone();
    let options = ArapOptions {
        tolerance: 1e-7,
        max_iterations: 2000,
    };
    arap.solve(&bar.set, &bar.targets, &mut full, &options)
        .unwrap();
    // the user's handles, then 24 placed automatically
    let mut handles = bar.set.handles().to_vec();
    handles.extend(auto_handles(&bar.lattice, &bar.rest, &handles, 24));
    let all = HandleSet::new(&bar.lattice, handles, &[]).unwrap();
    let weights = Weights::compute(&bar.lattice, &bar.rest, &all, NO_LIMIT).unwrap();
    let fixed = bar.set.columns();
    let reduced = ReducedArap::new(&bar.lattice, &bar.rest, &weights, fixed, 2).unwrap();
    let mut dh = bar.set.displacements(&bar.rest, &bar.targets).unwrap();
    dh.resize(all.columns(), Vec3::ZERO);
    let mut rotations = reduced.rest_rotations();
    let report = reduced.solve(
        &mut dh,
        &mut rotations,
        &ArapOptions {
            tolerance: 1e-7,
            max_iterations: 500,
        },
    );
    assert_never_rises(&report.energies);
    let mut posed = vec![Vec3::ZERO; bar.rest.len()];
    weights.pose(&dh, &mut posed);
    let off = rms(&bar.lattice, &posed, &full) / length;
    // the linear subspace alone (no ARAP) is much further off
    let mut linear = vec![Vec3::ZERO; bar.rest.len()];
    let mut plain = bar.set.displacements(&bar.rest, &bar.targets).unwrap();
    plain.resize(all.columns(), Vec3::ZERO);
    let two = Weights::compute(&bar.lattice, &bar.rest, &bar.set, NO_LIMIT).unwrap();
    two.pose(&plain[..fixed], &mut linear);
    let linear_off = rms(&bar.lattice, &linear, &full) / length;
    eprintln!(
        "reduced ARAP {:.2} % of the bar's length from full ARAP ({} iterations); the \
         linear subspace alone {:.2} %",
        100.0 * off,
        report.iterations,
        100.0 * linear_off
    );
    assert!(off < 0.05, "{:.2} %", 100.0 * off);
}

#[test]
fn a_reduced_body_falls_freely_as_implicit_euler_would() {
    let lattice = Shape::cuboid(UVec3::new(12, 4, 4)).voxelise(H).unwrap();
    let rest = rest(&lattice);
    let clusters = unit_clusters(&lattice);
    let handles = auto_handles(&lattice, &rest, &[], 12);
    let set = HandleSet::new(&lattice, handles, &[]).unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let dt = 1.0 / 60.0;
    let g = Vec3::new(0.0, -9.81, 0.0);
    // free: every column falls as the body would, ½ g t²
    let free = ReducedDynamics::new(&weights, &rest, &clusters, 0.01, 1e4, dt, 0).unwrap();
    let mut state = free.rest_state();
    for _ in 0..30 {
        free.step(&mut state, &[], g, 10);
    }
    let mut posed = vec![Vec3::ZERO; rest.len()];
    weights.pose(&state.displacements(), &mut posed);
    let t = 30.0 * dt;
    for i in lattice.live_particles() {
        let fall = posed[i as usize] - rest[i as usize];
        // implicit Euler: the fall of step k is g dt² k(k+1)/2
        let want = g.y * (dt * dt) as f32 * 30.0 * 31.0 / 2.0;
        assert!(
            (fall.y - want).abs() < 1e-4 && fall.x.abs() < 1e-4,
            "{fall} vs {want} at t = {t}"
        );
    }
}

#[test]
fn two_pieces_each_follow_their_own_handle_exactly() {
    let mut lattice = Shape::cuboid(UVec3::new(16, 4, 4)).voxelise(H).unwrap();
    for (a, b) in lattice.edges() {
        if lattice.coord(a).x == -1 && lattice.coord(b).x == 0 {
            lattice.sever(a, b);
        }
    }
    let rest = rest(&lattice);
    let left = select(&lattice, |c| c.x <= -7);
    let right = select(&lattice, |c| c.x >= 6);
    let set = HandleSet::new(
        &lattice,
        vec![Handle::Region(left), Handle::Region(right)],
        &[],
    )
    .unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let maps = [
        Affine3A::from_rotation_translation(Quat::from_rotation_y(0.5), Vec3::new(0.0, 0.3, 0.0)),
        Affine3A::from_rotation_translation(Quat::from_rotation_x(-0.7), Vec3::new(0.2, 0.0, 0.1)),
    ];
    let posed = pose(&weights, &set, &rest, &maps.map(HandleTarget::Affine));
    for i in lattice.live_particles() {
        let map = maps[usize::from(lattice.coord(i).x >= 0)];
        let want = map.transform_point3(rest[i as usize]);
        assert!(posed[i as usize].distance(want) < 1e-5, "particle {i}");
    }
}

#[test]
fn a_reduced_cantilever_settles_with_a_sag_inverse_to_its_stiffness() {
    // linear elasticity: a small static deflection under gravity scales as 1/k (stiff
    // enough for small deflections: at k = 4e4 the tip sags 7 h, past linearity)
    let lattice = Shape::cuboid(UVec3::new(16, 4, 4)).voxelise(H).unwrap();
    let rest = rest(&lattice);
    let clusters = unit_clusters(&lattice);
    let lo = lattice
        .live_particles()
        .map(|i| lattice.coord(i).x)
        .min()
        .unwrap();
    let held = vec![Handle::Region(select(&lattice, |c| c.x <= lo + 1))];
    let mut handles = held.clone();
    handles.extend(auto_handles(&lattice, &rest, &held, 16));
    let set = HandleSet::new(&lattice, handles, &[]).unwrap();
    let weights = Weights::compute(&lattice, &rest, &set, NO_LIMIT).unwrap();
    let tip = select(&lattice, |c| c.x == lo + 15);
    let sag = |stiffness: f64| {
        let dynamics =
            ReducedDynamics::new(&weights, &rest, &clusters, 0.01, stiffness, 1.0 / 60.0, 4)
                .unwrap();
        let mut state = dynamics.rest_state();
        for _ in 0..300 {
            dynamics.step(&mut state, &[Vec3::ZERO; 4], Vec3::new(0.0, -9.81, 0.0), 10);
        }
        let speed = state
            .velocity
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max);
        assert!(speed < 1e-6, "k = {stiffness}: still moving at {speed:e}");
        let mut posed = vec![Vec3::ZERO; rest.len()];
        weights.pose(&state.displacements(), &mut posed);
        -tip.iter()
            .map(|&i| posed[i as usize].y - rest[i as usize].y)
            .sum::<f32>()
            / tip.len() as f32
    };
    let (stiff, soft) = (sag(4e6), sag(2e6));
    eprintln!(
        "tip sag: {:.4} h at k = 4e6, {:.4} h at k = 2e6",
        stiff / H,
        soft / H
    );
    assert!(stiff > 0.0 && stiff < 0.5 * H, "{stiff}");
    assert!(
        (soft / stiff - 2.0).abs() < 0.1,
        "sag ratio {}",
        soft / stiff
    );
}
