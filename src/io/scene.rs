//! Built-in scenes, listed once in [`BUILTIN_SCENES`]: most are scene files compiled
//! into the program (`src/io/scenes/NAME.ron`, read as any scene file is read, so
//! `cleave scenes show NAME` prints what the program holds); the scenes made from a seed
//! or a parameter (random cuts, the cut block, the scooped cantilever, the pile, the
//! truck) are code.

use crate::config::SimConfig;
use crate::ecs::desc::Scene;
use crate::io::cut_scenes::{cut_block_scene, random_scene, scooped_cantilever_scene};
use crate::io::pile_scenes::pile_scene;
use crate::io::scene_file::SceneFile;
use crate::io::truck_scene::truck_scene;

/// How a built-in scene is made.
#[derive(Clone, Copy)]
pub enum Source {
    /// A scene file's text.
    File(&'static str),
    /// Code, given the seed.
    Made(fn(u64) -> Scene),
}

/// A built-in scene: its name, a line that says what happens in it, and how it is made.
#[derive(Clone, Copy)]
pub struct Builtin {
    /// The name `cleave run` takes.
    pub name: &'static str,
    /// What happens in it, in a line.
    pub description: &'static str,
    /// How it is made.
    pub source: Source,
}

/// Every built-in scene.
pub const BUILTIN_SCENES: [Builtin; 23] = [
    Builtin {
        name: "drop",
        description: "a 16×8×8 box falls on the ground and settles",
        source: Source::File(include_str!("scenes/drop.ron")),
    },
    Builtin {
        name: "cantilever",
        description: "a 24×6×6 beam pinned at one end sags under gravity",
        source: Source::File(include_str!("scenes/cantilever.ron")),
    },
    Builtin {
        name: "slice",
        description: "a blade sweeps through a 24×12×12 block on a pedestal: two halves tip off",
        source: Source::File(include_str!("scenes/slice.ron")),
    },
    Builtin {
        name: "dice",
        description: "two perpendicular slices through a 24×12×24 block: four pieces",
        source: Source::File(include_str!("scenes/dice.ron")),
    },
    Builtin {
        name: "scoop",
        description: "a sphere carves a trench along the top of a block: one piece",
        source: Source::File(include_str!("scenes/scoop.ron")),
    },
    Builtin {
        name: "random",
        description: "a seeded sequence of random blade and sphere cuts (stress test)",
        source: Source::Made(random_scene),
    },
    Builtin {
        name: "stack",
        description: "a 16×8×8 box dropped onto an 8×8×8 box resting on the ground comes to rest on top",
        source: Source::File(include_str!("scenes/stack.ron")),
    },
    Builtin {
        name: "pile",
        description: "boxes, balls and a capsule dropped into a walled bin of tilted static boxes",
        source: Source::Made(|seed| pile_scene(seeded(seed), H)),
    },
    Builtin {
        name: "press",
        description: "a moving plate squeezes a block, then a blade cuts it while squeezed",
        source: Source::File(include_str!("scenes/press.ron")),
    },
    Builtin {
        name: "tear",
        description: "a 32×6×6 bar whose ends are pulled apart by moving pins tears in two",
        source: Source::File(include_str!("scenes/tear.ron")),
    },
    Builtin {
        name: "notch",
        description: "the tear bar with a notch at 30 % of its length tears at the notch",
        source: Source::File(include_str!("scenes/notch.ron")),
    },
    Builtin {
        name: "cuts",
        description: "a 32×16×16 block, gravity off, cut 50 times by random blades and sphere scoops",
        source: Source::Made(|seed| cut_block_scene(seed, 50)),
    },
    Builtin {
        name: "bevel",
        description: "a blade slants through a 16³ block on a pedestal at 30° to its sides: the pieces tip off",
        source: Source::File(include_str!("scenes/bevel.ron")),
    },
    Builtin {
        name: "scooped",
        description: "the cantilever with 20 sphere scoops near the middle of its top and sides",
        source: Source::Made(scooped),
    },
    Builtin {
        name: "soft_beam",
        description: "a 32×3×3 bar of very soft clusters and stiff edges, pinned at one end: it bends like a chain and barely stretches",
        source: Source::File(include_str!("scenes/soft_beam.ron")),
    },
    Builtin {
        name: "jittered",
        description: "a soft block and ball spawned with every particle jittered by 0.3 h, relaxed into their rest shapes, then dropped",
        source: Source::File(include_str!("scenes/jittered.ron")),
    },
    Builtin {
        name: "bend",
        description: "a 32×4×4 bar posed by its two end regions: bent, twisted, stretched (`cleave deform bend`)",
        source: Source::File(include_str!("scenes/bend.ron")),
    },
    Builtin {
        name: "grab",
        description: "a 10×10×10 block dragged through the air by one point handle while it simulates",
        source: Source::File(include_str!("scenes/grab.ron")),
    },
    Builtin {
        name: "rod",
        description: "a 24×1×1 rod of oriented particles clamped at its root holds out under gravity",
        source: Source::File(include_str!("scenes/rod.ron")),
    },
    Builtin {
        name: "dent",
        description: "a plastic block of oriented particles pressed by a sphere keeps a dent",
        source: Source::File(include_str!("scenes/dent.ron")),
    },
    Builtin {
        name: "wheel",
        description: "a rigid disc spinning at 2 rev/s on an axle it shares particles with (a joint), gravity off",
        source: Source::File(include_str!("scenes/wheel.ron")),
    },
    Builtin {
        name: "sheet",
        description: "a 24×24×1 sheet of oriented particles standing on edge, clamped along its left edge, holds out under gravity",
        source: Source::File(include_str!("scenes/sheet.ron")),
    },
    Builtin {
        name: "truck",
        description: "a rigid chassis on rigid hubs with soft tyres (oriented particles, axles as joints) rolls down a slope and over a bump",
        source: Source::Made(|seed| truck_scene(seeded(seed))),
    },
];

const H: f32 = 0.1;

/// The default settings with `seed`.
fn seeded(seed: u64) -> SimConfig {
    SimConfig {
        seed,
        ..SimConfig::default()
    }
}

/// The `scooped` scene: the built-in `cantilever` with 20 scoops.
fn scooped(seed: u64) -> Scene {
    let cantilever = builtin("cantilever", seed).expect("`cantilever` is built in");
    scooped_cantilever_scene(cantilever, seed, 20)
}

/// The built-in scene `name`, with the given seed, or `None`.
pub fn builtin(name: &str, seed: u64) -> Option<Scene> {
    let scene = BUILTIN_SCENES.iter().find(|b| b.name == name)?;
    Some(match scene.source {
        Source::File(text) => {
            // (every built-in file is read by a test: this cannot fail)
            let file = SceneFile::parse(text).expect("a built-in scene file parses");
            let mut scene = file
                .to_scene(std::path::Path::new("."))
                .expect("a built-in scene file describes a scene");
            scene.config.seed = seed;
            scene
        }
        Source::Made(make) => make(seed),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_scene_is_made_with_the_seed_asked_for() {
        for b in BUILTIN_SCENES {
            let scene = builtin(b.name, 7).unwrap_or_else(|| panic!("{}", b.name));
            assert_eq!(scene.config.seed, 7, "{}", b.name);
            assert!(!scene.bodies.is_empty(), "{}", b.name);
        }
        assert!(builtin("no_such_scene", 0).is_none());
    }
}
