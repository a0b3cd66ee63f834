//! Saving and loading through the API as a new user would: a world of several bodies —
//! two held by hard pins, one posed by handles (under every pose method), one driven
//! by its own handles — saved mid-run and loaded goes on bit for bit as the run that
//! was never interrupted.

use cleave::deform::keys::{HandleKey, HandlePath};
use cleave::ecs::desc::{HandleDesc, Region};
use cleave::ecs::handles::PoseMethod;
use cleave::prelude::*;

const H: f32 = 0.1;

/// A bar of 8×2×2 particles whose middle sits at `centre`.
fn bar(centre: Vec3) -> BodyDesc {
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(8, 2, 2)), H);
    desc.position = centre;
    desc
}

/// A region around the particles of a bar at `centre` within `reach` of its end at −x.
fn left_end(centre: Vec3, reach: f32) -> Region {
    let end = centre - Vec3::new(0.4, 0.0, 0.0);
    Region {
        min: end - Vec3::new(1.0, 1.0, 1.0),
        max: end + Vec3::new(reach, 1.0, 1.0),
    }
}

/// The world: returns it and its bodies in the order built.
fn world(method: PoseMethod) -> (Simulation, Vec<Entity>) {
    let mut sim = Simulation::new(SimConfig::default()).unwrap();
    let mut bodies = Vec::new();
    // two bars pinned at their left ends
    for centre in [Vec3::new(0.0, 0.6, 0.0), Vec3::new(0.0, 0.6, 1.0)] {
        let body = sim.spawn_body(&bar(centre)).unwrap();
        let region = left_end(centre, 0.1);
        let pinned: Vec<u32> = sim
            .positions(body)
            .unwrap()
            .into_iter()
            .filter(|(_, x)| region.contains(*x))
            .map(|(i, _)| i)
            .collect();
        sim.attach(body, &pinned, 0.0).unwrap();
        bodies.push(body);
    }
    // a bar posed by a region handle at its left end that lifts it, and a point handle
    // at its right end that stays
    let centre = Vec3::new(0.0, 0.6, 2.0);
    let posed = sim.spawn_body(&bar(centre)).unwrap();
    let lift = HandlePath {
        keys: vec![
            (0.0, HandleKey::at(centre - Vec3::new(0.35, 0.0, 0.0))),
            (0.5, HandleKey::at(centre + Vec3::new(-0.35, 0.3, 0.0))),
        ],
    };
    let handles = [
        HandleDesc {
            region: left_end(centre, 0.1),
            point: false,
            path: lift,
            compliance: 0.0,
        },
        HandleDesc {
            region: Region {
                min: centre + Vec3::new(0.3, -1.0, -1.0),
                max: centre + Vec3::new(1.0, 1.0, 1.0),
            },
            point: true,
            path: HandlePath::default(),
            compliance: 0.0,
        },
    ];
    sim.pose_by_handles(posed, &handles, method).unwrap();
    bodies.push(posed);
    // a simulated bar carried by its own soft handle along a path
    let centre = Vec3::new(0.0, 0.6, 3.0);
    let mut driven = bar(centre);
    driven.handles = vec![HandleDesc {
        region: left_end(centre, 0.1),
        point: false,
        path: HandlePath {
            keys: vec![
                (0.0, HandleKey::at(centre - Vec3::new(0.35, 0.0, 0.0))),
                (0.5, HandleKey::at(centre + Vec3::new(-0.35, 0.4, 0.0))),
            ],
        },
        compliance: 1e-6,
    }];
    bodies.push(sim.spawn_body(&driven).unwrap());
    (sim, bodies)
}

/// Every body's positions and velocities as bits, in the order given.
fn state(sim: &Simulation, bodies: &[Entity]) -> Vec<u32> {
    let mut out = Vec::new();
    for &b in bodies {
        for (i, x) in sim.positions(b).unwrap() {
            out.push(i);
            out.extend(x.to_array().map(f32::to_bits));
        }
        for (_, v) in sim.velocities(b).unwrap() {
            out.extend(v.to_array().map(f32::to_bits));
        }
    }
    out
}

#[test]
fn pinned_posed_and_handle_driven_bodies_resume_bit_for_bit() {
    for method in [
        PoseMethod::Linear,
        PoseMethod::Arap(Default::default()),
        PoseMethod::reduced(),
    ] {
        let (mut sim, bodies) = world(method);
        sim.run(5);
        let mut bytes = Vec::new();
        sim.save(&mut bytes).unwrap();
        let mut loaded = Simulation::load(bytes.as_slice()).unwrap();
        let loaded_bodies: Vec<Entity> = bodies
            .iter()
            .map(|&b| loaded.loaded_entity(b).unwrap())
            .collect();
        assert_eq!(state(&sim, &bodies), state(&loaded, &loaded_bodies));
        sim.run(30);
        loaded.run(30);
        // the pins held (in both runs), the posed bar was lifted and the driven one
        // carried up
        for (name, run, list) in [("run", &sim, &bodies), ("loaded", &loaded, &loaded_bodies)] {
            for (k, &b) in list[..2].iter().enumerate() {
                let x = run.positions(b).unwrap();
                for i in [0, 8, 16, 24] {
                    let off = x[i].1.x - (-0.35);
                    assert!(
                        off.abs() < 1e-4,
                        "{method:?}, {name}: pin of bar {k} {off} m off"
                    );
                }
            }
            for &b in &list[2..] {
                let y = run.centroid(b).unwrap().y;
                assert!(y > 0.7, "{method:?}, {name}: {y} m");
            }
        }
        let (a, b) = (state(&sim, &bodies), state(&loaded, &loaded_bodies));
        let first = a.iter().zip(&b).position(|(x, y)| x != y);
        assert!(
            first.is_none() && a.len() == b.len(),
            "{method:?}: the loaded run differs (first at word {first:?}); centroids {:?} vs {:?}",
            bodies
                .iter()
                .map(|&e| sim.centroid(e).unwrap())
                .collect::<Vec<_>>(),
            loaded_bodies
                .iter()
                .map(|&e| loaded.centroid(e).unwrap())
                .collect::<Vec<_>>()
        );
    }
}
