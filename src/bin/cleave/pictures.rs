//! What `cleave run` writes for people to look at: PNG frames, an animated GIF, and
//! optionally PLY point clouds and OBJ and glTF surfaces, with the time spent on them.

use bevy_ecs::prelude::*;
use cleave::io::export::{write_obj, write_ply};
use cleave::io::gltf::write_glb;
use cleave::io::render::camera::Camera;
use cleave::io::render::encode::{GifWriter, write_png};
use cleave::io::render::{ColorMode, Draw, frame_camera, render, snapshot};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Which pictures to write.
#[derive(Clone, Debug)]
pub struct PictureOptions {
    /// A PNG every this many frames (0: none).
    pub png_every: u32,
    /// A GIF frame every this many frames (0: no GIF).
    pub gif_every: u32,
    /// A PLY point cloud every this many frames (0: none).
    pub ply_every: u32,
    /// An OBJ of the surfaces with every PNG.
    pub obj: bool,
    /// A binary glTF of the surfaces with every PNG.
    pub gltf: bool,
    /// Particle colours.
    pub color: ColorMode,
    /// What stands for a body.
    pub draw: Draw,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Seconds per simulated frame (sets the GIF speed).
    pub dt: f32,
}

/// Writes pictures as the run goes.
pub struct Pictures {
    options: PictureOptions,
    dir: PathBuf,
    camera: Option<Camera>,
    gif: Option<GifWriter>,
    /// Milliseconds spent reading, drawing and encoding.
    pub ms: f64,
    /// Files written.
    pub files: usize,
}

impl Pictures {
    /// Prepares the output directory.
    pub fn new(dir: &Path, options: PictureOptions) -> Result<Self, String> {
        if options.width == 0
            || options.height == 0
            || options.width > 8192
            || options.height > 8192
        {
            return Err(format!(
                "--width/--height {}×{} out of range (allowed 1 to 8192)",
                options.width, options.height
            ));
        }
        // the meshes are written with the pictures: without pictures, nothing would be
        if (options.obj || options.gltf) && options.png_every == 0 {
            return Err(
                "--export obj/gltf writes the surfaces with every PNG, and --png-every 0 writes none: give --png-every N"
                    .into(),
            );
        }
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
        let wanted = [
            (options.ply_every > 0, "ply"),
            (options.obj, "obj"),
            (options.gltf, "gltf"),
        ];
        for (wanted, sub) in wanted {
            if wanted {
                let path = dir.join(sub);
                std::fs::create_dir_all(&path)
                    .map_err(|e| format!("cannot create `{}`: {e}", path.display()))?;
            }
        }
        Ok(Self {
            options,
            dir: dir.to_path_buf(),
            camera: None,
            gif: None,
            ms: 0.0,
            files: 0,
        })
    }

    /// Writes whatever is due at `frame` (frame 0 is the initial state).
    pub fn frame(&mut self, world: &mut World, frame: u32) -> Result<(), String> {
        let due = |every: u32| every > 0 && frame.is_multiple_of(every);
        let o = &self.options;
        let (png, gif, ply) = (due(o.png_every), due(o.gif_every), due(o.ply_every));
        if !(png || gif || ply) {
            return Ok(());
        }
        let start = Instant::now();
        let snap = snapshot(world, o.color, o.draw);
        let (width, height) = (o.width, o.height);
        if ply {
            write_ply(
                &self.dir.join(format!("ply/frame_{frame:05}.ply")),
                &snapshot(world, o.color, Draw::Particles).spheres,
            )?;
            self.files += 1;
        }
        if png && (o.obj || o.gltf) {
            let surfaces = snapshot(world, o.color, Draw::Surfaces).surfaces;
            if o.obj {
                write_obj(
                    &self.dir.join(format!("obj/frame_{frame:05}.obj")),
                    &surfaces,
                )?;
                self.files += 1;
            }
            if o.gltf {
                write_glb(
                    &self.dir.join(format!("gltf/frame_{frame:05}.glb")),
                    &surfaces,
                )?;
                self.files += 1;
            }
        }
        if png || gif {
            let camera = *self
                .camera
                .get_or_insert_with(|| frame_camera(&snap, width, height));
            let canvas = render(&snap, &camera, width, height).ok_or("cannot allocate image")?;
            let rgba = canvas.pixmap.data();
            if png {
                write_png(
                    &self.dir.join(format!("frame_{frame:05}.png")),
                    width,
                    height,
                    rgba,
                )?;
                self.files += 1;
            }
            if gif {
                if self.gif.is_none() {
                    let delay = (self.options.gif_every as f32 * self.options.dt * 100.0).round();
                    self.gif = Some(GifWriter::create(
                        &self.dir.join("run.gif"),
                        width,
                        height,
                        delay.clamp(2.0, 500.0) as u16,
                    )?);
                    self.files += 1;
                }
                if let Some(g) = &mut self.gif {
                    g.add_frame(rgba)?;
                }
            }
        }
        self.ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Writes one picture, `NAME.png`, of the state now (with the camera every frame
    /// uses): a state before the frames, such as a body before relaxation.
    pub fn still(&mut self, world: &mut World, name: &str) -> Result<(), String> {
        if self.options.png_every == 0 {
            return Ok(());
        }
        let start = Instant::now();
        let o = &self.options;
        let snap = snapshot(world, o.color, o.draw);
        let (width, height) = (o.width, o.height);
        let camera = *self
            .camera
            .get_or_insert_with(|| frame_camera(&snap, width, height));
        let canvas = render(&snap, &camera, width, height).ok_or("cannot allocate image")?;
        write_png(
            &self.dir.join(format!("{name}.png")),
            width,
            height,
            canvas.pixmap.data(),
        )?;
        self.files += 1;
        self.ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }
}
