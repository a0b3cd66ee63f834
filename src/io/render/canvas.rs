//! The frame buffer: a tiny-skia pixmap for flat shapes (ground, grid, boxes, tools) plus
//! a depth buffer for the particles, stamped as shaded spheres, and the surfaces,
//! rasterised as shaded triangles.

use glam::Vec3;
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Stroke, Transform};

/// An RGBA image with a depth buffer.
pub struct Canvas {
    /// The image (opaque, so premultiplied = straight RGBA).
    pub pixmap: Pixmap,
    depth: Vec<f32>,
}

/// Direction towards the light in view space (right, up, towards the viewer).
const LIGHT: Vec3 = Vec3::new(-0.45, 0.65, 0.62);

impl Canvas {
    /// A canvas filled with `background`. `None` for a zero or oversized image.
    pub fn new(width: u32, height: u32, background: [u8; 3]) -> Option<Self> {
        let mut pixmap = Pixmap::new(width, height)?;
        pixmap.fill(Color::from_rgba8(
            background[0],
            background[1],
            background[2],
            255,
        ));
        Some(Self {
            pixmap,
            depth: vec![f32::INFINITY; (width * height) as usize],
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.pixmap.width()
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.pixmap.height()
    }

    /// Fills a polygon (pixel coordinates) with a colour and opacity.
    pub fn fill_polygon(&mut self, points: &[(f32, f32)], rgb: [u8; 3], alpha: u8) {
        let Some(path) = polygon(points) else {
            return;
        };
        let paint = solid(rgb, alpha);
        self.pixmap.fill_path(
            &path,
            &paint,
            FillRule::Winding,
            Transform::identity(),
            None,
        );
    }

    /// Strokes a polyline (pixel coordinates).
    pub fn stroke_line(&mut self, points: &[(f32, f32)], rgb: [u8; 3], alpha: u8, width: f32) {
        let mut pb = PathBuilder::new();
        let Some((first, rest)) = points.split_first() else {
            return;
        };
        pb.move_to(first.0, first.1);
        for p in rest {
            pb.line_to(p.0, p.1);
        }
        let Some(path) = pb.finish() else {
            return;
        };
        let stroke = Stroke {
            width,
            line_cap: tiny_skia::LineCap::Round,
            ..Stroke::default()
        };
        self.pixmap.stroke_path(
            &path,
            &solid(rgb, alpha),
            &stroke,
            Transform::identity(),
            None,
        );
    }

    /// Fills a circle.
    pub fn fill_circle(&mut self, x: f32, y: f32, r: f32, rgb: [u8; 3], alpha: u8) {
        if let Some(path) = PathBuilder::from_circle(x, y, r.max(0.5)) {
            self.pixmap.fill_path(
                &path,
                &solid(rgb, alpha),
                FillRule::Winding,
                Transform::identity(),
                None,
            );
        }
    }

    /// Stamps a shaded sphere of pixel radius `r` centred at `(x, y)` whose centre lies
    /// at view depth `z` and whose world radius is `world_r`; depth-tested per pixel.
    pub fn sphere(&mut self, x: f32, y: f32, z: f32, r: f32, world_r: f32, rgb: [u8; 3]) {
        let (w, h) = (self.width() as i32, self.height() as i32);
        let r = r.max(0.75);
        let (x0, x1) = ((x - r).floor() as i32, (x + r).ceil() as i32);
        let (y0, y1) = ((y - r).floor() as i32, (y + r).ceil() as i32);
        if x1 < 0 || y1 < 0 || x0 >= w || y0 >= h {
            return;
        }
        let inv_r2 = 1.0 / (r * r);
        let base = Vec3::new(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32);
        let light = LIGHT.normalize();
        let half = (light + Vec3::Z).normalize();
        let pixels = self.pixmap.data_mut();
        for py in y0.max(0)..y1.min(h) {
            let dy = py as f32 + 0.5 - y;
            for px in x0.max(0)..x1.min(w) {
                let dx = px as f32 + 0.5 - x;
                let q = (dx * dx + dy * dy) * inv_r2;
                if q > 1.0 {
                    continue;
                }
                let nz = (1.0 - q).sqrt();
                let depth = z - nz * world_r;
                let i = (py * w + px) as usize;
                if depth >= self.depth[i] {
                    continue;
                }
                self.depth[i] = depth;
                let n = Vec3::new(dx / r, -dy / r, nz);
                let diffuse = n.dot(light).max(0.0);
                let specular = n.dot(half).max(0.0).powi(24) * 110.0;
                let c = base * (0.32 + 0.68 * diffuse) + Vec3::splat(specular);
                let c = c.min(Vec3::splat(255.0));
                pixels[i * 4..i * 4 + 4].copy_from_slice(&[c.x as u8, c.y as u8, c.z as u8, 255]);
            }
        }
    }
}

impl Canvas {
    /// Fills a triangle with corners at pixel coordinates and view depths `corners` and
    /// view-space unit normals `normals`, shaded per pixel like the spheres (the normal
    /// interpolated, turned toward the viewer if it faces away); depth-tested.
    pub fn triangle(&mut self, corners: [(f32, f32, f32); 3], normals: [Vec3; 3], rgb: [u8; 3]) {
        let (w, h) = (self.width() as i32, self.height() as i32);
        let [(ax, ay, az), (bx, by, bz), (cx, cy, cz)] = corners;
        let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if area.abs() <= 1e-12 || area.is_nan() {
            return;
        }
        let x0 = (ax.min(bx).min(cx).floor() as i32).max(0);
        let x1 = (ax.max(bx).max(cx).ceil() as i32).min(w);
        let y0 = (ay.min(by).min(cy).floor() as i32).max(0);
        let y1 = (ay.max(by).max(cy).ceil() as i32).min(h);
        let base = Vec3::new(rgb[0] as f32, rgb[1] as f32, rgb[2] as f32);
        let light = LIGHT.normalize();
        let half = (light + Vec3::Z).normalize();
        let pixels = self.pixmap.data_mut();
        for py in y0..y1 {
            let y = py as f32 + 0.5;
            for px in x0..x1 {
                let x = px as f32 + 0.5;
                // barycentric weights of a, b and c
                let wa = ((bx - x) * (cy - y) - (by - y) * (cx - x)) / area;
                let wb = ((cx - x) * (ay - y) - (cy - y) * (ax - x)) / area;
                let wc = 1.0 - wa - wb;
                if wa < 0.0 || wb < 0.0 || wc < 0.0 {
                    continue;
                }
                // (perspective-correct enough for triangles a fraction of a cell wide)
                let depth = wa * az + wb * bz + wc * cz;
                let i = (py * w + px) as usize;
                if depth >= self.depth[i] {
                    continue;
                }
                self.depth[i] = depth;
                let mut n =
                    (normals[0] * wa + normals[1] * wb + normals[2] * wc).normalize_or_zero();
                if n.z < 0.0 {
                    n = -n;
                }
                let diffuse = n.dot(light).max(0.0);
                let specular = n.dot(half).max(0.0).powi(24) * 60.0;
                let c = (base * (0.32 + 0.68 * diffuse) + Vec3::splat(specular))
                    .min(Vec3::splat(255.0));
                pixels[i * 4..i * 4 + 4].copy_from_slice(&[c.x as u8, c.y as u8, c.z as u8, 255]);
            }
        }
    }
}

fn solid(rgb: [u8; 3], alpha: u8) -> Paint<'static> {
    let mut paint = Paint::default();
    paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], alpha);
    paint.anti_alias = true;
    paint
}

fn polygon(points: &[(f32, f32)]) -> Option<tiny_skia::Path> {
    let (first, rest) = points.split_first()?;
    let mut pb = PathBuilder::new();
    pb.move_to(first.0, first.1);
    for p in rest {
        pb.line_to(p.0, p.1);
    }
    pb.close();
    pb.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearer_spheres_win_the_depth_test() {
        let mut c = Canvas::new(32, 32, [0, 0, 0]).unwrap();
        c.sphere(16.0, 16.0, 5.0, 8.0, 0.1, [200, 0, 0]);
        c.sphere(16.0, 16.0, 9.0, 8.0, 0.1, [0, 0, 200]); // behind: hidden
        let centre = &c.pixmap.data()[(16 * 32 + 16) * 4..(16 * 32 + 16) * 4 + 3];
        assert!(centre[0] > centre[2] + 50, "{centre:?}");
        c.sphere(16.0, 16.0, 2.0, 8.0, 0.1, [0, 0, 200]); // in front: visible
        let centre = &c.pixmap.data()[(16 * 32 + 16) * 4..(16 * 32 + 16) * 4 + 3];
        assert!(centre[2] > centre[0] + 50, "{centre:?}");
        // corners untouched
        assert_eq!(&c.pixmap.data()[0..4], &[0, 0, 0, 255]);
    }
}
