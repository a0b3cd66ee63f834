//! The `truck` scene (SPEC §5, oriented particles): a rigid chassis on rigid hubs that
//! turn on axles (joints) inside soft tyres rolls down a slope, along the ground and
//! over a bump. Checked against rolling without slipping (a wheel's spin is its ground
//! speed over its radius) and against the tyres' own rest shape (they flatten over the
//! bump and come back).

use cleave::analysis::stats::rigid_fit;
use cleave::io::scene::builtin;
use cleave::io::truck_scene::{BUMP, TRUCK_H, TRUCK_LENGTH, WHEEL_REACH};
use cleave::prelude::*;

/// A wheel's particles, by index: its hub, the two axle particles inside it (its centre
/// line), and its tyre with each tyre particle's distance from the axle at rest.
struct Wheel {
    hub: Vec<u32>,
    axle: Vec<u32>,
    tyre: Vec<(u32, f32)>,
}

/// What one frame shows: the chassis's centroid, and each wheel's centre, spin about z
/// over the frame (rad/s), deflection (its reach less its centre's distance from the
/// surface below: the ground or the bump; metres) and deepest tyre compression (rest
/// less current distance of a tyre particle from the axle; metres).
#[derive(Clone, Copy, Debug)]
struct Frame {
    chassis: Vec3,
    centres: [Vec3; 4],
    spins: [f32; 4],
    deflection: [f32; 4],
    compression: [f32; 4],
}

/// The distance of `centre` from the ground or the bump, whichever is nearer.
fn clearance(centre: Vec3) -> f32 {
    let (x, radius) = BUMP;
    let bump = (centre - Vec3::new(x, 0.0, centre.z)).length() - radius;
    centre.y.min(bump)
}

fn mean(points: impl Iterator<Item = Vec3>) -> Vec3 {
    let (sum, n) = points.fold((Vec3::ZERO, 0), |(s, n), p| (s + p, n + 1));
    sum / n.max(1) as f32
}

#[test]
fn the_truck_rolls_ten_lengths_its_wheels_turn_with_the_ground_and_its_tyres_give() {
    let scene = builtin("truck", 0).unwrap();
    let groups = &scene.bodies[0].groups;
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let body = sim.bodies()[0];
    let rest: Vec<(u32, Vec3)> = sim.positions(body).unwrap();
    let inside = |k: usize, x: Vec3| groups[k].region.contains(x);
    let chassis: Vec<u32> = rest
        .iter()
        .filter(|(_, x)| inside(0, *x))
        .map(|p| p.0)
        .collect();
    let in_any = |x: Vec3| (0..groups.len()).any(|k| inside(k, x));
    let wheels: Vec<Wheel> = (0..4)
        .map(|w| {
            let (axle_group, hub_group) = (1 + w / 2, 3 + w);
            let hub: Vec<u32> = rest
                .iter()
                .filter(|(_, x)| inside(hub_group, *x))
                .map(|p| p.0)
                .collect();
            let axle: Vec<u32> = rest
                .iter()
                .filter(|(_, x)| inside(hub_group, *x) && inside(axle_group, *x))
                .map(|p| p.0)
                .collect();
            let centre = mean(axle.iter().map(|&i| rest[i as usize].1));
            let z = centre.z;
            let tyre = rest
                .iter()
                .filter(|(_, x)| {
                    !in_any(*x)
                        && (x.z - z).abs() < 2.0 * TRUCK_H
                        && (*x - centre).truncate().length() < WHEEL_REACH
                })
                .map(|(i, x)| (*i, (*x - centre).truncate().length()))
                .collect();
            Wheel { hub, axle, tyre }
        })
        .collect();
    for w in &wheels {
        assert_eq!(
            w.axle.len(),
            4,
            "an axle runs through its wheel's four layers"
        );
        assert!(
            w.hub.len() > 30 && w.tyre.len() > 40,
            "{} {}",
            w.hub.len(),
            w.tyre.len()
        );
    }
    let dt = scene.config.dt;
    let mut frames: Vec<Frame> = Vec::new();
    let mut before = rest.clone();
    for _ in 0..scene.frames {
        sim.step();
        let now = sim.positions(body).unwrap();
        assert!(
            now.iter().all(|(_, x)| x.is_finite()),
            "a NaN after {} frames",
            frames.len()
        );
        let at = |x: &[(u32, Vec3)], i: u32| x[i as usize].1;
        let mut frame = Frame {
            chassis: mean(chassis.iter().map(|&i| at(&now, i))),
            centres: [Vec3::ZERO; 4],
            spins: [0.0; 4],
            deflection: [0.0; 4],
            compression: [0.0; 4],
        };
        for (w, wheel) in wheels.iter().enumerate() {
            let centre = mean(wheel.axle.iter().map(|&i| at(&now, i)));
            let hub = |x: &[(u32, Vec3)]| wheel.hub.iter().map(|&i| at(x, i)).collect::<Vec<_>>();
            let (turn, ..) = rigid_fit(&hub(&before), &hub(&now));
            frame.centres[w] = centre;
            frame.spins[w] = turn.to_scaled_axis().z / dt;
            frame.deflection[w] = WHEEL_REACH - clearance(centre);
            frame.compression[w] = wheel
                .tyre
                .iter()
                .map(|&(i, r)| r - (at(&now, i) - centre).truncate().length())
                .fold(0.0, f32::max);
        }
        frames.push(frame);
        before = now;
    }
    let travelled = frames.last().unwrap().chassis.x - frames[0].chassis.x;
    eprintln!(
        "truck: travelled {travelled:.2} m = {:.1} lengths of {TRUCK_LENGTH} m",
        travelled / TRUCK_LENGTH
    );
    assert!(travelled >= 10.0 * TRUCK_LENGTH, "{travelled} m");
    let (bump, _) = BUMP;
    // on the flat: every wheel past the slope's foot by a metre, a metre short of the bump
    let flat: Vec<usize> = (1..frames.len())
        .filter(|&k| {
            let xs = frames[k].centres.map(|c| c.x);
            xs.iter().all(|&x| x > 1.0 && x < bump - 1.0)
        })
        .collect();
    assert!(flat.len() > 20, "{} frames on the flat", flat.len());
    let speed = |k: usize| (frames[k].chassis.x - frames[k - 1].chassis.x) / dt;
    let mean = |ks: &[usize], f: &dyn Fn(usize) -> f32| {
        ks.iter().map(|&k| f(k)).sum::<f32>() / ks.len() as f32
    };
    for w in 0..4 {
        // rolling without slipping: spin = ground speed / radius, the radius being the
        // axle's height above the ground (the tyre is loaded)
        let rolling = mean(&flat, &|k| {
            -frames[k].spins[w] * frames[k].centres[w].y / speed(k)
        });
        // the tyre's deflection on the flat, over the bump (the wheel's centre within a
        // wheel's reach of it) and on the flat after it; and its shape after the bump
        let beside = |lo: f32, hi: f32| -> Vec<usize> {
            (0..frames.len())
                .filter(|&k| (lo..hi).contains(&(frames[k].centres[w].x - bump)))
                .collect()
        };
        let (over, after) = (beside(-WHEEL_REACH, WHEEL_REACH), beside(1.0, 2.5));
        assert!(
            !over.is_empty() && after.len() > 20,
            "{} {}",
            over.len(),
            after.len()
        );
        let deflection = |k: usize| frames[k].deflection[w] / TRUCK_H;
        let compression = |k: usize| frames[k].compression[w] / TRUCK_H;
        let (on_flat, after_bump) = (mean(&flat, &deflection), mean(&after, &deflection));
        let peak = over.iter().map(|&k| deflection(k)).fold(0.0, f32::max);
        let shape = (mean(&flat, &compression), mean(&after, &compression));
        eprintln!(
            "wheel {w}: on the flat ({} frames, {:.2} m/s) spin × radius / speed {rolling:.3}; \
             tyre deflected {on_flat:.2} h on the flat, {peak:.2} h over the bump, {after_bump:.2} h after it; \
             deepest compression {:.2} h on the flat, {:.2} h after the bump",
            flat.len(),
            mean(&flat, &speed),
            shape.0,
            shape.1
        );
        assert!((0.8..=1.2).contains(&rolling), "wheel {w}: {rolling}");
        // (the rear wheels meet the bump with the truck pitching from the front's hit)
        assert!(peak >= 1.5 * on_flat, "wheel {w}: {peak} h vs {on_flat} h");
        assert!(
            (after_bump - on_flat).abs() <= 0.25 * on_flat,
            "wheel {w}: {after_bump} h vs {on_flat} h"
        );
        assert!(shape.1 <= 1.25 * shape.0, "wheel {w}: {shape:?}");
    }
}
