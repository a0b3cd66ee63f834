//! The colliders term's tests: pushes out of the ground and of posed shapes, friction,
//! moving colliders, depenetration a step at a time, block culling.

use super::*;
use crate::geometry::collider::ColliderShape;
use glam::{Quat, Vec3};

fn ground(friction: f32) -> Colliders {
    Colliders::new(
        Some(GroundPlane {
            height: 0.0,
            friction,
        }),
        vec![],
    )
}

#[test]
fn ground_and_boxes_push_out() {
    let block = PosedCollider::fixed(
        ColliderShape::Box {
            half_extents: Vec3::splat(0.5),
        },
        0.0,
        Pose::at(Vec3::splat(1.5)),
    );
    let colliders = Colliders::new(ground(0.0).ground, vec![block]);
    let p = colliders.resolve(Vec3A::new(0.0, -0.5, 0.0), Vec3A::ZERO, 0.0);
    assert_eq!(p.y, 0.0);
    let p = colliders.resolve(Vec3A::new(1.5, 1.9, 1.5), Vec3A::new(1.5, 2.5, 1.5), 0.0);
    assert!((p - Vec3A::new(1.5, 2.0, 1.5)).length() < 1e-6, "{p}");
}

#[test]
fn friction_stops_small_slides() {
    let colliders = ground(1.0);
    // slid 0.05 sideways while sinking 0.1: the friction cone holds it
    let p = colliders.resolve(Vec3A::new(0.05, -0.1, 0.0), Vec3A::ZERO, 0.0);
    assert_eq!(p, Vec3A::ZERO);
    // slid 0.5 sideways while sinking 0.1: kinetic friction removes 0.1 of it
    let p = colliders.resolve(Vec3A::new(0.5, -0.1, 0.0), Vec3A::ZERO, 0.0);
    assert!((p.x - 0.4).abs() < 1e-6 && p.y == 0.0, "{p}");
}

/// A 0.6 m box turned about Y (0.5 rad), without friction.
fn turned_block() -> PosedCollider {
    PosedCollider::fixed(
        ColliderShape::Box {
            half_extents: Vec3::splat(0.3),
        },
        0.0,
        Pose {
            position: Vec3::ZERO,
            rotation: Quat::from_rotation_y(0.5),
        },
    )
}

#[test]
fn a_fast_particle_stops_at_the_face_it_came_through() {
    // a particle crossing the turned box in one substep, ending beyond it or just
    // inside its far face
    let block = turned_block();
    let colliders = Colliders::new(None, vec![block.clone()]);
    for end_x in [2.0, 0.25] {
        let (from, to) = (Vec3A::new(-2.0, 0.05, 0.0), Vec3A::new(end_x, 0.05, 0.0));
        let p = colliders.resolve(to, from, 0.0);
        assert!(p.x < -0.29, "ended at {p} (end {end_x})");
        assert!(
            block
                .shape
                .signed_distance(block.end_inverse.transform_point3a(p))
                > -1e-5
        );
    }
}

#[test]
fn a_particle_sliding_on_a_face_is_not_taken_for_one_passing_through() {
    // resting on the top face of a box, it slides 0.1 sideways and lifts off
    // slightly: outside at both ends, a graze along the face
    let block = PosedCollider::fixed(
        ColliderShape::Box {
            half_extents: Vec3::splat(0.5),
        },
        0.3,
        Pose::at(Vec3::ZERO),
    );
    let from = Vec3A::new(0.0, 0.5, 0.0);
    for to in [Vec3A::new(0.1, 0.5, 0.0), Vec3A::new(0.1, 0.5001, 0.0)] {
        assert_eq!(block.resolve(to, from, 0.0), None, "{to}");
    }
    // sinking a little while it slides: kinetic friction, not a stop
    let (p, depth_before) = block
        .resolve(Vec3A::new(0.1, 0.49, 0.0), from, 0.0)
        .expect("a contact");
    assert_eq!(depth_before, 0.0);
    assert!((p.y - 0.5).abs() < 1e-6 && p.x > 0.09, "{p}");
}

#[test]
fn a_moving_collider_carries_particles_in_front_of_it() {
    // a plate moving +X by 0.5 in one substep past a particle at rest at x = 0.2
    let plate = ColliderShape::Box {
        half_extents: Vec3::new(0.05, 1.0, 1.0),
    };
    let moving = PosedCollider::new(
        plate,
        0.0,
        Pose::at(Vec3::new(0.0, 0.0, 0.0)),
        Pose::at(Vec3::new(0.5, 0.0, 0.0)),
    );
    let at = Vec3A::new(0.2, 0.3, 0.0);
    let (p, depth_before) = moving
        .resolve(at, at, 0.0)
        .expect("the plate reaches the particle");
    assert_eq!(depth_before, 0.0, "the plate came to it");
    assert!(
        (p.x - 0.55).abs() < 1e-5,
        "pushed to the plate's front face: {p}"
    );
    // a particle behind the plate is left alone
    let behind = Vec3A::new(-0.2, 0.3, 0.0);
    assert_eq!(moving.resolve(behind, behind, 0.0), None);
}

#[test]
fn a_particle_that_began_the_substep_deep_in_a_collider_comes_out_a_step_at_a_time() {
    // a particle that starts and ends 0.3 deep in a box (or below the ground) comes
    // out by `depenetration_step` per substep
    let mut colliders = Colliders::new(
        ground(0.0).ground,
        vec![PosedCollider::fixed(
            ColliderShape::Box {
                half_extents: Vec3::splat(0.5),
            },
            0.0,
            Pose::at(Vec3::new(0.0, 0.0, 3.0)),
        )],
    );
    colliders.depenetration_step = 0.01;
    for (inside, out) in [
        (Vec3A::new(0.0, 0.2, 3.0), Vec3A::new(0.0, 0.21, 3.0)),
        (Vec3A::new(0.0, -0.3, 0.0), Vec3A::new(0.0, -0.29, 0.0)),
    ] {
        let p = colliders.resolve(inside, inside, 0.0);
        assert!(p.distance(out) < 1e-6, "{p}");
        // one that came in during the substep goes out at once, from either
        let entered = colliders.resolve(inside, inside + Vec3A::new(0.0, 0.8, 0.0), 0.0);
        assert!((entered.y - (out.y + 0.29)).abs() < 1e-6, "{entered}");
    }
}

#[test]
fn blocks_far_from_every_collider_are_skipped_and_near_ones_are_not() {
    let colliders = Colliders::new(
        ground(0.5).ground,
        vec![PosedCollider::fixed(
            ColliderShape::Sphere { radius: 0.5 },
            0.5,
            Pose::at(Vec3::new(2.0, 1.0, 0.0)),
        )],
    );
    assert!(!colliders.reaches(Vec3A::new(-1.0, 0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.0));
    assert!(colliders.reaches(Vec3A::new(-1.0, -0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.0));
    assert!(colliders.reaches(Vec3A::new(1.0, 0.1, -1.0), Vec3A::new(1.6, 2.0, 1.0), 0.0));
    // a ball of radius 0.2 reaches the ground from 0.1 above it
    assert!(colliders.reaches(Vec3A::new(-1.0, 0.1, -1.0), Vec3A::new(1.0, 2.0, 1.0), 0.2));
    let (lo, hi) = bounds(&[Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 0.0)]);
    assert!(
        colliders.reaches(lo, hi, 0.0),
        "a NaN point is never skipped over"
    );
}

#[test]
fn balls_rest_with_their_radius_on_the_ground_and_on_colliders() {
    let r = 0.05;
    let p = ground(0.0).resolve(Vec3A::new(0.0, 0.01, 0.0), Vec3A::new(0.0, 0.2, 0.0), r);
    assert_eq!(p.y, r);
    // a fast ball crossing the turned box stops a radius short of the face it came
    // through
    let block = turned_block();
    let colliders = Colliders::new(None, vec![block.clone()]);
    for end_x in [2.0, 0.25, -0.3] {
        let (from, to) = (Vec3A::new(-2.0, 0.05, 0.0), Vec3A::new(end_x, 0.05, 0.0));
        let p = colliders.resolve(to, from, r);
        let local = block.end_inverse.transform_point3a(p);
        let gap = block.shape.signed_distance(local);
        assert!(
            (gap - r).abs() < 1e-4,
            "ended {gap} from the box (end {end_x})"
        );
        assert!(p.x < -0.29, "{p}");
    }
    // resting on the top face a radius above it is a graze, not a contact
    let flat = PosedCollider::fixed(
        ColliderShape::Box {
            half_extents: Vec3::splat(0.5),
        },
        0.3,
        Pose::at(Vec3::ZERO),
    );
    let from = Vec3A::new(0.0, 0.5 + r, 0.0);
    assert_eq!(flat.resolve(Vec3A::new(0.1, 0.5 + r, 0.0), from, r), None);
}

/// The ground alone is projected by its own loop (`project_on_ground`): on a body of
/// one block (run on the calling thread) and of several (in parallel), every particle
/// ends where the general resolve puts it — pushed out, with friction, a deep one held
/// back a step, a held one (inverse mass 0) and one above the ground untouched.
#[test]
fn the_ground_alone_moves_each_particle_as_the_general_resolve_does() {
    let mut colliders = ground(0.6);
    colliders.depenetration_step = 0.05;
    for n in [100, 3 * PARTICLES_PER_TASK + 7] {
        let previous: Vec<Vec3A> = (0..n)
            .map(|i| {
                let t = i as f32;
                Vec3A::new((t * 0.37).sin(), 0.2 * (t * 0.11).cos(), (t * 0.53).cos())
            })
            .collect();
        let start: Vec<Vec3A> = (previous.iter().enumerate())
            .map(|(i, p)| *p + Vec3A::new(0.03 * (i as f32).cos(), -0.15, 0.02))
            .collect();
        let inv_mass: Vec<f32> = (0..n)
            .map(|i| if i % 13 == 0 { 0.0 } else { 1.0 })
            .collect();
        let expected: Vec<(Vec3A, bool)> = (0..n)
            .map(|i| match inv_mass[i] == 0.0 || start[i].y >= 0.0 {
                true => (start[i], false),
                false => colliders.resolve_holding_back(start[i], previous[i], 0.0),
            })
            .collect();
        let mut positions = start.clone();
        let mut corrections = vec![Vec3A::ZERO; n];
        let mut orientations = vec![Quat::IDENTITY; n];
        let mut state = ParticleState {
            positions: &mut positions,
            previous: &previous,
            inv_mass: &inv_mass,
            corrections: &mut corrections,
            orientations: &mut orientations,
            spins: &[],
        };
        let step = Substep {
            dt: 0.01,
            iterations: 1,
            frame_span: [0.0, 1.0],
        };
        colliders.begin_substep(&step, &mut state);
        colliders.project(&step, &mut state);
        for (i, (to, held)) in expected.iter().enumerate() {
            assert_eq!((positions[i], colliders.held[i]), (*to, *held), "{n}: {i}");
            assert_eq!(corrections[i], *to - start[i], "{n}: {i}");
        }
        let pushed = (0..n).filter(|&i| positions[i] != start[i]).count();
        assert!(pushed > n / 4, "{n}: only {pushed} pushed");
        assert!(colliders.held.contains(&true), "{n}: none held back");
    }
}
