//! Relaxation (SPEC §6.1): jittered bodies settle into their rest shape while the
//! centroids of their boundary sets stay where they started; what the centroid holds
//! and the patches each contribute, measured by switching them off
//! (`cargo test --release --test relax -- --nocapture` prints the figures).

use cleave::body::shape::Shape;
use cleave::config::{Material, RelaxOptions, SimConfig};
use cleave::ecs::components::{Attachment, Body, Velocity};
use cleave::ecs::desc::BodyDesc;
use cleave::sim::relax_report::RelaxReport;
use cleave::sim::simulation::Simulation;
use glam::{UVec3, Vec3};

const H: f32 = 0.05;

/// The four ways to relax: both kinds of hold, either, neither.
fn variants() -> [(&'static str, RelaxOptions); 4] {
    let with = |patches, centroids| RelaxOptions {
        patches,
        centroids,
        ..Default::default()
    };
    [
        ("both", with(true, true)),
        ("no patches", with(false, true)),
        ("no centroids", with(true, false)),
        ("neither", with(false, false)),
    ]
}

/// A soft (gel) body of `shape` at 2 m, every particle jittered by up to 0.3 h.
fn jittered(shape: Shape) -> BodyDesc {
    BodyDesc {
        material: Material::gel(),
        position: Vec3::new(0.0, 2.0, 0.0),
        jitter: 0.3,
        ..BodyDesc::new(shape, H)
    }
}

fn print(case: &str, label: &str, r: &RelaxReport) {
    eprintln!(
        "{case:>14} {label:>12}: {:>3} frames, shape error {:.4} h → {:.4} h, \
         boundary drift {:.1e} h over {} sets, rms speed {:.4} h/s",
        r.frames,
        r.shape_error_before,
        r.shape_error,
        r.boundary_drift,
        r.boundary_sets,
        r.rms_speed
    );
}

#[test]
fn jittered_bodies_return_to_their_rest_shape_with_their_boundary_in_place() {
    for (case, shape) in [
        ("block 24×12×12", Shape::cuboid(UVec3::new(24, 12, 12))),
        ("sphere r 8 h", Shape::Sphere { radius: 8.0 * H }),
    ] {
        let reports: Vec<RelaxReport> = variants()
            .iter()
            .map(|(label, options)| {
                let mut sim = Simulation::new(SimConfig::default()).expect("a simulation");
                let body = sim.spawn_body(&jittered(shape.clone())).expect("a body");
                let report = sim.relax(body, options).expect("relaxed");
                print(case, label, &report);
                report
            })
            .collect();
        for r in &reports {
            assert!(r.converged, "{case}: {r:?}");
            assert!(r.shape_error_before > 0.2, "{case}: {r:?}");
            assert!(r.shape_error < 0.05, "{case}: {r:?}");
            assert!(r.boundary_sets > 10, "{case}: {r:?}");
        }
        // the holds keep every boundary set's centroid where it started
        let (both, no_patches, no_centroids) = (&reports[0], &reports[1], &reports[2]);
        assert!(both.boundary_drift < 1e-4, "{case}: {both:?}");
        assert!(no_patches.boundary_drift < 1e-4, "{case}: {no_patches:?}");
        // without them the centroids move by the jitter's mean over each set, and the
        // shape comes closer to its rest: the jittered centroids are not the rest's
        assert!(
            no_centroids.boundary_drift > 0.01,
            "{case}: {no_centroids:?}"
        );
        assert!(no_centroids.shape_error < both.shape_error, "{case}");
    }
}

#[test]
fn a_body_pushed_by_an_overlapping_one_is_held_in_place_by_its_boundary() {
    let relaxed = |options: &RelaxOptions| {
        let mut sim = Simulation::new(SimConfig::default()).expect("a simulation");
        let body = sim
            .spawn_body(&jittered(Shape::cuboid(UVec3::new(24, 12, 12))))
            .expect("a body");
        // a rigid block overlapping the body's +x face by half a spacing
        let other = BodyDesc {
            material: Material::rigid(),
            position: Vec3::new(15.5 * H, 2.0, 0.0),
            ..BodyDesc::new(Shape::cuboid(UVec3::new(8, 12, 12)), H)
        };
        sim.spawn_body(&other).expect("another body");
        sim.relax(body, options).expect("relaxed")
    };
    let reports: Vec<RelaxReport> = variants()
        .iter()
        .map(|(label, options)| {
            let report = relaxed(options);
            print("pushed block", label, &report);
            report
        })
        .collect();
    assert!(reports.iter().all(|r| r.converged), "{reports:?}");
    // held, the body gives way only at its face; free, the whole body is pushed off
    assert!(reports[0].boundary_drift < 0.05, "{:?}", reports[0]);
    assert!(reports[2].boundary_drift > 0.3, "{:?}", reports[2]);
    assert!(reports[0].shape_error > reports[2].shape_error);
}

#[test]
fn relaxing_leaves_the_rest_of_the_world_as_it_was() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(SimConfig::default())?;
    let body = sim.spawn_body(&jittered(Shape::cuboid(UVec3::new(8, 6, 6))))?;
    let flying = BodyDesc {
        position: Vec3::new(2.0, 3.0, 0.0),
        velocity: Vec3::new(1.0, 2.0, 0.0),
        ..BodyDesc::new(Shape::cuboid(UVec3::new(4, 4, 4)), H)
    };
    let other = sim.spawn_body(&flying)?;
    let before = (sim.positions(other)?, sim.velocities(other)?);
    let material = sim.world().get::<Body>(body).map(|b| b.material.clone());
    let report = sim.relax(body, &RelaxOptions::default())?;
    assert!(report.converged && report.frames > 1, "{report:?}");
    assert_eq!((sim.positions(other)?, sim.velocities(other)?), before);
    assert_eq!(
        sim.world().get::<Body>(body).map(|b| b.material.clone()),
        material
    );
    let attachments = sim
        .world_mut()
        .query::<&Attachment>()
        .iter(sim.world())
        .count();
    assert_eq!(attachments, 0, "the holds and pins are gone");
    assert_eq!(sim.config(), &SimConfig::default());
    // the next frame runs with gravity again, from the time relaxation started
    sim.step();
    let fell = sim.velocities(body)?.iter().all(|(_, v)| v.y < 0.0);
    assert!(fell, "gravity acts after relaxing");
    let moved: Vec<Velocity> = sim
        .velocities(other)?
        .iter()
        .map(|(_, v)| Velocity(*v))
        .collect();
    assert!(
        moved.iter().all(|v| v.0.x > 0.9),
        "the other body kept its speed"
    );
    Ok(())
}

#[test]
fn bad_options_and_entities_are_errors_naming_what_is_wrong() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(SimConfig::default())?;
    let body = sim.spawn_body(&jittered(Shape::cuboid(UVec3::new(4, 4, 4))))?;
    // (every field's check is `RelaxOptions::validate`'s, tested with it)
    let bad = RelaxOptions {
        tolerance: f32::NAN,
        ..Default::default()
    };
    let e = sim.relax(body, &bad).unwrap_err().to_string();
    assert!(e.contains("relax.tolerance"), "{e}");
    let nothing = sim.world_mut().spawn_empty().id();
    let e = sim.relax(nothing, &RelaxOptions::default()).unwrap_err();
    assert!(e.to_string().contains("is not a body"), "{e}");
    let e = sim
        .spawn_body(&BodyDesc {
            jitter: 0.6,
            ..jittered(Shape::cuboid(UVec3::new(4, 4, 4)))
        })
        .unwrap_err();
    assert!(e.to_string().contains("body.jitter"), "{e}");
    Ok(())
}

#[test]
fn a_scene_that_asks_for_it_is_relaxed_when_it_is_built() -> cleave::error::Result<()> {
    let scene = cleave::io::scene::builtin("jittered", 0).expect("a built-in");
    let sim = Simulation::from_scene(&scene)?;
    let reports = sim.relax_reports();
    assert_eq!(reports.len(), 2);
    for (body, report) in reports {
        assert!(report.converged && report.shape_error < 0.05, "{report:?}");
        assert!(sim.positions(*body)?.len() > 1000);
    }
    // and one that does not ask is not
    let mut plain = scene.clone();
    plain.config.relax = None;
    assert!(Simulation::from_scene(&plain)?.relax_reports().is_empty());
    Ok(())
}
