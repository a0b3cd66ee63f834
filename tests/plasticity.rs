//! Plasticity in both models (SPEC §5, material `yield_strain`, `creep`,
//! `max_plastic_strain`), checked against the same block without yield: a plastic block
//! pressed by a sphere keeps a dent, an elastic one springs back, and in
//! both models the dent survives the solver laying its layout out afresh and a cut
//! beside it.

use cleave::ecs::layout::SolverCache;
use cleave::io::scene::builtin;
use cleave::prelude::*;

/// The `dent` scene's lattice spacing.
fn dent_h() -> f32 {
    builtin("dent", 0).unwrap().bodies[0].spacing
}

fn start(scene: &cleave::ecs::desc::Scene) -> (Simulation, Entity) {
    let mut sim = Simulation::from_scene(scene).unwrap();
    let body = sim.bodies()[0];
    (sim, body)
}

/// The depth (metres) of the dent at the middle of the block's top in the `dent` scene
/// with its block of `model` and yield strain `yield_strain`: the deepest it went, and
/// what is left at the end.
fn dent(model: Model, yield_strain: f32) -> (f32, f32) {
    dent_with(model, yield_strain, Change::None)
}

/// What happens to the dented block's layout while the sphere lifts off (it rises from
/// 3.0 s to 3.5 s).
#[derive(Clone, Copy, PartialEq)]
enum Change {
    None,
    /// A second body is spawned far away at 3.2 s, so that the solver lays its layout
    /// out afresh.
    Spawn,
    /// A blade severs the block 4 spacings from the dent's middle, from 4.0 s to 4.3 s:
    /// the clusters it passes are rebuilt, the others patched around them.
    Cut,
}

/// [`dent`], with `change`.
fn dent_with(model: Model, yield_strain: f32, change: Change) -> (f32, f32) {
    let h = dent_h();
    let mut scene = builtin("dent", 0).unwrap();
    scene.bodies[0].material.model = model;
    scene.bodies[0].material.yield_strain = yield_strain;
    if change == Change::Cut {
        // (the blade's normal is its local z: turned to x)
        let at = |y: f32| Pose {
            position: Vec3::new(4.0 * h, y, 0.0),
            rotation: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
        };
        scene.tools.push(ToolDesc {
            shape: ToolShape::Blade {
                half_width: 1.0,
                half_height: 0.2,
            },
            cut_width: 0.25 * h,
            cut_mode: CutMode::Sever,
            path: Path {
                keys: vec![(4.0, at(0.8)), (4.3, at(-0.25)), (4.35, at(-5.0))],
            },
            pose: at(0.8),
        });
    }
    let spawn_at = (3.2 / scene.config.dt).round() as u32;
    let (mut sim, body) = start(&scene);
    // the four top particles around the middle (the sphere's axis)
    let rest = sim.positions(body).unwrap();
    let top = rest.iter().map(|(_, x)| x.y).fold(f32::MIN, f32::max);
    let middle: Vec<u32> = rest
        .iter()
        .filter(|(_, x)| x.y > top - 0.1 * h && x.x.abs() < h && x.z.abs() < h)
        .map(|(i, _)| *i)
        .collect();
    assert_eq!(middle.len(), 4);
    let depth = |sim: &Simulation| {
        let x = sim.positions(body).unwrap();
        // against the block's top far from the dent (its corners on the side of the
        // cut the dent is on), so that the whole block settling on the ground does not
        // count
        let corners: Vec<f32> = x
            .iter()
            .zip(&rest)
            .filter(|(_, (_, r))| r.y > top - 0.1 * h)
            .filter(|(_, (_, r))| r.x < -4.0 * h && r.z.abs() > 4.0 * h)
            .map(|((_, p), _)| p.y)
            .collect();
        let corner = corners.iter().sum::<f32>() / corners.len() as f32;
        let mid = middle.iter().map(|&i| x[i as usize].1.y).sum::<f32>() / 4.0;
        corner - mid
    };
    let mut deepest = 0.0f32;
    for frame in 0..scene.frames {
        let spawn = change == Change::Spawn && frame == spawn_at;
        if spawn {
            let mut far = BodyDesc::new(Shape::cuboid(UVec3::splat(2)), h);
            far.position = Vec3::new(3.0, 0.1, 0.0);
            sim.spawn_body(&far).unwrap();
        }
        sim.step();
        if spawn {
            let update = sim.world().resource::<SolverCache>().layout.last_update();
            assert!(update.is_some_and(|u| !u.patched), "a fresh layout");
        }
        deepest = deepest.max(depth(&sim));
    }
    if change == Change::Cut {
        let pieces = sim.pieces(body).unwrap().len();
        assert!(pieces >= 2, "the blade severs the block: {pieces} piece");
    }
    (deepest, depth(&sim))
}

#[test]
fn a_plastic_block_keeps_a_dent_and_an_elastic_one_springs_back() {
    let yield_strain = builtin("dent", 0).unwrap().bodies[0].material.yield_strain;
    for model in [Model::Oriented, Model::Clusters] {
        let (deepest, left) = dent(model, yield_strain);
        let (elastic_deepest, elastic_left) = dent(model, 0.0);
        eprintln!(
            "dent, {model:?}: plastic {:.3} h deepest, {:.3} h left; elastic {:.3} h deepest, {:.3} h left",
            deepest / 0.05,
            left / 0.05,
            elastic_deepest / 0.05,
            elastic_left / 0.05
        );
        assert!(
            deepest > 0.05,
            "{model:?}: the sphere dents the block: {deepest} m"
        );
        assert!(left >= 0.5 * deepest, "{model:?}: {left} of {deepest}");
        assert!(
            elastic_left.abs() <= 0.05 * elastic_deepest,
            "{model:?}: {elastic_left} of {elastic_deepest}"
        );
    }
}

#[test]
fn a_fresh_layout_and_a_cut_beside_it_keep_the_dent_in_both_models() {
    let yield_strain = builtin("dent", 0).unwrap().bodies[0].material.yield_strain;
    for model in [Model::Clusters, Model::Oriented] {
        let (_, left) = dent(model, yield_strain);
        let (_, rebuilt_left) = dent_with(model, yield_strain, Change::Spawn);
        let (_, cut_left) = dent_with(model, yield_strain, Change::Cut);
        eprintln!(
            "{model:?}: dent left: {:.3} h; with a fresh layout as the sphere lifts: {:.3} h; severed beside it: {:.3} h",
            left / dent_h(),
            rebuilt_left / dent_h(),
            cut_left / dent_h()
        );
        assert!(
            (rebuilt_left - left).abs() <= 0.1 * left,
            "{model:?}: {rebuilt_left} vs {left}"
        );
        assert!(
            (cut_left - left).abs() <= 0.1 * left,
            "{model:?}: {cut_left} vs {left}"
        );
    }
}
