//! A fixed perspective camera looking at the scene from a three-quarter view.

use glam::Vec3;

/// A pinhole camera: `project` maps world points to pixels and view depth.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vec3,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    focal: f32,
    centre: (f32, f32),
}

/// Nearest depth drawn; anything closer is clipped.
pub const NEAR: f32 = 1e-3;

impl Camera {
    /// A camera that frames the sphere (`centre`, `radius`) from a three-quarter view
    /// (front-right, above) in a `width × height` image.
    pub fn framing(centre: Vec3, radius: f32, width: u32, height: u32) -> Self {
        let direction = Vec3::new(1.0, 0.8, 1.5).normalize();
        let fov_y = 35f32.to_radians();
        let aspect = width as f32 / height as f32;
        let half_fov = (fov_y * 0.5).min((aspect * (fov_y * 0.5).tan()).atan());
        let distance = radius.max(1e-3) / half_fov.sin() * 1.05;
        let eye = centre + direction * distance;
        let forward = (centre - eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        Self {
            eye,
            right,
            up,
            forward,
            focal: height as f32 * 0.5 / (fov_y * 0.5).tan(),
            centre: (width as f32 * 0.5, height as f32 * 0.5),
        }
    }

    /// Pixel coordinates and view depth of `p`; `None` behind the near plane.
    #[inline]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z <= NEAR {
            return None;
        }
        let s = self.focal / z;
        Some((
            self.centre.0 + d.dot(self.right) * s,
            self.centre.1 - d.dot(self.up) * s,
            z,
        ))
    }

    /// Pixels per world unit at view depth `z`.
    #[inline]
    pub fn scale_at(&self, z: f32) -> f32 {
        self.focal / z
    }

    /// Direction from the scene towards the eye.
    pub fn towards_eye(&self) -> Vec3 {
        -self.forward
    }

    /// Eye position.
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// A world direction in view space: (right, up, toward the eye).
    pub fn to_view(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.right), v.dot(self.up), -v.dot(self.forward))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framed_sphere_lands_inside_the_image() {
        let cam = Camera::framing(Vec3::new(1.0, 2.0, -3.0), 2.0, 640, 480);
        let (x, y, _) = cam.project(Vec3::new(1.0, 2.0, -3.0)).unwrap();
        assert!((x - 320.0).abs() < 1e-3 && (y - 240.0).abs() < 1e-3);
        for d in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z] {
            let (x, y, _) = cam.project(Vec3::new(1.0, 2.0, -3.0) + d * 2.0).unwrap();
            assert!(
                (0.0..640.0).contains(&x) && (0.0..480.0).contains(&y),
                "{d}"
            );
        }
        // up is up
        let (_, y_top, _) = cam.project(Vec3::new(1.0, 3.0, -3.0)).unwrap();
        assert!(y_top < 240.0);
        assert!(cam.project(cam.eye() - cam.towards_eye()).is_some());
        assert!(cam.project(cam.eye() + cam.towards_eye()).is_none());
    }
}
