//! In and out: built-in scenes and scene files, state dumps, saved simulations,
//! pictures, point clouds and surface meshes (OBJ, glTF).

pub mod cut_scenes;
pub mod dump;
#[cfg(feature = "render")]
pub mod export;
#[cfg(feature = "render")]
pub mod gltf;
pub mod pile_scenes;
#[cfg(feature = "render")]
pub mod render;
pub mod save;
pub mod save_file;
pub mod scene;
pub mod scene_file;
pub mod stream;
pub mod truck_scene;
