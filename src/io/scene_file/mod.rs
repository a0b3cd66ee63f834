//! Scenes as RON files: the file schema, checked while it is read so that every error
//! names the file, line, column and field (and, for a value out of range, the allowed
//! range); conversion to and from [`Scene`], so every built-in scene is also a file.

use crate::body::shape::{Shape, ShapePart};
use crate::config::SimConfig;
use crate::cut::tool::{Path as ToolPath, Pose};
use crate::deform::keys::HandlePath;
use crate::ecs::components::Hold;
use crate::ecs::desc::Scene;
use crate::ecs::desc::{
    AttachmentDesc, BodyDesc, ColliderDesc, HandleDesc, SurfaceOptions, ToolDesc,
};
use crate::geometry::collider::ColliderShape;
use crate::geometry::mesh::TriangleMesh;
use glam::Vec3;
use std::path::Path;
use std::sync::Arc;

mod check;
mod positions;
mod schema;

pub use positions::entry_position;
pub use schema::*;

impl ColliderShapeFile {
    /// The file form of `shape`; `None` for a mesh given in memory.
    fn from_shape(shape: &ColliderShape) -> Option<Self> {
        Some(match *shape {
            ColliderShape::Box { half_extents } => Self::Box { half_extents },
            ColliderShape::Sphere { radius } => Self::Sphere { radius },
            ColliderShape::Capsule {
                radius,
                half_length,
            } => Self::Capsule {
                radius,
                half_length,
            },
            ColliderShape::Mesh(_) => return None,
        })
    }

    /// The shape, if it is not a mesh (whose file is read when the scene is built).
    fn primitive(&self) -> Option<ColliderShape> {
        Some(match *self {
            Self::Box { half_extents } => ColliderShape::Box { half_extents },
            Self::Sphere { radius } => ColliderShape::Sphere { radius },
            Self::Capsule {
                radius,
                half_length,
            } => ColliderShape::Capsule {
                radius,
                half_length,
            },
            Self::Mesh { .. } => return None,
        })
    }

    /// The shape, checked; a mesh is read relative to `base_dir`. `field` names it in
    /// errors.
    fn to_shape(&self, base_dir: &Path, field: &str) -> Result<ColliderShape, String> {
        let shape = match (self.primitive(), self) {
            (Some(shape), _) => shape,
            (None, Self::Mesh { path, resolution }) => {
                let file = base_dir.join(path);
                let mesh =
                    TriangleMesh::load_obj(&file).map_err(|e| format!("{field}.path: {e}"))?;
                let sdf = crate::geometry::mesh_sdf::MeshSdf::new(&mesh, *resolution)
                    .map_err(|e| format!("{field}: {e}"))?;
                ColliderShape::Mesh(Arc::new(sdf))
            }
            (None, _) => unreachable!("every collider shape but a mesh is a primitive"),
        };
        shape.validate(field).map_err(|e| e.to_string())?;
        Ok(shape)
    }
}

impl SettingsFile {
    fn from_config(c: &SimConfig) -> Self {
        Self {
            dt: c.dt,
            substeps: c.substeps,
            iterations: c.iterations,
            gravity: c.gravity,
            damping: c.damping,
            ground: c.ground,
            boxes: c.boxes.clone(),
            solver: c.solver,
            contacts: c.contacts,
            culling: c.culling,
            relax: c.relax.clone(),
            check_invariants_every_frame: c.check_invariants_every_frame,
            memory_budget_gb: c.memory_budget_gb,
        }
    }

    fn to_config(&self, seed: u64) -> SimConfig {
        SimConfig {
            dt: self.dt,
            substeps: self.substeps,
            iterations: self.iterations,
            gravity: self.gravity,
            damping: self.damping,
            ground: self.ground,
            boxes: self.boxes.clone(),
            solver: self.solver,
            contacts: self.contacts,
            culling: self.culling,
            relax: self.relax.clone(),
            seed,
            check_invariants_every_frame: self.check_invariants_every_frame,
            memory_budget_gb: self.memory_budget_gb,
        }
    }
}

impl SceneFile {
    /// The file form of `scene`; `None` if a body's shape has no file form (a signed
    /// distance function, or a mesh given in memory).
    pub fn from_scene(scene: &Scene) -> Option<Self> {
        let bodies = scene
            .bodies
            .iter()
            .map(|b| {
                let shape = shape_file(&b.shape)?;
                if b.render_mesh.is_some() {
                    return None;
                }
                Some(BodyFile {
                    shape,
                    spacing: b.spacing,
                    position: b.position,
                    rotation: b.rotation,
                    velocity: b.velocity,
                    angular_velocity: b.angular_velocity,
                    material: b.material.clone(),
                    pins: b.pins.clone(),
                    attachments: attachment_files(&b.attachments, Hold::Each),
                    centroids: attachment_files(&b.attachments, Hold::Centroid),
                    handles: b.handles.iter().map(handle_file).collect(),
                    groups: b
                        .groups
                        .iter()
                        .map(|g| RegionCompliance::new(g.region, g.compliance))
                        .collect(),
                    stiffness_regions: b
                        .stiffness_regions
                        .iter()
                        .map(|g| RegionCompliance::new(g.region, g.compliance))
                        .collect(),
                    render_mesh: None,
                    surface: SurfaceFile {
                        smooth: b.surface.smooth,
                    },
                    jitter: b.jitter,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let tools = scene
            .tools
            .iter()
            .map(|t| ToolFile {
                shape: t.shape,
                cut_width: t.cut_width,
                cut_mode: t.cut_mode,
                path: t.path.keys.clone(),
                pose: Some(t.pose),
            })
            .collect();
        let colliders = scene
            .colliders
            .iter()
            .map(|c| {
                Some(ColliderFile {
                    shape: ColliderShapeFile::from_shape(&c.shape)?,
                    friction: c.friction,
                    path: c.path.keys.clone(),
                    pose: Some(c.pose),
                })
            })
            .collect::<Option<Vec<_>>>()?;
        Some(Self {
            seed: scene.config.seed,
            frames: scene.frames,
            settings: SettingsFile::from_config(&scene.config),
            bodies,
            tools,
            colliders,
        })
    }

    /// The scene; mesh paths are resolved against `base_dir`.
    pub fn to_scene(&self, base_dir: &Path) -> Result<Scene, String> {
        let mut bodies = Vec::new();
        for (i, b) in self.bodies.iter().enumerate() {
            let shape = shape_of(&b.shape, base_dir, &format!("bodies[{i}].shape"))?;
            let material = b.material.clone();
            material
                .validate()
                .map_err(|e| format!("bodies[{i}]: {e}"))?;
            let render_mesh = match &b.render_mesh {
                Some(path) => Some(Arc::new(
                    TriangleMesh::load_obj(&base_dir.join(path))
                        .map_err(|e| format!("bodies[{i}].render_mesh: {e}"))?,
                )),
                None => None,
            };
            bodies.push(BodyDesc {
                shape,
                spacing: b.spacing,
                position: b.position,
                rotation: b.rotation,
                velocity: b.velocity,
                angular_velocity: b.angular_velocity,
                material,
                pins: b.pins.clone(),
                attachments: [(&b.attachments, Hold::Each), (&b.centroids, Hold::Centroid)]
                    .into_iter()
                    .flat_map(|(list, hold)| {
                        list.iter().map(move |a| AttachmentDesc {
                            region: a.region,
                            path: path_and_pose(&a.path, None).0,
                            compliance: a.compliance,
                            hold,
                        })
                    })
                    .collect(),
                handles: b.handles.iter().map(handle_desc).collect(),
                groups: b.groups.iter().map(|&g| g.into()).collect(),
                stiffness_regions: b.stiffness_regions.iter().map(|&g| g.into()).collect(),
                render_mesh,
                surface: SurfaceOptions {
                    smooth: b.surface.smooth,
                },
                jitter: b.jitter,
            });
        }
        let tools = self
            .tools
            .iter()
            .map(|t| {
                let (path, pose) = path_and_pose(&t.path, t.pose);
                ToolDesc {
                    shape: t.shape,
                    cut_width: t.cut_width,
                    cut_mode: t.cut_mode,
                    path,
                    pose,
                }
            })
            .collect();
        let mut colliders = Vec::with_capacity(self.colliders.len());
        for (i, c) in self.colliders.iter().enumerate() {
            let (path, pose) = path_and_pose(&c.path, c.pose);
            colliders.push(ColliderDesc {
                shape: c
                    .shape
                    .to_shape(base_dir, &format!("colliders[{i}].shape"))?,
                friction: c.friction,
                path,
                pose,
            });
        }
        let config = self.settings.to_config(self.seed);
        config.validate().map_err(|e| e.to_string())?;
        Ok(Scene {
            config,
            bodies,
            tools,
            colliders,
            frames: self.frames,
        })
    }

    /// Pretty RON text with a short header.
    pub fn to_ron(&self) -> String {
        let pretty = ron::ser::PrettyConfig::new()
            .depth_limit(4)
            .struct_names(false);
        let body = ron::ser::to_string_pretty(self, pretty).unwrap_or_default();
        format!(
            "// cleave scene (RON). Units: metres, seconds. Rotations are quaternions (x, y, z, w).\n\
             // Run it with `cleave run FILE.ron`.\n{body}\n"
        )
    }

    /// Parses RON text; errors read `LINE:COLUMN: FIELD: MESSAGE`. An optional value
    /// may be written bare (`particle_mass: 0.5`) or as `Some(0.5)`.
    pub fn parse(text: &str) -> Result<Self, String> {
        // (editors on some systems start UTF-8 files with a byte-order mark)
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let options = ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .with_recursion_limit(RECURSION_LIMIT);
        let mut de = ron::Deserializer::from_str_with_options(text, &options)
            .map_err(|e| spanned(&e, ""))?;
        let file: Self = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            let span = de.span_error(e.into_inner());
            spanned(&span, &path)
        })?;
        de.end().map_err(|e| spanned(&de.span_error(e), ""))?;
        Ok(file)
    }
}

/// The deepest a scene file may nest brackets (RON's default, stated so that the error
/// can say it): deep enough for any scene, shallow enough for the reader's stack.
const RECURSION_LIMIT: usize = 128;

/// A handle as a scene file gives it.
fn handle_file(h: &HandleDesc) -> HandleFile {
    HandleFile {
        region: h.region,
        point: h.point,
        path: h.path.keys.clone(),
        compliance: h.compliance,
    }
}

/// A handle from its scene file form.
fn handle_desc(h: &HandleFile) -> HandleDesc {
    HandleDesc {
        region: h.region,
        point: h.point,
        path: HandlePath {
            keys: h.path.clone(),
        },
        compliance: h.compliance,
    }
}

/// The attachments of `list` that hold by `hold`, as a scene file lists them.
fn attachment_files(list: &[AttachmentDesc], hold: Hold) -> Vec<AttachmentFile> {
    list.iter()
        .filter(|a| a.hold == hold)
        .map(|a| AttachmentFile {
            region: a.region,
            path: a.path.keys.clone(),
            compliance: a.compliance,
        })
        .collect()
}

/// A keyframed path and the pose before it starts (default: the first key's, else the
/// origin).
fn path_and_pose(keys: &[(f32, Pose)], pose: Option<Pose>) -> (ToolPath, Pose) {
    let pose = pose
        .or_else(|| keys.first().map(|k| k.1))
        .unwrap_or(Pose::at(Vec3::ZERO));
    (
        ToolPath {
            keys: keys.to_vec(),
        },
        pose,
    )
}

fn spanned(e: &ron::error::SpannedError, path: &str) -> String {
    // (a value where a field name belongs ends the path in `?`)
    let path = path.strip_suffix(".?").unwrap_or(path);
    let (path, message) = within(path, e);
    let field = if path.is_empty() || path == "." || path == "?" {
        String::new()
    } else {
        format!(" {path}:")
    };
    format!("{}:{}:{field} {message}", e.position.line, e.position.col)
}

/// The field path and the message of `e`. A checked reader's message that names a part
/// of the value it read (`.radius: …`, `[2].time: …`: the type's own check, see
/// `check::refused`) continues the path.
fn within(path: &str, e: &ron::error::SpannedError) -> (String, String) {
    let message = message(e);
    match message.split_once(": ") {
        Some((part, rest)) if part.starts_with(['.', '[']) && !part.contains(' ') => {
            (format!("{path}{part}"), rest.to_string())
        }
        _ => (path.to_string(), message),
    }
}

/// The message of `e`, in this file format's words where RON's own would mislead.
fn message(e: &ron::error::SpannedError) -> String {
    match &e.code {
        // RON reads `Sphere(0.6)` as a field named `0.6`
        ron::Error::SuggestRawIdentifier(found) => format!(
            "expected a field name, found `{found}`: fields are named, as in \
             `Sphere(radius: 0.6)`"
        ),
        // (RON's own text points a user at serde_stacker, a library's remedy)
        ron::Error::ExceededRecursionLimit => format!(
            "nested too deep: a scene file nests brackets at most {RECURSION_LIMIT} deep, \
             and each shape Union inside another takes three: flatten the unions into one"
        ),
        code => code.to_string(),
    }
}

/// Reads a scene file; errors name the file.
pub fn load_scene_file(path: &Path) -> Result<Scene, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let file = SceneFile::parse(&text).map_err(|e| format!("{}:{e}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    file.to_scene(base)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// The file form of `shape`; `None` for a signed distance function or a mesh given in
/// memory.
fn shape_file(shape: &Shape) -> Option<ShapeFile> {
    Some(match shape {
        Shape::Cells { cells } => ShapeFile::Cells { cells: *cells },
        Shape::Box { half_extents } => ShapeFile::Box {
            half_extents: *half_extents,
        },
        Shape::Sphere { radius } => ShapeFile::Sphere { radius: *radius },
        Shape::Capsule {
            radius,
            half_length,
        } => ShapeFile::Capsule {
            radius: *radius,
            half_length: *half_length,
        },
        Shape::Cylinder {
            radius,
            half_length,
        } => ShapeFile::Cylinder {
            radius: *radius,
            half_length: *half_length,
        },
        Shape::Union(parts) => ShapeFile::Union {
            parts: parts
                .iter()
                .map(|p| {
                    Some(ShapePartFile {
                        shape: shape_file(&p.shape)?,
                        at: p.at,
                    })
                })
                .collect::<Option<_>>()?,
        },
        Shape::Sdf(_) | Shape::Mesh(_) => return None,
    })
}

/// The shape a file gives at `field`; mesh paths are resolved against `base_dir`.
fn shape_of(file: &ShapeFile, base_dir: &Path, field: &str) -> Result<Shape, String> {
    Ok(match file {
        ShapeFile::Cells { cells } => Shape::Cells { cells: *cells },
        ShapeFile::Box { half_extents } => Shape::Box {
            half_extents: *half_extents,
        },
        ShapeFile::Sphere { radius } => Shape::Sphere { radius: *radius },
        ShapeFile::Capsule {
            radius,
            half_length,
        } => Shape::Capsule {
            radius: *radius,
            half_length: *half_length,
        },
        ShapeFile::Cylinder {
            radius,
            half_length,
        } => Shape::Cylinder {
            radius: *radius,
            half_length: *half_length,
        },
        ShapeFile::Mesh { path } => {
            let file = base_dir.join(path);
            let mesh = TriangleMesh::load_obj(&file).map_err(|e| format!("{field}.path: {e}"))?;
            Shape::Mesh(Arc::new(mesh))
        }
        ShapeFile::Union { parts } => Shape::Union(
            parts
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    Ok(ShapePart {
                        shape: shape_of(&p.shape, base_dir, &format!("{field}.parts[{k}].shape"))?,
                        at: p.at,
                    })
                })
                .collect::<Result<_, String>>()?,
        ),
    })
}
