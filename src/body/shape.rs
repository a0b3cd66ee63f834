//! Shapes voxelised into a lattice: primitives, signed-distance functions and closed
//! triangle meshes, within a memory budget checked before anything is allocated.

use super::lattice::{Lattice, MAX_LATTICE_CELLS};
use crate::error::{
    CELLS, CleaveError, POSITION, Result, SIZE, SIZE_OR_ZERO, check_finite_vec, check_positive,
    check_vec_within,
};
use crate::geometry::mesh::TriangleMesh;
use glam::{IVec3, UVec3, Vec3};
use std::sync::Arc;

/// Estimated memory per particle of a running body (entity, components, solver layout,
/// cluster index; measured with `cleave bench` as peak resident memory per particle).
pub const BYTES_PER_PARTICLE: u64 = 600;

/// Memory one body may take by default, in GB ([`crate::config::SimConfig::memory_budget_gb`]);
/// with [`BYTES_PER_PARTICLE`] it bounds the particles of a body before anything is
/// allocated.
pub const DEFAULT_MEMORY_BUDGET_GB: f32 = 2.0;

/// Refuses a shape whose lattice could hold more particles than `budget_gb` allows.
fn check_budget(field: &str, particles: u64, budget_gb: f32) -> Result<()> {
    let max = (budget_gb as f64 * 1e9 / BYTES_PER_PARTICLE as f64) as u64;
    if particles > max {
        return Err(CleaveError::OverBudget {
            field: field.into(),
            particles,
            gigabytes: (particles as f64) * BYTES_PER_PARTICLE as f64 / 1e9,
            bytes_per_particle: BYTES_PER_PARTICLE,
            budget_gigabytes: budget_gb,
            max,
        });
    }
    Ok(())
}

/// A signed-distance function (negative inside) with the box that bounds its inside.
#[derive(Clone)]
pub struct SdfShape {
    /// The function; non-finite values count as outside.
    pub sdf: Arc<dyn Fn(Vec3) -> f32 + Send + Sync>,
    /// Lower corner of a box containing the inside.
    pub min: Vec3,
    /// Upper corner of a box containing the inside.
    pub max: Vec3,
}

impl std::fmt::Debug for SdfShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SdfShape")
            .field("min", &self.min)
            .field("max", &self.max)
            .finish()
    }
}

/// One part of a [`Shape::Union`]: a shape placed with its local origin at `at`.
#[derive(Clone, Debug)]
pub struct ShapePart {
    /// The part's shape.
    pub shape: Shape,
    /// Where its local origin sits in the union's frame.
    pub at: Vec3,
}

/// A shape to voxelise, in its local frame (centred on the origin for primitives).
#[derive(Clone, Debug)]
pub enum Shape {
    /// Axis-aligned box with the given half extents.
    Box {
        /// Half size along each axis.
        half_extents: Vec3,
    },
    /// Exactly `cells.x × cells.y × cells.z` lattice points, centred on the origin for
    /// even counts and offset by h/2 along axes with an odd count.
    Cells {
        /// Particles along each axis.
        cells: UVec3,
    },
    /// Sphere of the given radius.
    Sphere {
        /// Radius.
        radius: f32,
    },
    /// Capsule along the local X axis.
    Capsule {
        /// Radius of the round ends and the shaft.
        radius: f32,
        /// Half length of the shaft (without the caps).
        half_length: f32,
    },
    /// A solid cylinder along the local Z axis (a disc, a wheel, an axle).
    Cylinder {
        /// Radius.
        radius: f32,
        /// Half its length along Z.
        half_length: f32,
    },
    /// Any signed-distance function.
    Sdf(SdfShape),
    /// The union of shapes, each placed at its offset (a truck: a box and its wheels).
    /// A part may not be [`Shape::Cells`], whose size is in lattice units.
    Union(Vec<ShapePart>),
    /// A closed triangle mesh (inside by winding number).
    Mesh(Arc<TriangleMesh>),
}

impl Shape {
    /// A box holding exactly `cells.x × cells.y × cells.z` particles, at the spacing
    /// its body is voxelised with ([`Shape::Cells`]).
    pub fn cuboid(cells: UVec3) -> Self {
        Shape::Cells { cells }
    }

    /// How errors name the shape: `shape`, or for a mesh `shape (mesh FILE)`.
    fn field(&self) -> String {
        match self {
            Shape::Mesh(mesh) => format!("shape (mesh {})", mesh.source.display()),
            _ => "shape".into(),
        }
    }

    /// Lattice coordinate range `[lo, hi)` of a [`Shape::Cells`] block.
    fn cells_range(cells: UVec3) -> (IVec3, IVec3) {
        let lo = -(cells / 2).as_ivec3();
        (lo, lo + cells.as_ivec3())
    }

    fn bounds(&self) -> Result<(Vec3, Vec3)> {
        Ok(match self {
            Shape::Box { half_extents } => {
                SIZE.check_each("shape.half_extents", *half_extents)?;
                (-*half_extents, *half_extents)
            }
            Shape::Cells { .. } => (Vec3::ZERO, Vec3::ZERO),
            Shape::Sphere { radius } => {
                SIZE.check("shape.radius", *radius)?;
                (Vec3::splat(-radius), Vec3::splat(*radius))
            }
            Shape::Capsule {
                radius,
                half_length,
            } => {
                SIZE.check("shape.radius", *radius)?;
                SIZE_OR_ZERO.check("shape.half_length", *half_length)?;
                let e = Vec3::new(radius + half_length, *radius, *radius);
                (-e, e)
            }
            Shape::Cylinder {
                radius,
                half_length,
            } => {
                SIZE.check("shape.radius", *radius)?;
                SIZE.check("shape.half_length", *half_length)?;
                let e = Vec3::new(*radius, *radius, *half_length);
                (-e, e)
            }
            Shape::Sdf(s) => {
                check_finite_vec("shape.min", s.min)?;
                check_finite_vec("shape.max", s.max)?;
                (s.min, s.max)
            }
            Shape::Union(parts) => {
                let (mut min, mut max) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
                for (i, part) in parts.iter().enumerate() {
                    check_vec_within(&format!("shape.parts[{i}].at"), part.at, &POSITION)?;
                    if matches!(part.shape, Shape::Cells { .. }) {
                        return Err(crate::error::out_of_range(
                            &format!("shape.parts[{i}].shape"),
                            "Cells",
                            "any shape but Cells (sized in lattice units; use Box)",
                        ));
                    }
                    let (lo, hi) = part.shape.bounds()?;
                    (min, max) = (min.min(lo + part.at), max.max(hi + part.at));
                }
                if parts.is_empty() {
                    return Err(crate::error::out_of_range(
                        "shape.parts",
                        0,
                        "at least one part",
                    ));
                }
                (min, max)
            }
            Shape::Mesh(m) => m.bounds(),
        })
    }

    /// Signed distance (negative inside); non-finite values mean outside.
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        match self {
            Shape::Box { half_extents } => {
                let q = p.abs() - *half_extents;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            // In lattice units (h = 1): cells are placed on the lattice directly.
            Shape::Cells { cells } => {
                let (lo, hi) = Self::cells_range(*cells);
                let centre = (lo + hi).as_vec3() * 0.5;
                let q = (p - centre).abs() - cells.as_vec3() * 0.5;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            Shape::Sphere { radius } => p.length() - radius,
            Shape::Capsule {
                radius,
                half_length,
            } => {
                let x = p.x.clamp(-half_length, *half_length);
                (p - Vec3::new(x, 0.0, 0.0)).length() - radius
            }
            Shape::Cylinder {
                radius,
                half_length,
            } => {
                let q = glam::Vec2::new(p.truncate().length() - radius, p.z.abs() - half_length);
                q.max(glam::Vec2::ZERO).length() + q.max_element().min(0.0)
            }
            Shape::Sdf(s) => (s.sdf)(p),
            Shape::Union(parts) => parts
                .iter()
                .map(|part| part.shape.signed_distance(p - part.at))
                .fold(f32::INFINITY, f32::min),
            // (voxelising a mesh tests whole rows instead, see `voxelise`)
            Shape::Mesh(m) => {
                if m.contains(p) {
                    -1.0
                } else {
                    1.0
                }
            }
        }
    }

    /// Voxelises the shape at spacing `h`: lattice point `k` sits at `(k + ½)·h` in the
    /// shape's frame and is kept when it lies inside (signed distance ≤ 10⁻⁴·h). A shape
    /// whose bounding box holds more cells than [`DEFAULT_MEMORY_BUDGET_GB`] allows is
    /// refused before anything is allocated.
    pub fn voxelise(&self, h: f32) -> Result<Lattice> {
        self.voxelise_within(h, DEFAULT_MEMORY_BUDGET_GB)
    }

    /// [`Shape::voxelise`] within a memory budget of `budget_gb` gigabytes.
    pub fn voxelise_within(&self, h: f32, budget_gb: f32) -> Result<Lattice> {
        check_positive("spacing", h)?;
        if let Shape::Cells { cells } = self {
            CELLS.check_each("shape.cells", cells.as_vec3())?;
            let total = cells.x as u64 * cells.y as u64 * cells.z as u64;
            check_budget("shape.cells", total, budget_gb)?;
            if total > MAX_LATTICE_CELLS {
                return Err(CleaveError::TooLarge {
                    field: "shape.cells".into(),
                    cells: total,
                    max: MAX_LATTICE_CELLS,
                });
            }
            let (lo, hi) = Self::cells_range(*cells);
            let mut coords = Vec::with_capacity(total as usize);
            for z in lo.z..hi.z {
                for y in lo.y..hi.y {
                    for x in lo.x..hi.x {
                        coords.push(IVec3::new(x, y, z));
                    }
                }
            }
            return Lattice::from_coords(h, coords);
        }
        let (lo, hi) = self.bounds()?;
        let kmin = (lo / h - Vec3::splat(0.5)).floor();
        let kmax = (hi / h - Vec3::splat(0.5)).ceil();
        let extent = (kmax - kmin + Vec3::ONE).max(Vec3::ZERO);
        let cells = extent.x as f64 * extent.y as f64 * extent.z as f64;
        let field = self.field();
        if cells.is_finite() {
            check_budget(&field, cells as u64, budget_gb)?;
        }
        if !cells.is_finite() || cells > MAX_LATTICE_CELLS as f64 {
            return Err(CleaveError::TooLarge {
                field,
                cells: if cells.is_finite() {
                    cells as u64
                } else {
                    u64::MAX
                },
                max: MAX_LATTICE_CELLS,
            });
        }
        let (kmin, kmax) = (kmin.as_ivec3(), kmax.as_ivec3());
        let tolerance = 1e-4 * h;
        let coords = match self {
            // a whole grid at once: a winding number per point costs cells × triangles
            Shape::Mesh(mesh) => {
                let dims = (kmax - kmin + IVec3::ONE).as_uvec3();
                let origin = (kmin.as_vec3() + Vec3::splat(0.5)) * h;
                let (nx, ny) = (dims.x as usize, dims.y as usize);
                let inside = mesh.inside_grid(origin, h, dims);
                let cell = |i: usize| {
                    kmin + IVec3::new((i % nx) as i32, (i / nx % ny) as i32, (i / nx / ny) as i32)
                };
                (0..inside.len()).filter(|&i| inside[i]).map(cell).collect()
            }
            _ => {
                let mut coords = Vec::new();
                for z in kmin.z..=kmax.z {
                    for y in kmin.y..=kmax.y {
                        for x in kmin.x..=kmax.x {
                            let k = IVec3::new(x, y, z);
                            let p = (k.as_vec3() + Vec3::splat(0.5)) * h;
                            let d = self.signed_distance(p);
                            if d.is_finite() && d <= tolerance {
                                coords.push(k);
                            }
                        }
                    }
                }
                coords
            }
        };
        if coords.is_empty() {
            return Err(CleaveError::EmptyShape {
                field: self.field(),
                spacing: h,
            });
        }
        Lattice::from_coords(h, coords)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_and_capsule_are_symmetric() {
        let s = Shape::Sphere { radius: 3.0 }.voxelise(1.0).unwrap();
        let c: Vec3 = s.live_particles().map(|i| s.rest_position(i)).sum();
        assert!(c.length() < 1e-3);
        let cap = Shape::Capsule {
            radius: 1.0,
            half_length: 2.0,
        }
        .voxelise(0.5)
        .unwrap();
        assert!(cap.live_count() > 0);
    }

    #[test]
    fn bad_shapes_are_errors() {
        assert!(Shape::Sphere { radius: -1.0 }.voxelise(1.0).is_err());
        assert!(Shape::Sphere { radius: 1.0 }.voxelise(0.0).is_err());
        assert!(Shape::Sphere { radius: 1.0 }.voxelise(f32::NAN).is_err());
        let e = Shape::Box {
            half_extents: Vec3::ZERO,
        }
        .voxelise(1.0);
        assert!(matches!(e, Err(CleaveError::OutOfRange { .. })), "{e:?}");
        // a box between the lattice's points holds none of them
        let e = Shape::Box {
            half_extents: Vec3::splat(0.1),
        }
        .voxelise(1.0);
        assert!(matches!(e, Err(CleaveError::EmptyShape { .. })), "{e:?}");
        let e = Shape::cuboid(UVec3::new(2, 0, 2)).voxelise(1.0);
        assert!(matches!(e, Err(CleaveError::OutOfRange { .. })), "{e:?}");
        assert!(Shape::Sphere { radius: 1e9 }.voxelise(1e-3).is_err());
    }

    #[test]
    fn cuboid_has_exact_counts_and_edges() {
        let l = Shape::cuboid(UVec3::new(4, 3, 2)).voxelise(0.1).unwrap();
        assert_eq!(l.live_count(), 24);
        // edges of a 4×3×2 grid: 3·3·2 + 4·2·2 + 4·3·1
        assert_eq!(l.edges().len(), 18 + 16 + 12);
        let centre: Vec3 = l.live_particles().map(|i| l.rest_position(i)).sum::<Vec3>() / 24.0;
        // even axes (x, z) are centred; the odd axis (y) is offset by h/2
        assert!(
            (centre - Vec3::new(0.0, 0.05, 0.0)).length() < 1e-5,
            "centre {centre}"
        );
    }
}
