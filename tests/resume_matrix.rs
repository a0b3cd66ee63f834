//! Every built-in scene resumes bit for bit: in each cut mode (scenes with tools), in
//! both models and with surface patches on and off, a run saved mid-way and loaded goes
//! on exactly as the run that was never interrupted (the `cleave-state` dumps of both,
//! byte for byte). Short runs: the save, the load and the frames after them are what is
//! checked; cuts in progress across a save are `save_resume.rs`'s and `scene_cuts.rs`'s.

use cleave::config::Model;
use cleave::ecs::desc::Scene;
use cleave::io::dump::dump_world;
use cleave::io::scene::{BUILTIN_SCENES, builtin};
use cleave::prelude::*;
use rayon::prelude::*;

/// Frames before the save, and after it.
const BEFORE: u32 = 3;
const AFTER: u32 = 4;

/// The dump of `scene` run straight, and the dump of it saved after [`BEFORE`] frames,
/// loaded and run on.
fn straight_and_resumed(scene: &Scene) -> (String, String) {
    let dump = |sim: &mut Simulation| serde_json::to_string(&dump_world(sim.world_mut())).unwrap();
    let mut straight = Simulation::from_scene(scene).unwrap();
    straight.run(BEFORE + AFTER);
    let mut first = Simulation::from_scene(scene).unwrap();
    first.run(BEFORE);
    let mut bytes = Vec::new();
    first.save(&mut bytes).unwrap();
    let mut resumed = Simulation::load(bytes.as_slice()).unwrap();
    resumed.run(AFTER);
    (dump(&mut straight), dump(&mut resumed))
}

#[test]
fn every_builtin_scene_resumes_bit_for_bit_in_every_mode_model_and_with_patches() {
    let mut cases = Vec::new();
    for name in BUILTIN_SCENES.map(|b| b.name) {
        let scene = builtin(name, 0).unwrap();
        let modes: &[Option<CutMode>] = if scene.tools.is_empty() {
            &[None]
        } else {
            &[
                Some(CutMode::Remove),
                Some(CutMode::Sever),
                Some(CutMode::Split),
            ]
        };
        for &mode in modes {
            for model in [Model::Clusters, Model::Oriented] {
                for patches in [false, true] {
                    cases.push((name.to_string(), mode, model, patches));
                }
            }
        }
    }
    let outcomes: Vec<Option<String>> = cases
        .par_iter()
        .filter_map(|(name, mode, model, patches)| -> Option<Option<String>> {
            let (mode, model, patches) = (*mode, *model, *patches);
            let mut scene = builtin(name, 0).unwrap();
            for tool in &mut scene.tools {
                tool.cut_mode = mode.unwrap_or(tool.cut_mode);
            }
            for body in &mut scene.bodies {
                body.material.model = model;
                if patches {
                    body.material.patch_normal_compliance = Some(1e-7);
                    body.material.patch_tangent_compliance = Some(1e-5);
                }
            }
            let case = format!("{name} {mode:?} {model} patches {patches}");
            // a scene that cannot be built in this model is not a resume to check
            Simulation::from_scene(&scene).ok()?;
            let (a, b) = straight_and_resumed(&scene);
            Some((a != b).then_some(case))
        })
        .collect();
    let failures: Vec<String> = outcomes.iter().flatten().cloned().collect();
    eprintln!(
        "{} cases, {} built and resumed",
        cases.len(),
        outcomes.len()
    );
    assert!(outcomes.len() >= cases.len() - 8, "most cases build");
    assert!(failures.is_empty(), "not bit for bit: {failures:#?}");
}
