//! The bodies' surfaces in a picture ([`crate::ecs::surface_mesh::SurfaceMesh`]): shaded,
//! depth-tested triangles coloured by piece, and their shadow straight down on the
//! ground.

use super::camera::Camera;
use super::canvas::Canvas;
use glam::Vec3;
use tiny_skia::{FillRule, Paint, PathBuilder, Transform};

/// One body's surface to draw, as plain data.
#[derive(Clone, Debug, Default)]
pub struct SurfaceToDraw {
    /// Vertex positions (world).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals (world).
    pub normals: Vec<Vec3>,
    /// Triangles (vertex indices).
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, its piece (numbered over all bodies, like [`super::Sphere::piece`]).
    pub pieces: Vec<u32>,
    /// Per triangle, its colour.
    pub colours: Vec<[u8; 3]>,
}

/// Cosine of the largest angle between a triangle and a vertex normal it is shaded with:
/// at a sharper crease (a box's edge, a cut's rim) the triangle is shaded flat, so
/// that the crease stays sharp instead of smearing across the thin triangles beside it.
const CREASE: f32 = 0.9;

/// Draws `surface` into `canvas` seen by `camera`.
pub fn draw_surface(canvas: &mut Canvas, camera: &Camera, surface: &SurfaceToDraw) {
    let projected: Vec<Option<(f32, f32, f32)>> = surface
        .positions
        .iter()
        .map(|p| camera.project(*p))
        .collect();
    let normals: Vec<Vec3> = surface.normals.iter().map(|n| camera.to_view(*n)).collect();
    for (t, rgb) in surface.triangles.iter().zip(&surface.colours) {
        let [a, b, c] = t.map(|v| projected[v as usize]);
        if let (Some(a), Some(b), Some(c)) = (a, b, c) {
            let [pa, pb, pc] = t.map(|v| surface.positions[v as usize]);
            let flat = camera.to_view((pb - pa).cross(pc - pa).normalize_or_zero());
            let shaded = t.map(|v| {
                let n = normals[v as usize];
                // (a triangle of no area has no normal of its own)
                if flat == Vec3::ZERO || n.dot(flat) >= CREASE {
                    n
                } else {
                    flat
                }
            });
            canvas.triangle([a, b, c], shaded, *rgb);
        }
    }
}

/// Darkens the ground at `height` under every triangle of `surfaces` (lit from straight
/// above), as one shape so overlapping triangles do not darken it twice.
pub fn draw_shadows(canvas: &mut Canvas, camera: &Camera, height: f32, surfaces: &[SurfaceToDraw]) {
    let mut path = PathBuilder::new();
    for s in surfaces {
        let below: Vec<Option<(f32, f32)>> = s
            .positions
            .iter()
            .map(|p| {
                (p.y >= height)
                    .then(|| camera.project(Vec3::new(p.x, height, p.z)))
                    .flatten()
                    .map(|q| (q.0, q.1))
            })
            .collect();
        for t in &s.triangles {
            if let [Some(a), Some(b), Some(c)] = t.map(|v| below[v as usize]) {
                path.move_to(a.0, a.1);
                path.line_to(b.0, b.1);
                path.line_to(c.0, c.1);
                path.close();
            }
        }
    }
    let Some(path) = path.finish() else {
        return;
    };
    let mut paint = Paint::default();
    paint.set_color_rgba8(60, 64, 72, 70);
    paint.anti_alias = true;
    canvas.pixmap.fill_path(
        &path,
        &paint,
        FillRule::Winding,
        Transform::identity(),
        None,
    );
}
