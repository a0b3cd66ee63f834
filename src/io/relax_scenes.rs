//! The built-in `jittered` scene: two soft bodies spawned out of their rest shapes and
//! relaxed back into them before the first frame (`settings.relax`, see
//! [`crate::sim::relax`]).

use crate::body::shape::Shape;
use crate::config::{Material, RelaxOptions, SimConfig};
use crate::ecs::desc::{BodyDesc, Scene};
use glam::{UVec3, Vec3};

/// Lattice spacing of the scene (metres).
const H: f32 = 0.05;

/// A gel 24×12×12 block and a gel ball of radius 8 h, every particle jittered by up to
/// 0.3 h, relaxed with the default options, then dropped on the ground.
pub fn jittered_scene(config: SimConfig) -> Scene {
    let jittered = |shape: Shape, position: Vec3| BodyDesc {
        material: Material::gel(),
        position,
        jitter: 0.3,
        ..BodyDesc::new(shape, H)
    };
    Scene {
        config: SimConfig {
            relax: Some(RelaxOptions::default()),
            ..config
        },
        bodies: vec![
            jittered(
                Shape::cuboid(UVec3::new(24, 12, 12)),
                Vec3::new(-0.4, 0.6, 0.0),
            ),
            jittered(Shape::Sphere { radius: 8.0 * H }, Vec3::new(0.7, 0.8, 0.0)),
        ],
        tools: vec![],
        colliders: vec![],
        frames: 120,
    }
}
