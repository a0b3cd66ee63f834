//! Export for other tools: the particles as ASCII PLY point clouds (position, colour,
//! piece id), the surfaces as Wavefront OBJ meshes (positions, normals, a group per
//! piece), readable by Blender, ParaView and MeshLab.

use crate::io::render::Sphere;
use crate::io::render::surfaces::SurfaceToDraw;
use std::collections::BTreeMap;
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

/// Writes the surfaces as one Wavefront OBJ: every vertex with its normal, and a group
/// `piece_N` per piece holding its triangles.
pub fn write_obj(path: &Path, surfaces: &[SurfaceToDraw]) -> Result<(), String> {
    let fail = |e: std::io::Error| format!("cannot write `{}`: {e}", path.display());
    let file = std::fs::File::create(path).map_err(fail)?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "# cleave surfaces").map_err(fail)?;
    let mut groups: BTreeMap<u32, Vec<[usize; 3]>> = BTreeMap::new();
    let mut offset = 1;
    for s in surfaces {
        for (p, n) in s.positions.iter().zip(&s.normals) {
            writeln!(w, "v {} {} {}\nvn {} {} {}", p.x, p.y, p.z, n.x, n.y, n.z).map_err(fail)?;
        }
        for (t, piece) in s.triangles.iter().zip(&s.pieces) {
            groups
                .entry(*piece)
                .or_default()
                .push(t.map(|v| v as usize + offset));
        }
        offset += s.positions.len();
    }
    for (piece, triangles) in groups {
        writeln!(w, "g piece_{piece}").map_err(fail)?;
        for [a, b, c] in triangles {
            writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}").map_err(fail)?;
        }
    }
    w.flush().map_err(fail)
}
