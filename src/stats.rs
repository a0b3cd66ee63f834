//! Measurements of a world: counts, shape error against the best rigid fit of the rest
//! shape, lowest particle, piece centroids.

use crate::components::*;
use crate::graph::body_pieces;
use crate::rotation::extract_rotation;
use bevy_ecs::prelude::*;
use glam::{Mat3, Quat, Vec3};
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
}

/// RMS distance between `current` and the best rigid transform of `rest`.
pub fn rigid_fit_error(rest: &[Vec3], current: &[Vec3]) -> f32 {
    if rest.is_empty() {
        return 0.0;
    }
    let n = rest.len() as f32;
    let (rc, cc) = (
        rest.iter().sum::<Vec3>() / n,
        current.iter().sum::<Vec3>() / n,
    );
    let mut a = Mat3::ZERO;
    for (r, c) in rest.iter().zip(current) {
        let (q, p) = (*r - rc, *c - cc);
        a += Mat3::from_cols(p * q.x, p * q.y, p * q.z);
    }
    let rot = extract_rotation(glam::Mat3A::from(a), Quat::IDENTITY, 200);
    let sum: f32 = rest
        .iter()
        .zip(current)
        .map(|(r, c)| (rot * (*r - rc) + cc - *c).length_squared())
        .sum();
    (sum / n).sqrt()
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
        if of.0 == body {
            clusters += 1;
            memberships += members.0.len();
        }
    }
    let (labels, pieces) = body_pieces(l);
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
    })
}
