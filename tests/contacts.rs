//! Contacts and colliders through the public API: no tunnelling through static or
//! kinematic colliders, random drops that never end overlapping, overlapping spawns
//! resolved without an explosion, and bad input refused with the field named. Overlap is
//! measured here by brute force over the particle positions, apart from the engine.

mod common;
use bevy_ecs::prelude::*;
use cleave::prelude::*;
use glam::{Quat, UVec3, Vec3, Vec3A};
use proptest::prelude::*;

const H: f32 = 0.1;

/// Live particle positions of every body, by body (in spawn order of `bodies`).
fn positions(sim: &mut Simulation, bodies: &[Entity]) -> Vec<Vec<Vec3>> {
    bodies
        .iter()
        .map(|b| {
            let world = sim.world();
            let lattice = world.get::<BodyLattice>(*b).expect("a body");
            lattice
                .lattice
                .live_particles()
                .filter_map(|i| world.get::<Position>(lattice.particles[i as usize]))
                .map(|p| p.0)
                .collect()
        })
        .collect()
}

/// The smallest distance between particles of different bodies (brute force).
fn min_gap(groups: &[Vec<Vec3>]) -> f32 {
    let mut best = f32::INFINITY;
    for (i, a) in groups.iter().enumerate() {
        for b in &groups[i + 1..] {
            for p in a {
                for q in b {
                    best = best.min(p.distance(*q));
                }
            }
        }
    }
    best
}

fn no_gravity() -> SimConfig {
    SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        damping: 0.0,
        ..SimConfig::default()
    }
}

#[test]
fn a_body_at_100_m_per_s_stops_outside_a_06_m_box() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(no_gravity())?;
    // a turned 0.6 m box, 3 m ahead of the body
    let shape = ColliderShape::Box {
        half_extents: Vec3::splat(0.3),
    };
    let pose = Pose {
        position: Vec3::new(3.0, 0.0, 0.0),
        rotation: Quat::from_rotation_y(0.3),
    };
    sim.spawn_collider(&ColliderDesc {
        shape: shape.clone(),
        friction: 0.0,
        pose,
        path: Path::default(),
    })?;
    let mut body = BodyDesc::new(Shape::cuboid(UVec3::splat(4)), H);
    body.velocity = Vec3::new(100.0, 0.0, 0.0);
    let body = sim.spawn_body(&body)?;
    // one substep moves the body 0.83 m: more than the box is deep
    for _ in 0..20 {
        sim.step();
    }
    let inverse = glam::Affine3A::from_rotation_translation(pose.rotation, pose.position).inverse();
    for p in &positions(&mut sim, &[body])[0] {
        let local = inverse.transform_point3a(Vec3A::from(*p));
        assert!(shape.signed_distance(local) > -1e-4, "{p} inside the box");
        assert!(p.x < 3.0, "{p} went through the box");
    }
    Ok(())
}

/// A thin plate swept at 20 m/s from x = −1 to 1 in 0.1 s into a resting block, moved by
/// its keyframed path or, with `by_code`, by game code setting the path's pose before
/// each frame; the block's positions after 12 frames.
fn plate_push(by_code: bool) -> cleave::error::Result<Vec<Vec3>> {
    let mut sim = Simulation::new(SimConfig::default())?;
    let plate = ColliderShape::Box {
        half_extents: Vec3::new(0.02, 1.0, 1.0),
    };
    let at = |x: f32| Pose::at(Vec3::new(x, 0.5, 0.0));
    let path = Path {
        keys: vec![(0.0, at(-1.0)), (0.1, at(1.0))],
    };
    let collider = sim.spawn_collider(&ColliderDesc {
        shape: plate,
        friction: 0.2,
        pose: at(-1.0),
        path: if by_code {
            Path::default()
        } else {
            path.clone()
        },
    })?;
    let mut body = BodyDesc::new(Shape::cuboid(UVec3::new(4, 4, 4)), H);
    body.position = Vec3::new(0.0, 0.16, 0.0);
    let body = sim.spawn_body(&body)?;
    let dt = sim.config().dt;
    for frame in 0..12 {
        if by_code {
            let end = path.sample((frame + 1) as f32 * dt).expect("a path");
            sim.set_collider_pose(collider, end)?;
        }
        sim.step();
    }
    Ok(positions(&mut sim, &[body]).remove(0))
}

#[test]
fn a_plate_at_20_m_per_s_pushes_a_body_instead_of_passing_through() -> cleave::error::Result<()> {
    let keyframed = plate_push(false)?;
    // the plate stopped at x = 1 (front face 1.02): every particle is in front of it
    for p in &keyframed {
        assert!(p.x > 1.02 - 1e-3, "{p} is behind the plate");
    }
    // moved by game code frame by frame, it sweeps the same way
    assert_eq!(plate_push(true)?, keyframed);
    Ok(())
}

/// A closed octahedron |x| + |y| + |z| = `r` as a triangle mesh.
fn octahedron(r: f32) -> cleave::geometry::mesh::TriangleMesh {
    let (v, t) = common::octahedron(r);
    let v = v.into_iter().map(Vec3::from).collect();
    cleave::geometry::mesh::TriangleMesh::new(v, t, std::path::Path::new("octahedron"))
        .expect("a closed mesh")
}

#[test]
fn bodies_rest_on_and_do_not_tunnel_into_a_mesh_collider() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(SimConfig::default())?;
    let sdf = cleave::geometry::mesh_sdf::MeshSdf::new(&octahedron(0.6), 48)?;
    let shape = ColliderShape::Mesh(std::sync::Arc::new(sdf));
    // turned, its lower tip in the ground: a ramp of four sloped faces
    let pose = Pose {
        position: Vec3::new(0.0, 0.3, 0.0),
        rotation: Quat::from_rotation_y(0.4),
    };
    sim.spawn_collider(&ColliderDesc {
        shape: shape.clone(),
        friction: 0.8,
        pose,
        path: Path::default(),
    })?;
    // one dropped gently on top, one thrown at it at 60 m/s
    let mut gentle = BodyDesc::new(Shape::cuboid(UVec3::splat(4)), H);
    gentle.position = Vec3::new(0.05, 1.3, 0.0);
    let mut thrown = gentle.clone();
    thrown.position = Vec3::new(-3.0, 0.35, 0.1);
    thrown.velocity = Vec3::new(60.0, 0.0, 0.0);
    let bodies = [sim.spawn_body(&gentle)?, sim.spawn_body(&thrown)?];
    let inverse = glam::Affine3A::from_rotation_translation(pose.rotation, pose.position).inverse();
    let deepest = |sim: &mut Simulation| {
        positions(sim, &bodies)
            .iter()
            .flatten()
            .map(|p| -shape.signed_distance(inverse.transform_point3a(Vec3A::from(*p))))
            .fold(f32::NEG_INFINITY, f32::max)
    };
    for _ in 0..120 {
        sim.step();
        let depth = deepest(&mut sim);
        assert!(depth < 0.1 * H, "a particle {depth} inside the mesh");
    }
    // the thrown body stopped on the near side
    assert!(
        positions(&mut sim, &bodies[1..])[0]
            .iter()
            .all(|p| p.x < 0.0)
    );
    Ok(())
}

/// The largest speed of a particle of `body`.
fn body_speed(sim: &Simulation, body: Entity) -> f32 {
    let world = sim.world();
    let lattice = world.get::<BodyLattice>(body).expect("a body");
    lattice
        .lattice
        .live_particles()
        .filter_map(|i| world.get::<Velocity>(lattice.particles[i as usize]))
        .map(|v| v.0.length())
        .fold(0.0, f32::max)
}

#[test]
fn overlapping_spawns_are_resolved_without_an_explosion() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(SimConfig::default())?;
    // a, b: faces 0.04 apart (their balls overlap by 60 %); c: two thirds inside a
    // collider box; d, e: lattices interleaved half a layer deep (faces crossed)
    // (rigid: a soft body is checked below)
    let mut a = BodyDesc::new(Shape::cuboid(UVec3::splat(6)), H);
    a.material = Material::rigid();
    // resting on the ground on its contact balls (its lowest centres 0.05 up)
    a.position = Vec3::new(0.0, 0.3, 0.0);
    let at = |x: f32, z: f32| {
        let mut d = a.clone();
        d.position += Vec3::new(x, 0.0, z);
        d
    };
    sim.spawn_collider(&ColliderDesc {
        shape: ColliderShape::Box {
            half_extents: Vec3::new(0.2, 0.5, 0.5),
        },
        friction: 0.5,
        pose: Pose::at(Vec3::new(3.1, 0.3, 0.0)),
        path: Path::default(),
    })?;
    let descs = [
        at(0.0, 0.0),
        at(0.54, 0.0),
        at(3.0, 0.0),
        at(0.0, 3.0),
        at(0.45, 3.0),
    ];
    let [a, b, c, d, e] = descs.map(|d| sim.spawn_body(&d).expect("spawned"));
    sim.step();
    // the bounds stated in the issue note, for the first frame: 3 m/s for balls that
    // overlap, 5 m/s for interleaved lattices, 10 m/s for a body spawned in a collider
    for body in [a, b] {
        assert!(body_speed(&sim, body) < 3.0, "{}", body_speed(&sim, body));
    }
    for body in [d, e] {
        assert!(body_speed(&sim, body) < 5.0, "{}", body_speed(&sim, body));
    }
    assert!(body_speed(&sim, c) < 10.0, "{}", body_speed(&sim, c));
    // any material, a third to nine tenths inside a collider: its deep particles come
    // out a step per substep and its particles do not speed up past the depenetration
    // speed meanwhile, so the clusters do not fling it (a rubber one left at 72 m/s)
    for material in [Material::rigid(), Material::default(), Material::gel()] {
        for depth in [0.2, 0.4, 0.55] {
            let mut sim = Simulation::new(SimConfig::default())?;
            sim.spawn_collider(&ColliderDesc {
                shape: ColliderShape::Box {
                    half_extents: Vec3::new(0.2, 0.5, 0.5),
                },
                friction: 0.5,
                pose: Pose::at(Vec3::new(0.0, 0.3, 0.0)),
                path: Path::default(),
            })?;
            let mut deep = BodyDesc::new(Shape::cuboid(UVec3::splat(6)), H);
            deep.material = material.clone();
            deep.position = Vec3::new(-0.5 + depth, 0.3, 0.0);
            let deep = sim.spawn_body(&deep)?;
            sim.step();
            let speed = body_speed(&sim, deep);
            assert!(speed < 10.0, "{material:?} {depth}: {speed}");
        }
    }
    sim.run(180);
    let all = positions(&mut sim, &[a, b, c, d, e]);
    assert!(
        all.iter().flatten().all(|p| p.is_finite()),
        "a NaN position"
    );
    assert!(min_gap(&all[..2]) > 0.8 * H, "a–b {}", min_gap(&all[..2]));
    // interleaved lattices cannot tell inside from outside pair by pair: they stay
    // locked together, a documented limit, jittering but not flying apart
    assert!(body_speed(&sim, d) < 1.0 && body_speed(&sim, e) < 1.0);
    Ok(())
}

#[test]
fn bad_colliders_are_refused_with_the_field_named() {
    let mut sim = Simulation::new(SimConfig::default()).expect("a simulation");
    let good = ColliderDesc {
        shape: ColliderShape::Sphere { radius: 0.5 },
        friction: 0.5,
        pose: Pose::at(Vec3::ZERO),
        path: Path::default(),
    };
    let cases = [
        (
            ColliderDesc {
                shape: ColliderShape::Sphere { radius: -1.0 },
                ..good.clone()
            },
            "collider.shape.radius",
        ),
        (
            ColliderDesc {
                shape: ColliderShape::Box {
                    half_extents: Vec3::new(1.0, f32::NAN, 1.0),
                },
                ..good.clone()
            },
            "collider.shape.half_extents",
        ),
        (
            ColliderDesc {
                friction: f32::NAN,
                ..good.clone()
            },
            "collider.friction",
        ),
        (
            ColliderDesc {
                path: Path {
                    keys: vec![(1.0, Pose::at(Vec3::ZERO)), (0.5, Pose::at(Vec3::X))],
                },
                ..good.clone()
            },
            "collider.path[1].time",
        ),
        (
            ColliderDesc {
                path: Path {
                    keys: vec![(f32::NAN, Pose::at(Vec3::ZERO))],
                },
                ..good.clone()
            },
            "collider.path[0].time",
        ),
        // two keys at one time: a jump of infinite speed
        (
            ColliderDesc {
                path: Path {
                    keys: vec![(0.5, Pose::at(Vec3::ZERO)), (0.5, Pose::at(Vec3::X))],
                },
                ..good.clone()
            },
            "collider.path[1].time",
        ),
        // 2e6 m in 0.02 s
        (
            ColliderDesc {
                path: Path {
                    keys: vec![(0.0, Pose::at(Vec3::ZERO)), (0.02, Pose::at(Vec3::X * 2e5))],
                },
                ..good.clone()
            },
            "invalid `collider.path[1]`: 10000000 m/s from the key before (allowed: ≤ 1e4 m/s",
        ),
        (
            ColliderDesc {
                path: Path {
                    keys: vec![(0.0, Pose::at(Vec3::Y * 2e6))],
                },
                ..good.clone()
            },
            "collider.path[0].position",
        ),
        (
            ColliderDesc {
                shape: ColliderShape::Sphere { radius: 1e30 },
                ..good.clone()
            },
            "collider.shape.radius",
        ),
    ];
    for (desc, field) in cases {
        let e = sim.spawn_collider(&desc).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
    assert!(sim.spawn_collider(&good).is_ok());
    // a contact ball wider than two spacings
    let mut body = BodyDesc::new(Shape::cuboid(UVec3::splat(3)), H);
    body.material.contact_radius = Some(1e3);
    let e = sim.spawn_body(&body).unwrap_err().to_string();
    assert!(
        e.contains("material.contact_radius") && e.contains("2 × spacing"),
        "{e}"
    );
    body.material.contact_radius = Some(2.0 * H);
    assert!(sim.spawn_body(&body).is_ok());
}

/// A random small body shape.
fn body_shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        (0.12f32..0.3, 0.12f32..0.3, 0.12f32..0.3).prop_map(|(x, y, z)| Shape::Box {
            half_extents: Vec3::new(x, y, z)
        }),
        (0.15f32..0.3).prop_map(|radius| Shape::Sphere { radius }),
        (0.1f32..0.2, 0.05f32..0.25).prop_map(|(radius, half_length)| Shape::Capsule {
            radius,
            half_length
        }),
    ]
}

/// A random collider shape.
fn collider_shape() -> impl Strategy<Value = ColliderShape> {
    prop_oneof![
        (0.1f32..0.5, 0.05f32..0.3, 0.1f32..0.5).prop_map(|(x, y, z)| ColliderShape::Box {
            half_extents: Vec3::new(x, y, z)
        }),
        (0.1f32..0.4).prop_map(|radius| ColliderShape::Sphere { radius }),
        (0.05f32..0.2, 0.1f32..0.4).prop_map(|(radius, half_length)| ColliderShape::Capsule {
            radius,
            half_length
        }),
    ]
}

proptest! {
    // (a fixed seed: CI runs the same cases every time; change it to explore others)
    #![proptest_config(ProptestConfig { cases: 12, rng_seed: proptest::test_runner::RngSeed::Fixed(12), ..ProptestConfig::default() })]

    /// Two random bodies dropped onto a random turned collider on the ground, one above
    /// the other: they never end overlapping, nor inside the collider.
    #[test]
    fn random_drops_never_end_overlapping(
        lower in body_shape(),
        upper in body_shape(),
        collider in collider_shape(),
        yaw in 0.0f32..3.0,
        tilt in -0.5f32..0.5,
        offset in -0.15f32..0.15,
        seed in 0u64..1000,
    ) {
        let mut sim = Simulation::new(SimConfig { seed, ..SimConfig::default() }).expect("sim");
        let rotation = Quat::from_rotation_y(yaw) * Quat::from_rotation_z(tilt);
        let pose = Pose { position: Vec3::new(0.0, 0.2, 0.0), rotation };
        sim.spawn_collider(&ColliderDesc {
            shape: collider.clone(),
            friction: 0.5,
            pose,
            path: Path::default(),
        }).expect("collider");
        // rigid bodies (soft ones under load end closer: the contact projection's
        // residual grows as the clusters give)
        let mut a = BodyDesc::new(lower, H);
        a.material = Material::rigid();
        a.position = Vec3::new(offset, 1.2, 0.0);
        let mut b = BodyDesc::new(upper, H);
        b.material = Material::rigid();
        b.position = Vec3::new(-offset, 2.0, 0.05);
        b.rotation = Quat::from_rotation_x(0.4);
        let bodies = [sim.spawn_body(&a).expect("a"), sim.spawn_body(&b).expect("b")];
        sim.run(150);
        let groups = positions(&mut sim, &bodies);
        // (a body of eight particles under one ten times heavier, on a small collider,
        // ends at 0.69 h, the worst seen: the contact projection's residual under load;
        // the scenes' bodies keep 0.7 h and more)
        prop_assert!(min_gap(&groups) > 0.65 * H, "bodies {} apart", min_gap(&groups));
        let inverse = glam::Affine3A::from_rotation_translation(pose.rotation, pose.position)
            .inverse();
        for p in groups.iter().flatten() {
            let depth = -collider.signed_distance(inverse.transform_point3a(Vec3A::from(*p)));
            prop_assert!(depth < 0.05 * H, "{p} is {depth} inside the collider");
        }
        prop_assert!(check_invariants(sim.world()).is_empty());
    }
}

#[test]
fn the_pile_ends_with_no_particle_inside_a_wall() -> cleave::error::Result<()> {
    let scene = cleave::io::scene::builtin("pile", 0).expect("a built-in");
    let mut sim = Simulation::new(scene.config.clone())?;
    let bodies: Vec<Entity> = scene
        .bodies
        .iter()
        .map(|b| sim.spawn_body(b))
        .collect::<cleave::error::Result<_>>()?;
    for c in &scene.colliders {
        sim.spawn_collider(c)?;
    }
    sim.run(scene.frames);
    let all = positions(&mut sim, &bodies);
    for c in &scene.colliders {
        let inverse =
            glam::Affine3A::from_rotation_translation(c.pose.rotation, c.pose.position).inverse();
        for p in all.iter().flatten() {
            let depth = -c
                .shape
                .signed_distance(inverse.transform_point3a(Vec3A::from(*p)));
            assert!(depth < 1e-3 * H, "{p} is {depth} inside a wall");
        }
    }
    assert!(
        all.iter().flatten().all(|p| p.y > -1e-6),
        "below the ground"
    );
    assert!(min_gap(&all) > 0.7 * H, "bodies {} apart", min_gap(&all));
    assert!(check_invariants(sim.world()).is_empty());
    Ok(())
}

/// A horseshoe lying on its side: two arms of 20×2×4 particles, 3 layers apart,
/// joined by a spine at one end, its upper arm free to sag onto the lower one.
fn horseshoe(self_contact: bool) -> BodyDesc {
    let boxes = [
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.95, 0.15, 0.35)),
        (Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.95, 0.65, 0.35)),
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.15, 0.65, 0.35)),
    ];
    let sdf = move |p: Vec3| {
        boxes
            .iter()
            .map(|(lo, hi)| {
                let (c, e) = ((*lo + *hi) * 0.5, (*hi - *lo) * 0.5);
                let q = (p - c).abs() - e;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            })
            .fold(f32::INFINITY, f32::min)
    };
    let shape = Shape::Sdf(cleave::body::shape::SdfShape {
        sdf: std::sync::Arc::new(sdf),
        min: Vec3::splat(-0.1),
        max: Vec3::new(2.0, 0.7, 0.4),
    });
    let mut body = BodyDesc::new(shape, H);
    body.position = Vec3::new(-1.0, 0.05, 0.0);
    body.material.self_contact = self_contact;
    body
}

#[test]
fn a_piece_folding_onto_itself_collides_with_itself_unless_switched_off() {
    let closest = |self_contact: bool| -> f32 {
        let mut sim = Simulation::new(SimConfig::default()).expect("sim");
        let body = sim.spawn_body(&horseshoe(self_contact)).expect("body");
        sim.run(240);
        // the arms' particles away from the spine, by lattice coordinate: the lower arm's
        // two layers and the upper arm's two, four or more cells from the spine's start
        let world = sim.world();
        let l = &world.get::<BodyLattice>(body).expect("a body").lattice;
        let origin = l
            .live_particles()
            .map(|i| l.coord(i))
            .fold(glam::IVec3::MAX, |a, c| a.min(c));
        let (mut lower, mut upper) = (vec![], vec![]);
        for i in l.live_particles() {
            let c = l.coord(i) - origin;
            let particle = world.get::<BodyLattice>(body).expect("a body").particles[i as usize];
            let p = world.get::<Position>(particle).expect("a position").0;
            match (c.x >= 4, c.y) {
                (true, 0..=1) => lower.push(p),
                (true, 5..) => upper.push(p),
                _ => {}
            }
        }
        assert!(lower.len() >= 100 && upper.len() >= 100);
        min_gap(&[lower, upper])
    };
    let (on, off) = (closest(true), closest(false));
    assert!(on > 0.8 * H, "with self-contact the arms stay apart: {on}");
    assert!(
        off < 0.5 * H,
        "without it the upper arm sinks into the lower: {off}"
    );
}
