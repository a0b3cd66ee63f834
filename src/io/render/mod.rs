//! Software rendering of a simulation for people to look at: the bodies' surfaces as
//! shaded, depth-tested triangles coloured by piece with a shadow on the ground, or their
//! particles as shaded spheres coloured by piece or by cluster ([`Draw`]); the ground as
//! a grid, the colliders, and the tools, seen by a fixed three-quarter camera that
//! frames the scene. [`snapshot`] reads a World into plain data; [`render`] draws plain
//! data.
//!
//! Known simplification: the ground, boxes and tools are flat layers (ground and boxes
//! behind all bodies, tools in front); only the bodies, and collider balls and capsules
//! (drawn as balls), are depth-tested.

pub mod camera;
pub mod canvas;
pub mod encode;
pub mod surfaces;

use crate::config::GroundPlane;
use crate::cut::tool::{Pose, ToolShape};
use crate::ecs::components::{
    BodyLattice, Collider, ColliderPose, ParticleClusters, Tool, ToolPose,
};
use crate::ecs::resources::SimSettings;
use crate::ecs::surface_mesh::SurfaceMesh;
use crate::geometry::collider::ColliderShape;
use bevy_ecs::prelude::*;
use camera::Camera;
use canvas::Canvas;
use glam::Vec3;
use surfaces::{SurfaceToDraw, draw_shadows, draw_surface};

/// How particles are coloured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ColorMode {
    /// One colour per connected piece.
    #[default]
    Pieces,
    /// One colour per cluster; a particle in several clusters blends their colours.
    Clusters,
    /// By each particle's orientation: the diagonal `(1, 1, 1)/√3` turned by it, as RGB
    /// (`0.5 + 0.5·v`); at rest a light grey, so a twisted rod shows its twist in hue.
    Orientation,
}

/// The colour [`ColorMode::Orientation`] gives a particle turned by `q`.
pub fn orientation_colour(q: glam::Quat) -> [u8; 3] {
    let v = q * Vec3::ONE.normalize();
    let c = (Vec3::splat(0.5) + 0.5 * v).clamp(Vec3::ZERO, Vec3::ONE) * 255.0;
    [c.x as u8, c.y as u8, c.z as u8]
}

/// What stands for a body in a picture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Draw {
    /// Its surface (its particles while it has none yet, or was spawned without one).
    #[default]
    Surfaces,
    /// Its particles, as balls.
    Particles,
    /// Both.
    Both,
}

/// One particle to draw.
#[derive(Clone, Copy, Debug)]
pub struct Sphere {
    /// World position.
    pub position: Vec3,
    /// World radius (half the lattice spacing).
    pub radius: f32,
    /// Colour.
    pub rgb: [u8; 3],
    /// Piece number (over all bodies).
    pub piece: u32,
}

/// Everything drawn in one frame, as plain data.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    /// The live particles drawn as balls.
    pub spheres: Vec<Sphere>,
    /// The surfaces drawn.
    pub surfaces: Vec<SurfaceToDraw>,
    /// Tool shapes and poses.
    pub tools: Vec<(ToolShape, Pose)>,
    /// Ground plane.
    pub ground: Option<GroundPlane>,
    /// Colliders (the config's static boxes among them) and their poses.
    pub colliders: Vec<(ColliderShape, Pose)>,
}

/// Distinct colours for pieces.
const PIECE_COLOURS: [[u8; 3]; 10] = [
    [76, 114, 176],
    [221, 132, 82],
    [85, 168, 104],
    [196, 78, 82],
    [129, 114, 179],
    [204, 185, 116],
    [218, 139, 195],
    [100, 181, 205],
    [147, 120, 96],
    [140, 140, 140],
];

/// A bright colour derived from a cluster's identity.
fn cluster_colour(bits: u64) -> Vec3 {
    let mut x = bits.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x ^= x >> 29;
    let hue = (x % 3600) as f32 / 3600.0;
    let (s, v) = (0.7, 0.95);
    let h6 = hue * 6.0;
    let f = h6.fract();
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let rgb = match h6 as u32 {
        0 => Vec3::new(v, t, p),
        1 => Vec3::new(q, v, p),
        2 => Vec3::new(p, v, t),
        3 => Vec3::new(p, q, v),
        4 => Vec3::new(t, p, v),
        _ => Vec3::new(v, p, q),
    };
    rgb * 255.0
}

/// Reads the bodies (as `draw` says, particles coloured as `mode` says), tools and
/// colliders of `world`.
pub fn snapshot(world: &mut World, mode: ColorMode, draw: Draw) -> Snapshot {
    type BodyRow<'a> = (
        Entity,
        &'a BodyLattice,
        Option<&'a ParticleClusters>,
        Option<&'a SurfaceMesh>,
    );
    let mut query = world.query::<BodyRow>();
    let world: &World = world;
    let mut bodies: Vec<BodyRow> = query.iter(world).collect();
    bodies.sort_by_key(|(e, ..)| *e);
    let mut spheres = Vec::new();
    let mut surfaces = Vec::new();
    let mut piece_offset = 0u32;
    for (_, body, clusters, surface) in &bodies {
        let lattice = &body.lattice;
        let (labels, pieces) = (&lattice.pieces().label, lattice.pieces().count);
        let surface = surface.filter(|s| s.topology_version > 0 && draw != Draw::Particles);
        if let Some(s) = surface {
            surfaces.push(SurfaceToDraw {
                positions: s.positions.clone(),
                normals: s.normals.clone(),
                triangles: s.triangles().to_vec(),
                pieces: s
                    .triangle_pieces()
                    .iter()
                    .map(|p| piece_offset + p)
                    .collect(),
                colours: s
                    .triangle_pieces()
                    .iter()
                    .map(|p| PIECE_COLOURS[(piece_offset + p) as usize % PIECE_COLOURS.len()])
                    .collect(),
            });
            if draw == Draw::Surfaces {
                piece_offset += pieces as u32;
                continue;
            }
        }
        let radius = lattice.spacing() * 0.5;
        for i in lattice.live_particles() {
            let Some(position) = world
                .get::<crate::ecs::components::Position>(body.particles[i as usize])
                .map(|p| p.0)
            else {
                continue;
            };
            let piece = piece_offset + labels[i as usize];
            let rgb = match (mode, clusters) {
                (ColorMode::Clusters, Some(c)) => {
                    let sum: Vec3 = c.clusters_of(i).map(|e| cluster_colour(e.to_bits())).sum();
                    let mean = sum / c.index.clusters_of(i).len().max(1) as f32;
                    [mean.x as u8, mean.y as u8, mean.z as u8]
                }
                (ColorMode::Orientation, _) => world
                    .get::<crate::ecs::components::Orientation>(body.particles[i as usize])
                    .map_or([128; 3], |q| orientation_colour(q.0)),
                _ => PIECE_COLOURS[piece as usize % PIECE_COLOURS.len()],
            };
            spheres.push(Sphere {
                position,
                radius,
                rgb,
                piece,
            });
        }
        piece_offset += pieces as u32;
    }
    let mut tool_query = world.try_query::<(Entity, &Tool, &ToolPose)>();
    let mut tools: Vec<(Entity, ToolShape, Pose)> = tool_query
        .iter_mut()
        .flat_map(|q| q.iter(world))
        .map(|(e, t, p)| (e, t.shape, p.current))
        .collect();
    tools.sort_by_key(|(e, _, _)| *e);
    let settings = &world.resource::<SimSettings>().0;
    let mut colliders: Vec<(ColliderShape, Pose)> =
        settings.boxes.iter().map(|b| b.shape_and_pose()).collect();
    let mut collider_query = world.try_query::<(Entity, &Collider, &ColliderPose)>();
    let mut moving: Vec<(Entity, ColliderShape, Pose)> = collider_query
        .iter_mut()
        .flat_map(|q| q.iter(world))
        .map(|(e, c, p)| (e, c.shape.clone(), p.current))
        .collect();
    moving.sort_by_key(|(e, _, _)| *e);
    colliders.extend(moving.into_iter().map(|(_, s, p)| (s, p)));
    Snapshot {
        spheres,
        surfaces,
        tools: tools.into_iter().map(|(_, s, p)| (s, p)).collect(),
        ground: settings.ground,
        colliders,
    }
}

impl Snapshot {
    /// Where the bodies are: the particles drawn and the surfaces' vertices.
    fn body_points(&self) -> impl Iterator<Item = Vec3> + '_ {
        let surfaces = self
            .surfaces
            .iter()
            .flat_map(|s| s.positions.iter().copied());
        self.spheres.iter().map(|s| s.position).chain(surfaces)
    }
}

/// A camera that frames the bodies and colliders of `snapshot`.
pub fn frame_camera(snapshot: &Snapshot, width: u32, height: u32) -> Camera {
    let mut points: Vec<Vec3> = snapshot.body_points().collect();
    for (shape, pose) in &snapshot.colliders {
        let half = shape.local_half_extents();
        points.extend([pose.position - half, pose.position + half]);
    }
    if points.is_empty() {
        return Camera::framing(Vec3::ZERO, 1.0, width, height);
    }
    let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
        (lo.min(*p), hi.max(*p))
    });
    let centre = (lo + hi) * 0.5;
    // room for pieces to fall apart and drop to the ground
    let radius = (hi - lo).length() * 0.5 * 1.35 + 0.2;
    Camera::framing(centre, radius, width, height)
}

/// Draws `snapshot` seen by `camera` into a new `width × height` canvas.
pub fn render(snapshot: &Snapshot, camera: &Camera, width: u32, height: u32) -> Option<Canvas> {
    let mut canvas = Canvas::new(width, height, [236, 239, 243])?;
    if let Some(ground) = snapshot.ground {
        draw_ground(&mut canvas, camera, ground.height, snapshot);
        draw_shadows(&mut canvas, camera, ground.height, &snapshot.surfaces);
    }
    for (shape, pose) in &snapshot.colliders {
        draw_collider(&mut canvas, camera, shape, pose);
    }
    for s in &snapshot.spheres {
        if let Some((x, y, z)) = camera.project(s.position) {
            let r = s.radius * camera.scale_at(z);
            canvas.sphere(x, y, z, r, s.radius, s.rgb);
        }
    }
    for s in &snapshot.surfaces {
        draw_surface(&mut canvas, camera, s);
    }
    for (shape, pose) in &snapshot.tools {
        let below_ground = snapshot
            .ground
            .is_some_and(|g| pose.position.y + shape.bounding_radius() < g.height);
        if !below_ground {
            draw_tool(&mut canvas, camera, shape, pose);
        }
    }
    Some(canvas)
}

fn draw_ground(canvas: &mut Canvas, camera: &Camera, height: f32, snapshot: &Snapshot) {
    let count = snapshot.body_points().count();
    let centre = if count == 0 {
        Vec3::ZERO
    } else {
        snapshot.body_points().sum::<Vec3>() / count as f32
    };
    let (lo, hi) = snapshot
        .body_points()
        .fold((centre, centre), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let extent = ((hi - lo).max_element() * 1.5).max(1.0);
    let step = nice_step(extent / 5.0);
    let half = (extent / step).ceil() * step;
    let (cx, cz) = (
        (centre.x / step).round() * step,
        (centre.z / step).round() * step,
    );
    let corner = |x: f32, z: f32| camera.project(Vec3::new(x, height, z)).map(|p| (p.0, p.1));
    let quad: Option<Vec<(f32, f32)>> =
        [(-half, -half), (half, -half), (half, half), (-half, half)]
            .iter()
            .map(|(dx, dz)| corner(cx + dx, cz + dz))
            .collect();
    if let Some(quad) = quad {
        canvas.fill_polygon(&quad, [214, 218, 223], 255);
    }
    let lines = (2.0 * half / step).round() as i32;
    for k in 0..=lines {
        let t = -half + k as f32 * step;
        for (a, b) in [
            ((cx + t, cz - half), (cx + t, cz + half)),
            ((cx - half, cz + t), (cx + half, cz + t)),
        ] {
            if let (Some(p), Some(q)) = (corner(a.0, a.1), corner(b.0, b.1)) {
                canvas.stroke_line(&[p, q], [178, 184, 192], 255, 1.0);
            }
        }
    }
}

/// 1, 2 or 5 times a power of ten, at least `x`.
fn nice_step(x: f32) -> f32 {
    let p = 10f32.powf(x.max(1e-6).log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|s| *s >= x)
        .unwrap_or(10.0 * p)
}

/// A box as its visible faces (behind every particle); a ball as a depth-tested
/// sphere; a capsule as a row of such spheres along its axis.
fn draw_collider(canvas: &mut Canvas, camera: &Camera, shape: &ColliderShape, pose: &Pose) {
    const STONE: [u8; 3] = [150, 150, 158];
    let world = |p: Vec3| pose.position + pose.rotation * p;
    let ball = |canvas: &mut Canvas, centre: Vec3, radius: f32| {
        if let Some((x, y, z)) = camera.project(centre) {
            canvas.sphere(x, y, z, radius * camera.scale_at(z), radius, STONE);
        }
    };
    match shape {
        &ColliderShape::Box { half_extents: h } => {
            for axis in 0..3 {
                for sign in [-1.0f32, 1.0] {
                    let mut normal = Vec3::ZERO;
                    normal[axis] = sign;
                    let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
                    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                        .map(|(a, b): (f32, f32)| world(normal * h + u * (a * h) + v * (b * h)));
                    let normal = pose.rotation * normal;
                    let centre = corners.iter().sum::<Vec3>() * 0.25;
                    if normal.dot(camera.eye() - centre) <= 0.0 {
                        continue;
                    }
                    let light = Vec3::new(-0.3, 0.9, 0.4).normalize();
                    let shade = 0.55 + 0.45 * normal.dot(light).max(0.0);
                    let grey = (STONE[0] as f32 * shade) as u8;
                    let quad: Option<Vec<(f32, f32)>> = corners
                        .iter()
                        .map(|c| camera.project(*c).map(|p| (p.0, p.1)))
                        .collect();
                    if let Some(quad) = quad {
                        canvas.fill_polygon(&quad, [grey, grey, grey.saturating_add(8)], 255);
                    }
                }
            }
        }
        &ColliderShape::Sphere { radius } => ball(canvas, pose.position, radius),
        &ColliderShape::Capsule {
            radius,
            half_length,
        } => {
            let steps = ((2.0 * half_length / (0.5 * radius)).ceil() as u32).clamp(1, 64);
            for k in 0..=steps {
                let x = -half_length + 2.0 * half_length * k as f32 / steps as f32;
                ball(canvas, world(Vec3::new(x, 0.0, 0.0)), radius);
            }
        }
        ColliderShape::Mesh(sdf) => {
            // the triangles that face the camera, shaded, behind every particle
            let mesh = sdf.mesh();
            let light = Vec3::new(-0.3, 0.9, 0.4).normalize();
            for t in &mesh.triangles {
                let [a, b, c] = t.map(|v| world(mesh.vertices[v as usize]));
                let normal = (b - a).cross(c - a).normalize_or_zero();
                // either orientation: shade the side that faces the camera
                let normal = if normal.dot(camera.eye() - a) < 0.0 {
                    -normal
                } else {
                    normal
                };
                let shade = 0.55 + 0.45 * normal.dot(light).max(0.0);
                let grey = (STONE[0] as f32 * shade) as u8;
                let tri: Option<Vec<(f32, f32)>> = [a, b, c]
                    .iter()
                    .map(|c| camera.project(*c).map(|p| (p.0, p.1)))
                    .collect();
                if let Some(tri) = tri {
                    canvas.fill_polygon(&tri, [grey, grey, grey.saturating_add(8)], 255);
                }
            }
        }
    }
}

fn draw_tool(canvas: &mut Canvas, camera: &Camera, shape: &ToolShape, pose: &Pose) {
    const STEEL: [u8; 3] = [92, 104, 122];
    let world = |p: Vec3| pose.position + pose.rotation * p;
    match *shape {
        ToolShape::Blade {
            half_width,
            half_height,
        } => {
            let corners: Option<Vec<(f32, f32)>> =
                [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|(u, v)| {
                        camera
                            .project(world(Vec3::new(u * half_width, v * half_height, 0.0)))
                            .map(|p| (p.0, p.1))
                    })
                    .collect();
            if let Some(mut c) = corners {
                canvas.fill_polygon(&c, STEEL, 90);
                c.push(c[0]);
                canvas.stroke_line(&c, STEEL, 230, 1.5);
            }
        }
        ToolShape::Sphere { radius } => {
            if let Some((x, y, z)) = camera.project(pose.position) {
                let r = radius * camera.scale_at(z);
                canvas.fill_circle(x, y, r, STEEL, 80);
            }
        }
        ToolShape::Capsule {
            radius,
            half_length,
        } => {
            let ends = (
                camera.project(world(Vec3::new(-half_length, 0.0, 0.0))),
                camera.project(world(Vec3::new(half_length, 0.0, 0.0))),
            );
            if let (Some(a), Some(b)) = ends {
                let r = radius * camera.scale_at((a.2 + b.2) * 0.5);
                canvas.stroke_line(&[(a.0, a.1), (b.0, b.1)], STEEL, 80, 2.0 * r);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(0.3), 0.5);
        assert_eq!(nice_step(1.0), 1.0);
        assert_eq!(nice_step(1.1), 2.0);
        assert_eq!(nice_step(7.0), 10.0);
    }

    #[test]
    fn a_sphere_in_front_of_the_camera_is_drawn_in_its_colour() {
        let snapshot = Snapshot {
            spheres: vec![Sphere {
                position: Vec3::new(0.0, 0.5, 0.0),
                radius: 0.3,
                rgb: [200, 40, 40],
                piece: 0,
            }],
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.5,
            }),
            ..Snapshot::default()
        };
        let camera = frame_camera(&snapshot, 64, 48);
        let canvas = render(&snapshot, &camera, 64, 48).unwrap();
        let centre = &canvas.pixmap.data()[(24 * 64 + 32) * 4..(24 * 64 + 32) * 4 + 3];
        assert!(centre[0] > 2 * centre[1] && centre[0] > 100, "{centre:?}");
    }

    #[test]
    fn a_twist_about_any_axis_changes_the_orientation_colour() {
        let rest = orientation_colour(glam::Quat::IDENTITY);
        assert_eq!(rest, [201, 201, 201]);
        for axis in [Vec3::X, Vec3::Y, Vec3::Z] {
            let turned = orientation_colour(glam::Quat::from_axis_angle(axis, 1.0));
            let apart: i32 = (0..3)
                .map(|k| (turned[k] as i32 - rest[k] as i32).abs())
                .sum();
            assert!(apart > 60, "{axis}: {turned:?}");
        }
    }
}
