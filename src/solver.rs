//! The dense shape-matching kernel (SPEC §2.2): positions in contiguous arrays, cluster
//! members as index ranges, particle → membership ranges. Built once per topology, then
//! iterated many times. Jacobi scheme in FastLSM style: each membership carries the
//! weight `mᵢ / nᵢ` (nᵢ = clusters of particle i), so every cluster's goal displacements
//! sum to zero momentum and the particle update `Δpᵢ = (1/nᵢ) Σₖ sₖ (gᵢₖ − pᵢ)`
//! conserves linear momentum. Each cluster is solved independently and each particle
//! sums its memberships in a fixed order, so results do not depend on thread count.

use crate::config::{GroundPlane, StaticBox};
use crate::rotation::extract_rotation;
use glam::{Mat3, Mat3A, Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Müller iterations per cluster per solver iteration (warm-started, so one suffices).
pub const ROTATION_ITERATIONS: u32 = 1;

/// Clusters per parallel task.
const CLUSTERS_PER_TASK: usize = 256;
/// Particles per parallel task.
const PARTICLES_PER_TASK: usize = 2048;

/// One cluster as given to [`SolverLayout::new`].
#[derive(Clone, Copy, Debug)]
pub struct ClusterSpec<'a> {
    /// Dense particle indices of the members.
    pub members: &'a [u32],
    /// Stiffness in [0, 1].
    pub stiffness: f32,
    /// Warm-start rotation.
    pub rotation: Quat,
}

/// Static colliders applied after every iteration.
#[derive(Clone, Debug, Default)]
pub struct Colliders {
    /// Ground plane.
    pub ground: Option<GroundPlane>,
    /// Static boxes.
    pub boxes: Vec<StaticBox>,
}

/// Dense arrays for the solver; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct SolverLayout {
    /// Particle positions (predicted during a substep).
    pub positions: Vec<Vec3A>,
    /// Positions at the start of the substep.
    pub previous: Vec<Vec3A>,
    /// Velocities after prediction; [`SolverLayout::update_velocities`] adds the
    /// solver's corrections.
    pub velocities: Vec<Vec3A>,
    /// Inverse masses (0 = pinned).
    pub inv_mass: Vec<f32>,
    /// Total position correction per particle during the last [`SolverLayout::solve`].
    pub corrections: Vec<Vec3A>,
    /// Warm-start rotation per cluster.
    pub rotations: Vec<Quat>,
    cluster_start: Vec<u32>,
    member_particle: Vec<u32>,
    rest_offset: Vec<Vec3A>,
    member_weight: Vec<f32>,
    stiffness: Vec<f32>,
    offset_bias: Vec<Vec3A>,
    weight_sum: Vec<f32>,
    particle_start: Vec<u32>,
    particle_slots: Vec<u32>,
    inv_count: Vec<f32>,
    deltas: Vec<Vec3A>,
    task_bounds: Vec<usize>,
}

/// Splits `data` into consecutive slices at the given (ascending) cut points.
fn split_at_bounds<'a, T>(mut data: &'a mut [T], bounds: &[usize]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(bounds.len());
    let mut done = 0;
    for &b in &bounds[1..] {
        let (head, tail) = data.split_at_mut(b - done);
        out.push(head);
        data = tail;
        done = b;
    }
    out
}

impl SolverLayout {
    /// Builds the layout for particles with the given rest positions and clusters.
    pub fn new<'a>(rest: &[Vec3], clusters: impl IntoIterator<Item = ClusterSpec<'a>>) -> Self {
        let clusters: Vec<ClusterSpec<'a>> = clusters.into_iter().collect();
        let n = rest.len();
        let mut count = vec![0u32; n];
        for c in &clusters {
            for &m in c.members {
                count[m as usize] += 1;
            }
        }
        let mut layout = SolverLayout {
            positions: rest.iter().map(|r| Vec3A::from(*r)).collect(),
            previous: rest.iter().map(|r| Vec3A::from(*r)).collect(),
            velocities: vec![Vec3A::ZERO; n],
            corrections: vec![Vec3A::ZERO; n],
            inv_mass: vec![1.0; n],
            inv_count: count
                .iter()
                .map(|c| if *c > 0 { 1.0 / *c as f32 } else { 0.0 })
                .collect(),
            ..Default::default()
        };
        layout.cluster_start.push(0);
        for c in &clusters {
            let weights: Vec<f32> = c
                .members
                .iter()
                .map(|m| layout.inv_count[*m as usize])
                .collect();
            let total: f32 = weights.iter().sum();
            let centroid: Vec3 = c
                .members
                .iter()
                .zip(&weights)
                .map(|(m, w)| rest[*m as usize] * *w)
                .sum::<Vec3>()
                / total;
            let (mut bias, mut weight_sum) = (glam::DVec3::ZERO, 0.0f64);
            for (m, w) in c.members.iter().zip(&weights) {
                let (weight, offset) = (w / total, Vec3A::from(rest[*m as usize] - centroid));
                layout.member_particle.push(*m);
                layout.member_weight.push(weight);
                layout.rest_offset.push(offset);
                bias += Vec3::from(offset).as_dvec3() * weight as f64;
                weight_sum += weight as f64;
            }
            layout
                .cluster_start
                .push(layout.member_particle.len() as u32);
            layout.offset_bias.push(Vec3A::from(bias.as_vec3()));
            layout.weight_sum.push(weight_sum as f32);
            layout.stiffness.push(c.stiffness);
            layout.rotations.push(c.rotation);
        }
        // particle → membership slots
        layout.particle_start = Vec::with_capacity(n + 1);
        let mut start = 0u32;
        for c in &count {
            layout.particle_start.push(start);
            start += c;
        }
        layout.particle_start.push(start);
        let mut fill = layout.particle_start.clone();
        layout.particle_slots = vec![0; start as usize];
        for (slot, &m) in layout.member_particle.iter().enumerate() {
            layout.particle_slots[fill[m as usize] as usize] = slot as u32;
            fill[m as usize] += 1;
        }
        layout.deltas = vec![Vec3A::ZERO; layout.member_particle.len()];
        layout.task_bounds = (0..clusters.len())
            .step_by(CLUSTERS_PER_TASK)
            .chain([clusters.len()])
            .collect();
        layout
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of clusters.
    pub fn cluster_count(&self) -> usize {
        self.stiffness.len()
    }

    /// Number of memberships (sum of cluster sizes).
    pub fn membership_count(&self) -> usize {
        self.member_particle.len()
    }

    /// Runs `iterations` Jacobi shape-matching iterations, each followed by collisions.
    pub fn solve(&mut self, iterations: u32, colliders: &Colliders) {
        self.corrections.iter_mut().for_each(|c| *c = Vec3A::ZERO);
        for _ in 0..iterations {
            self.match_clusters();
            self.move_particles(colliders);
        }
    }

    /// Adds the last solve's corrections to the velocities: `v += Σ Δp / dt`.
    ///
    /// Deriving velocity from the corrections rather than from `(p − p_prev) / dt` keeps
    /// the rounding of large absolute positions out of the velocities, so momentum is
    /// conserved to the precision of the (small) corrections.
    pub fn update_velocities(&mut self, inv_dt: f32) {
        let corrections = &self.corrections;
        self.velocities
            .par_iter_mut()
            .zip(corrections)
            .with_min_len(PARTICLES_PER_TASK)
            .for_each(|(v, c)| *v += *c * inv_dt);
    }

    /// Cluster pass: optimal rotation per cluster and goal displacement per membership.
    fn match_clusters(&mut self) {
        let positions = &self.positions;
        let (bias, weight_sum) = (&self.offset_bias, &self.weight_sum);
        let (start, members, offsets, weights, stiffness) = (
            &self.cluster_start,
            &self.member_particle,
            &self.rest_offset,
            &self.member_weight,
            &self.stiffness,
        );
        let slot_bounds: Vec<usize> = self
            .task_bounds
            .iter()
            .map(|&c| start[c] as usize)
            .collect();
        let rotation_tasks = split_at_bounds(&mut self.rotations, &self.task_bounds);
        let delta_tasks = split_at_bounds(&mut self.deltas, &slot_bounds);
        rotation_tasks
            .into_par_iter()
            .zip(delta_tasks)
            .enumerate()
            .for_each(|(task, (rotations, deltas))| {
                let first_cluster = self.task_bounds[task];
                let first_slot = start[first_cluster] as usize;
                for (i, rotation) in rotations.iter_mut().enumerate() {
                    let k = first_cluster + i;
                    let range = start[k] as usize..start[k + 1] as usize;
                    // Work relative to the first member: differences of nearby positions
                    // are exact, so A and the goals keep full precision far from the
                    // origin. Σ w·q = 0, so the reference point does not change A.
                    let origin = positions[members[range.start] as usize];
                    let mut centroid = Vec3A::ZERO;
                    let mut a = Mat3A::ZERO;
                    for s in range.clone() {
                        let p = positions[members[s] as usize] - origin;
                        let w = weights[s];
                        centroid += p * w;
                        let wq = offsets[s] * w;
                        a.x_axis += p * wq.x;
                        a.y_axis += p * wq.y;
                        a.z_axis += p * wq.z;
                    }
                    *rotation = extract_rotation(&Mat3::from(a), *rotation, ROTATION_ITERATIONS);
                    let r = Mat3A::from_quat(*rotation);
                    // Exact momentum balance in f32: Σw(Rq + c − p) = R·Σwq + c·Σw − Σwp = 0.
                    let centroid = (centroid - r * bias[k]) / weight_sum[k];
                    let s_k = stiffness[k];
                    for s in range {
                        let p = positions[members[s] as usize] - origin;
                        deltas[s - first_slot] = (r * offsets[s] + centroid - p) * s_k;
                    }
                }
            });
    }

    /// Particle pass: average goal displacement, then colliders.
    fn move_particles(&mut self, colliders: &Colliders) {
        let (starts, slots, deltas, inv_count, inv_mass, previous) = (
            &self.particle_start,
            &self.particle_slots,
            &self.deltas,
            &self.inv_count,
            &self.inv_mass,
            &self.previous,
        );
        self.positions
            .par_chunks_mut(PARTICLES_PER_TASK)
            .zip(self.corrections.par_chunks_mut(PARTICLES_PER_TASK))
            .enumerate()
            .for_each(|(task, (chunk, corrections))| {
                let base = task * PARTICLES_PER_TASK;
                for (j, (p, correction)) in chunk.iter_mut().zip(corrections).enumerate() {
                    let i = base + j;
                    if inv_mass[i] == 0.0 {
                        continue;
                    }
                    let mut sum = Vec3A::ZERO;
                    for &slot in &slots[starts[i] as usize..starts[i + 1] as usize] {
                        sum += deltas[slot as usize];
                    }
                    let step = sum * inv_count[i];
                    *p += step;
                    let unconstrained = *p;
                    resolve_colliders(p, previous[i], colliders);
                    *correction += step + (*p - unconstrained);
                }
            });
    }
}

/// Pushes `p` out of the ground and static boxes, with Coulomb friction against the
/// displacement since `previous`.
#[inline]
pub fn resolve_colliders(p: &mut Vec3A, previous: Vec3A, colliders: &Colliders) {
    if let Some(g) = &colliders.ground
        && p.y < g.height
    {
        let depth = g.height - p.y;
        p.y = g.height;
        apply_friction(p, previous, Vec3A::Y, depth, g.friction);
    }
    for b in &colliders.boxes {
        let (min, max) = (Vec3A::from(b.min), Vec3A::from(b.max));
        if p.cmpgt(min).all() && p.cmplt(max).all() {
            let below = *p - min;
            let above = max - *p;
            let (mut depth, mut normal) = (f32::INFINITY, Vec3A::ZERO);
            for (axis, unit) in [Vec3A::X, Vec3A::Y, Vec3A::Z].into_iter().enumerate() {
                if below[axis] < depth {
                    depth = below[axis];
                    normal = -unit;
                }
                if above[axis] < depth {
                    depth = above[axis];
                    normal = unit;
                }
            }
            *p += normal * depth;
            apply_friction(p, previous, normal, depth, b.friction);
        }
    }
}

#[inline]
fn apply_friction(p: &mut Vec3A, previous: Vec3A, normal: Vec3A, depth: f32, friction: f32) {
    let moved = *p - previous;
    let tangential = moved - normal * moved.dot(normal);
    let length = tangential.length();
    let limit = friction * depth;
    if length <= limit {
        *p -= tangential;
    } else if length > 0.0 {
        *p -= tangential * (limit / length);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bar(n: usize) -> (Vec<Vec3>, Vec<Vec<u32>>) {
        let rest: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let clusters = (0..n - 2)
            .map(|i| vec![i as u32, i as u32 + 1, i as u32 + 2])
            .collect();
        (rest, clusters)
    }

    #[test]
    fn restores_a_perturbed_bar_and_conserves_momentum() {
        let (rest, clusters) = bar(8);
        let spec = clusters.iter().map(|m| ClusterSpec {
            members: m,
            stiffness: 1.0,
            rotation: Quat::IDENTITY,
        });
        let mut l = SolverLayout::new(&rest, spec);
        l.positions[3].y += 0.5;
        l.positions[6].z -= 0.3;
        let momentum = |l: &SolverLayout| l.positions.iter().copied().sum::<Vec3A>();
        let before = momentum(&l);
        l.solve(200, &Colliders::default());
        assert!((momentum(&l) - before).length() < 1e-4);
        // back to a straight bar (up to a rigid motion): distances between ends restored
        let d = (l.positions[7] - l.positions[0]).length();
        assert!((d - 7.0).abs() < 0.05, "{d}");
    }

    #[test]
    fn ground_and_boxes_push_out() {
        let colliders = Colliders {
            ground: Some(GroundPlane {
                height: 0.0,
                friction: 0.0,
            }),
            boxes: vec![StaticBox {
                min: Vec3::splat(1.0),
                max: Vec3::splat(2.0),
                friction: 0.0,
            }],
        };
        let mut p = Vec3A::new(0.0, -0.5, 0.0);
        resolve_colliders(&mut p, Vec3A::ZERO, &colliders);
        assert_eq!(p.y, 0.0);
        let mut p = Vec3A::new(1.5, 1.9, 1.5);
        resolve_colliders(&mut p, Vec3A::new(1.5, 2.5, 1.5), &colliders);
        assert_eq!(p, Vec3A::new(1.5, 2.0, 1.5));
    }
}
