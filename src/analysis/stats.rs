//! Measurements of a world: counts, shape error against the best rigid fit of the rest
//! shape, lowest particle, piece centroids.

use crate::body::lattice::Lattice;
use crate::ecs::components::*;
pub use crate::math::rigid_fit::{rigid_fit, rigid_fit_error};
use bevy_ecs::prelude::*;
use glam::{IVec3, Vec3};
use serde::Serialize;

/// Counts and shape measures of one body.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct BodyStats {
    /// Live particles.
    pub particles: usize,
    /// Clusters.
    pub clusters: usize,
    /// Sum of cluster sizes.
    pub memberships: usize,
    /// Mean cluster size.
    pub mean_cluster_size: f64,
    /// Memberships per live particle.
    pub memberships_per_particle: f64,
    /// Connected pieces.
    pub pieces: usize,
    /// RMS distance to the best rigid fit of the rest shape, per piece, in units of h
    /// (the largest over pieces).
    pub shape_error_h: f64,
    /// Lowest particle height.
    pub lowest_y: f64,
    /// Centroid of each piece, ordered by smallest particle index.
    pub piece_centroids: Vec<[f32; 3]>,
    /// Whether every position is finite.
    pub finite: bool,
    /// The largest speed of a live particle (m/s).
    pub max_speed: f64,
    /// The largest strain of a live lattice edge, `| |xₐ − x_b| / L − 1 |` with `L` its
    /// rest length.
    pub max_edge_strain: f64,
}

/// The largest strain `| |xₐ − x_b| / L − 1 |` over the live edges of `lattice` at
/// `positions` (by particle index), `L` each edge's rest length; 0 without edges.
pub fn max_edge_strain(lattice: &Lattice, positions: &[Vec3]) -> f64 {
    lattice
        .edges()
        .into_iter()
        .map(|(a, b)| {
            let rest = lattice.rest_position(a).distance(lattice.rest_position(b));
            let now = positions[a as usize].distance(positions[b as usize]);
            (now / rest - 1.0).abs() as f64
        })
        .fold(0.0, f64::max)
}

/// The smallest distance between two of `points` with different `labels`, when some
/// such pair is closer than `reach`; `None` otherwise. The points sorted into a uniform
/// grid of cells of side `reach` (by cell, so that each cell's points are one run), each
/// pair of neighbouring cells (diagonals too) met once: the cost is linear in the points
/// (written apart from the contact kind's broad phase, so that it can check it). Two
/// cells whose points all bear one and the same label hold no such pair and are not
/// compared: inside a piece, where most cells are, a cell costs its 14 lookups, and only
/// cells along the gaps between pieces compare their points.
pub fn min_distance_between_labels(points: &[Vec3], labels: &[u64], reach: f32) -> Option<f32> {
    let cell = |p: Vec3| (p / reach).floor().as_ivec3();
    let mut sorted: Vec<(IVec3, u32)> = (points.iter().enumerate())
        .filter(|(_, p)| p.is_finite())
        .map(|(i, p)| (cell(*p), i as u32))
        .collect();
    sorted.sort_unstable_by_key(|(c, i)| (c.z, c.y, c.x, *i));
    // each cell's run, and the one label its points share (`None` when they differ)
    let mut runs: rustc_hash::FxHashMap<IVec3, (usize, usize, Option<u64>)> = Default::default();
    let mut start = 0;
    while start < sorted.len() {
        let c = sorted[start].0;
        let end = start + sorted[start..].iter().take_while(|(d, _)| *d == c).count();
        let first = labels[sorted[start].1 as usize];
        let shared = (sorted[start..end].iter())
            .all(|(_, i)| labels[*i as usize] == first)
            .then_some(first);
        runs.insert(c, (start, end, shared));
        start = end;
    }
    let mut best: Option<f32> = None;
    for (&c, &(a0, a1, label)) in &runs {
        // (each pair of cells once: the cell itself, offset 13, and the 13 offsets
        // after it, whose opposites are the 13 before)
        for k in 13..27 {
            let o = IVec3::new(k % 3, k / 3 % 3, k / 9) - IVec3::ONE;
            let Some(&(b0, b1, other)) = runs.get(&(c + o)) else {
                continue;
            };
            if label.is_some() && label == other {
                continue;
            }
            for (i, &(_, a)) in sorted[a0..a1].iter().enumerate() {
                // (within the cell, each pair once)
                let b0 = if k == 13 { a0 + i + 1 } else { b0 };
                for &(_, b) in &sorted[b0..b1] {
                    let (a, b) = (a as usize, b as usize);
                    if labels[a] != labels[b] {
                        let d = points[a].distance(points[b]);
                        if d < reach && best.is_none_or(|m| d < m) {
                            best = Some(d);
                        }
                    }
                }
            }
        }
    }
    best
}

/// Live particle positions of every body with their body and piece: `(position, body
/// ordinal, piece label)`, bodies in entity order.
pub fn labelled_positions(world: &World) -> Vec<(Vec3, u32, u32)> {
    let Some(mut query) = world.try_query::<(Entity, &BodyLattice)>() else {
        return Vec::new();
    };
    let mut bodies: Vec<(Entity, &BodyLattice)> = query.iter(world).collect();
    bodies.sort_unstable_by_key(|(e, _)| *e);
    let mut out = Vec::new();
    for (ordinal, (_, body)) in bodies.iter().enumerate() {
        let labels = &body.lattice.pieces().label;
        for i in body.lattice.live_particles() {
            if let Some(p) = world.get::<Position>(body.particles[i as usize]) {
                out.push((p.0, ordinal as u32, labels[i as usize]));
            }
        }
    }
    out
}

/// Statistics of one body.
pub fn body_stats(world: &mut World, body: Entity) -> Option<BodyStats> {
    let lattice = world.get::<BodyLattice>(body)?.clone();
    let l = &lattice.lattice;
    let positions: Vec<Vec3> = (0..l.len() as u32)
        .map(|i| {
            if l.is_live(i) {
                world
                    .get::<Position>(lattice.particles[i as usize])
                    .map_or(Vec3::NAN, |p| p.0)
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    let mut clusters = 0;
    let mut memberships = 0;
    for (members, of) in world.query::<(&ClusterMembers, &ClusterOf)>().iter(world) {
        if of.body == body {
            clusters += 1;
            memberships += members.0.len();
        }
    }
    let (labels, pieces) = (&l.pieces().label, l.pieces().count);
    let mut groups: Vec<Vec<u32>> = vec![Vec::new(); pieces];
    for i in l.live_particles() {
        groups[labels[i as usize] as usize].push(i);
    }
    let h = l.spacing();
    let mut shape_error = 0.0f32;
    let mut centroids = Vec::new();
    for g in &groups {
        let rest: Vec<Vec3> = g.iter().map(|i| l.rest_position(*i)).collect();
        let cur: Vec<Vec3> = g.iter().map(|i| positions[*i as usize]).collect();
        shape_error = shape_error.max(rigid_fit_error(&rest, &cur) / h);
        centroids.push((cur.iter().sum::<Vec3>() / cur.len() as f32).to_array());
    }
    let live: Vec<Vec3> = l.live_particles().map(|i| positions[i as usize]).collect();
    let n = live.len();
    Some(BodyStats {
        particles: n,
        clusters,
        memberships,
        mean_cluster_size: if clusters > 0 {
            memberships as f64 / clusters as f64
        } else {
            0.0
        },
        memberships_per_particle: if n > 0 {
            memberships as f64 / n as f64
        } else {
            0.0
        },
        pieces,
        shape_error_h: shape_error as f64,
        lowest_y: live.iter().map(|p| p.y).fold(f32::INFINITY, f32::min) as f64,
        piece_centroids: centroids,
        finite: live.iter().all(|p| p.is_finite()),
        max_speed: l
            .live_particles()
            .filter_map(|i| world.get::<Velocity>(lattice.particles[i as usize]))
            .map(|v| v.0.length() as f64)
            .fold(0.0, f64::max),
        max_edge_strain: max_edge_strain(l, &positions),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closest_pair_of_different_labels_is_found() {
        let points = [
            Vec3::ZERO,
            Vec3::new(0.05, 0.0, 0.0),
            Vec3::new(0.3, 0.0, 0.0),
            Vec3::new(0.38, 0.0, 0.0),
        ];
        // 0–1 share a label; 2–3 are the closest pair of different labels
        let d = min_distance_between_labels(&points, &[0, 0, 1, 2], 0.5).unwrap();
        assert!((d - 0.08).abs() < 1e-6, "{d}");
        assert_eq!(min_distance_between_labels(&points, &[7; 4], 0.5), None);
        assert_eq!(
            min_distance_between_labels(&points, &[0, 0, 1, 1], 0.2),
            None
        );
    }

    /// Points in blobs of one label each, some blobs touching, with a few points of a
    /// blob relabelled: the grid finds what a test of every pair finds.
    #[test]
    fn the_grid_finds_what_every_pair_finds() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for case in 0..40 {
            let mut points = Vec::new();
            let mut labels = Vec::new();
            for blob in 0..rng.random_range(1..5u64) {
                let centre = Vec3::new(rng.random_range(-1.0..1.0), 0.0, 0.0);
                for _ in 0..rng.random_range(1..200) {
                    let offset = Vec3::new(
                        rng.random_range(-0.5..0.5),
                        rng.random_range(-0.5..0.5),
                        rng.random_range(-0.5..0.5),
                    );
                    points.push(centre + offset);
                    labels.push(if rng.random_bool(0.02) { 9 } else { blob });
                }
            }
            let reach = rng.random_range(0.02..0.3);
            let mut every: Option<f32> = None;
            for a in 0..points.len() {
                for b in 0..points.len() {
                    let d = points[a].distance(points[b]);
                    if labels[a] != labels[b] && d < reach && every.is_none_or(|m| d < m) {
                        every = Some(d);
                    }
                }
            }
            assert_eq!(
                min_distance_between_labels(&points, &labels, reach),
                every,
                "case {case}"
            );
        }
    }
}
