//! Point-cloud export: one ASCII PLY file per frame with position, colour and piece id,
//! readable by Blender, ParaView and MeshLab.

use crate::io::render::Sphere;
use std::io::Write;
use std::path::Path;

/// Writes the particles as an ASCII PLY point cloud.
pub fn write_ply(path: &Path, spheres: &[Sphere]) -> Result<(), String> {
    let fail = |e: std::io::Error| format!("cannot write `{}`: {e}", path.display());
    let file = std::fs::File::create(path).map_err(fail)?;
    let mut w = std::io::BufWriter::new(file);
    write!(
        w,
        "ply\nformat ascii 1.0\ncomment cleave particles\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\n\
         property int piece\nend_header\n",
        spheres.len()
    )
    .map_err(fail)?;
    for s in spheres {
        let p = s.position;
        writeln!(
            w,
            "{} {} {} {} {} {} {}",
            p.x, p.y, p.z, s.rgb[0], s.rgb[1], s.rgb[2], s.piece
        )
        .map_err(fail)?;
    }
    w.flush().map_err(fail)
}
