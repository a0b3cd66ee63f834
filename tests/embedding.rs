//! What a game embedding cleave relies on, outside Bevy: the handles of a saved
//! simulation map to the same bodies, tools, colliders and attachments after a load
//! while the old entities are refused; poses set from code are checked; attachments are
//! made, moved and released at run time; the last frame's messages are read without
//! Bevy; centroids of a body and of its pieces.

use cleave::prelude::*;

const H: f32 = 0.1;

fn block(cells: UVec3, at: Vec3) -> BodyDesc {
    let mut desc = BodyDesc::new(Shape::cuboid(cells), H);
    desc.position = at;
    desc
}

/// A still world (no gravity, no ground) with a box, a ball, a tool moved by code, a
/// collider and an attachment; and their entities.
fn scene() -> cleave::error::Result<(Simulation, [Entity; 5])> {
    let mut sim = Simulation::new(SimConfig {
        gravity: Vec3::new(0.0, -3.0, 0.0),
        ground: None,
        ..SimConfig::default()
    })?;
    let boxed = sim.spawn_body(&block(UVec3::new(6, 4, 4), Vec3::ZERO))?;
    let mut ball = BodyDesc::new(Shape::Sphere { radius: 0.25 }, H);
    ball.position = Vec3::new(2.0, 0.0, 0.0);
    let ball = sim.spawn_body(&ball)?;
    let tool = sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Sphere { radius: 0.05 },
        cut_width: 0.05,
        cut_mode: CutMode::Remove,
        path: Path::default(),
        pose: Pose::at(Vec3::new(0.0, 5.0, 0.0)),
    })?;
    let collider = sim.spawn_collider(&ColliderDesc {
        shape: ColliderShape::Sphere { radius: 0.2 },
        friction: 0.0,
        pose: Pose::at(Vec3::new(-3.0, 0.0, 0.0)),
        path: Path::default(),
    })?;
    let attachment = sim.attach(boxed, &[0, 1, 2], 1e-4)?;
    Ok((sim, [boxed, ball, tool, collider, attachment]))
}

#[test]
fn handles_map_through_a_load_and_old_entities_are_refused() -> cleave::error::Result<()> {
    let (mut sim, handles) = scene()?;
    let [boxed, ball, tool, collider, attachment] = handles;
    sim.run(5);
    let mut bytes = Vec::new();
    sim.save(&mut bytes)?;
    let mut loaded = Simulation::load(bytes.as_slice())?;
    let new: Vec<Entity> = handles
        .iter()
        .map(|h| loaded.loaded_entity(*h))
        .collect::<cleave::error::Result<_>>()?;
    // the same bodies, in the same order, with the same state
    let original: Vec<Entity> = sim
        .bodies()
        .iter()
        .map(|b| loaded.loaded_entity(*b))
        .collect::<cleave::error::Result<_>>()?;
    assert_eq!(loaded.bodies(), original);
    let mut both = vec![new[0], new[1]];
    both.sort_unstable();
    assert_eq!(original, both);
    assert_eq!(loaded.positions(new[0])?, sim.positions(boxed)?);
    assert_eq!(loaded.positions(new[1])?, sim.positions(ball)?);
    // every handle kept from before names nothing in the loaded simulation
    for old in [boxed, ball] {
        let e = loaded.positions(old).expect_err("an old body").to_string();
        assert!(e.contains("before a load"), "{e}");
    }
    let here = Pose::at(Vec3::ONE);
    assert!(loaded.set_tool_pose(tool, here).is_err());
    assert!(loaded.set_collider_pose(collider, here).is_err());
    assert!(loaded.move_attachment(attachment, here).is_err());
    assert!(loaded.detach(attachment).is_err());
    loaded.set_tool_pose(new[2], here)?;
    loaded.set_collider_pose(new[3], here)?;
    loaded.move_attachment(new[4], here)?;
    // a particle is not a handle the map keeps; a fresh simulation has no map
    let particle = sim
        .world()
        .get::<BodyLattice>(boxed)
        .expect("a body")
        .particles[0];
    assert!(loaded.loaded_entity(particle).is_err());
    assert!(sim.loaded_entity(boxed).is_err());
    // loaded again from the loaded one: the first world's entities still name nothing
    let mut again = Vec::new();
    loaded.save(&mut again)?;
    let third = Simulation::load(again.as_slice())?;
    assert!(third.positions(boxed).is_err() && third.positions(new[0]).is_err());
    let body = third.loaded_entity(new[0])?;
    assert_eq!(third.positions(body)?, loaded.positions(new[0])?);
    Ok(())
}

#[test]
fn poses_set_from_code_are_checked() -> cleave::error::Result<()> {
    let (mut sim, [boxed, _, tool, collider, attachment]) = scene()?;
    let message = |r: cleave::error::Result<()>| r.expect_err("refused").to_string();
    let nan = Pose::at(Vec3::new(f32::NAN, 0.0, 0.0));
    let far = Pose::at(Vec3::new(0.0, 2e6, 0.0));
    let no_turn = Pose {
        position: Vec3::ZERO,
        rotation: Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
    };
    assert!(message(sim.set_tool_pose(tool, nan)).contains("tool pose.position"));
    assert!(message(sim.set_tool_pose(tool, far)).contains("1e6"));
    assert!(message(sim.set_tool_pose(tool, no_turn)).contains("tool pose.rotation"));
    assert!(message(sim.set_collider_pose(collider, nan)).contains("collider pose.position"));
    assert!(message(sim.move_attachment(attachment, far)).contains("attachment pose.position"));
    assert!(message(sim.set_tool_pose(boxed, Pose::at(Vec3::ZERO))).contains("is not a tool"));
    assert!(message(sim.set_collider_pose(tool, Pose::at(Vec3::ZERO))).contains("not a collider"));
    assert!(message(sim.detach(boxed)).contains("not an attachment"));
    // something a path drives refuses a pose from code
    let keyframed = sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Sphere { radius: 0.05 },
        cut_width: 0.05,
        cut_mode: CutMode::Remove,
        path: Path {
            keys: vec![
                (0.0, Pose::at(Vec3::Y * 5.0)),
                (1.0, Pose::at(Vec3::Y * 6.0)),
            ],
        },
        pose: Pose::at(Vec3::Y * 5.0),
    })?;
    assert!(message(sim.set_tool_pose(keyframed, Pose::at(Vec3::ZERO))).contains("path"));
    // a refused pose changed nothing
    let before = *sim.world().get::<ToolPose>(tool).expect("a tool");
    assert_eq!(before.current.position, Vec3::new(0.0, 5.0, 0.0));
    Ok(())
}

#[test]
fn an_attachment_drags_a_body_and_lets_go_at_run_time() -> cleave::error::Result<()> {
    let (mut sim, [boxed, .., first]) = scene()?;
    let centroid = |sim: &Simulation| -> cleave::error::Result<Vec3> {
        let p = sim.positions(boxed)?;
        Ok(p.iter().map(|(_, x)| *x).sum::<Vec3>() / p.len() as f32)
    };
    let start = centroid(&sim)?;
    // grab the top layer and pull it up 1 m over 30 frames
    let top: Vec<u32> = sim
        .positions(boxed)?
        .into_iter()
        .filter(|(_, x)| x.y > 0.1)
        .map(|(i, _)| i)
        .collect();
    let grab = sim.attach(boxed, &top, 1e-5)?;
    let held = sim
        .world()
        .get::<AttachmentTarget>(grab)
        .expect("a target")
        .pose;
    for frame in 1..=30 {
        let lift = Vec3::Y * (frame as f32 / 30.0);
        sim.move_attachment(grab, Pose::at(held.position + lift))?;
        sim.step();
    }
    let lifted = centroid(&sim)?;
    assert!(lifted.y - start.y > 0.8, "{start} → {lifted}");
    // let go of both attachments: it falls
    sim.detach(grab)?;
    sim.detach(first)?;
    assert!(sim.detach(grab).is_err(), "released twice");
    // it was rising at 2 m/s: under 3 m/s² it is back 2 m lower 2 s later
    sim.run(120);
    let fallen = centroid(&sim)?;
    assert!(fallen.y < lifted.y - 1.5, "{lifted} → {fallen}");
    Ok(())
}

#[test]
fn the_last_frames_messages_are_read_without_bevy() -> cleave::error::Result<()> {
    let mut sim = Simulation::new(SimConfig {
        gravity: Vec3::ZERO,
        ground: None,
        ..SimConfig::default()
    })?;
    let body = sim.spawn_body(&block(UVec3::new(8, 4, 4), Vec3::ZERO))?;
    let tool = sim.spawn_tool(&ToolDesc {
        shape: ToolShape::Blade {
            half_width: 1.0,
            half_height: 1.0,
        },
        cut_width: 0.05,
        cut_mode: CutMode::Sever,
        path: Path::default(),
        pose: Pose::at(Vec3::new(0.0, 2.0, 0.0)),
    })?;
    assert!(sim.messages::<BodySplit>().is_empty());
    sim.step();
    assert!(sim.messages::<BodySplit>().is_empty(), "nothing cut yet");
    // one frame's move from above the block to below it, set from code
    sim.set_tool_pose(tool, Pose::at(Vec3::new(0.0, -2.0, 0.0)))?;
    sim.step();
    let splits = sim.messages::<BodySplit>();
    assert_eq!(splits.len(), 1, "{splits:?}");
    assert_eq!(
        (
            splits[0].body,
            splits[0].pieces_before,
            splits[0].pieces_after
        ),
        (body, 1, 2)
    );
    assert!(!sim.messages::<EdgesSevered>().is_empty());
    assert_eq!(sim.pieces(body)?.len(), 2);
    // gravity off, nothing moved: the block's centre, and each half's (the blade lies
    // in the XY plane: 2 layers of 0.1 m on each side of z = 0, centres 0.1 m out),
    // ordered as the pieces
    assert!(sim.centroid(body)?.length() < 1e-5);
    let halves = sim.piece_centroids(body)?;
    let first_behind = sim.positions(body)?[0].1.z < 0.0;
    let expected = if first_behind {
        [-0.1, 0.1]
    } else {
        [0.1, -0.1]
    };
    for (c, z) in halves.iter().zip(expected) {
        assert!((*c - Vec3::new(0.0, 0.0, z)).length() < 1e-5, "{halves:?}");
    }
    sim.step();
    assert!(
        sim.messages::<BodySplit>().is_empty(),
        "only the last frame's"
    );
    Ok(())
}
