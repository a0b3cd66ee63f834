//! Edge distance constraints (SPEC §5, "stretch vs bend"): every live lattice edge of a
//! body whose material sets `edge_compliance` keeps its rest length. Shape matching
//! resists stretching and bending alike; soft clusters with stiff edges make a body that
//! bends easily but barely stretches.
//!
//! An edge `a–b` of rest length `L` is the constraint `C = |xₐ − x_b| − L` with
//! compliance `α = edge_compliance / h` (m/N: a bar of the material, cross-section h²
//! and length h, has stiffness `E h`), projected XPBD-style with its `λ` accumulated
//! over the substep. The edges of a body are coloured by axis and by the parity of their
//! lower end's coordinate along it: two edges of one colour never share a particle
//! (a particle has at most one link each way along an axis), so each colour is
//! projected in parallel, in place, deterministically. A body's edges are taken again
//! from its lattice whenever it changes, so severed and split edges lose their
//! constraint at once. In projective dynamics each edge adds `w (eₐ − e_b)(eₐ − e_b)ᵀ`
//! to the global matrix (`w = 1/α`), its projection the current direction at length `L`.

use crate::body::lattice::NO_PARTICLE;
use crate::solver::disjoint::Disjoint;
use crate::solver::term::{
    NO_DENSE, ParticleState, ProjectiveTerm, Substep, Term, TermExtent, Topology, Unknowns,
};
use glam::{DVec3, Vec3A};
use rayon::prelude::*;

/// Edges per parallel task.
const EDGES_PER_TASK: usize = 1024;

/// Colours: three axes × two parities.
const COLOURS: usize = 6;

/// One edge.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Edge {
    /// Its ends' dense indices.
    a: u32,
    b: u32,
    /// Its rest length.
    rest: f32,
}

/// One body's edges, by colour, with their compliance.
#[derive(Clone, Debug, Default)]
struct BodyEdges {
    /// The body's id.
    id: u64,
    /// Compliance of each edge, m/N.
    compliance: f32,
    /// The edges of each colour.
    colours: [Vec<Edge>; COLOURS],
    /// Each edge's accumulated `λ` in this substep, as `colours`.
    lambda: [Vec<f32>; COLOURS],
}

/// The edge term; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Edges {
    /// By body id.
    bodies: Vec<BodyEdges>,
    /// Changes whenever the edges do (for projective dynamics' matrix).
    version: u64,
}

impl Edges {
    /// Number of edges.
    pub fn len(&self) -> usize {
        self.bodies
            .iter()
            .flat_map(|b| &b.colours)
            .map(Vec::len)
            .sum()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every edge as `(a, b, rest length, compliance)` (dense ends).
    pub fn iter(&self) -> impl Iterator<Item = (u32, u32, f32, f32)> + '_ {
        self.bodies.iter().flat_map(|body| {
            body.colours
                .iter()
                .flatten()
                .map(|e| (e.a, e.b, e.rest, body.compliance))
        })
    }
}

/// The edges of one body as its lattice links them, or `None` when its material has
/// no edge constraints.
fn body_edges(body: &crate::solver::term::BodyTopology) -> Option<BodyEdges> {
    let compliance = body.material.edge_compliance? / body.lattice.spacing();
    let lattice = body.lattice;
    let mut edges = BodyEdges {
        id: body.id,
        compliance,
        ..Default::default()
    };
    let dense = |p: u32| {
        body.dense
            .get(p as usize)
            .copied()
            .filter(|d| *d != NO_DENSE)
    };
    for a in lattice.live_particles() {
        // each edge once: from its end on the negative side, along +x, +y, +z
        for (axis, d) in [1usize, 3, 5].into_iter().enumerate() {
            let b = lattice.link(a, d);
            if b == NO_PARTICLE {
                continue;
            }
            let (Some(da), Some(db)) = (dense(a), dense(b)) else {
                continue;
            };
            let rest = (lattice.rest_position(a) - lattice.rest_position(b)).length();
            let parity = (lattice.coord(a)[axis] & 1) as usize;
            edges.colours[2 * axis + parity].push(Edge { a: da, b: db, rest });
        }
    }
    for (lambda, colour) in edges.lambda.iter_mut().zip(&mut edges.colours) {
        // in the particles' dense (spatial) order, so that a sweep walks memory in order
        colour.sort_unstable_by_key(|e| (e.a, e.b));
        *lambda = vec![0.0; colour.len()];
    }
    Some(edges)
}

impl Term for Edges {
    fn name(&self) -> &'static str {
        "edges"
    }

    fn is_empty(&self) -> bool {
        Edges::is_empty(self)
    }

    fn extent(&self) -> TermExtent {
        TermExtent {
            particles: 0,
            constraints: self.len(),
        }
    }

    /// Takes the edges of every body that changed (all, after a rebuild) from its
    /// lattice again; forgets the bodies that are gone.
    fn topology(&mut self, change: &Topology) {
        let kept = std::mem::take(&mut self.bodies);
        self.bodies = change.rebuild_bodies(kept, |b| b.id, body_edges);
        self.version += 1;
    }

    fn begin_substep(&mut self, _step: &Substep, _state: &mut ParticleState) {
        for lambda in self.bodies.iter_mut().flat_map(|b| &mut b.lambda) {
            lambda.iter_mut().for_each(|l| *l = 0.0);
        }
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        let inv_mass = state.inv_mass;
        let positions = Disjoint::new(state.positions);
        let corrections = Disjoint::new(state.corrections);
        for body in &mut self.bodies {
            let alpha = step.scaled(body.compliance);
            for (edges, lambda) in body.colours.iter().zip(&mut body.lambda) {
                edges
                    .par_chunks(EDGES_PER_TASK)
                    .zip(lambda.par_chunks_mut(EDGES_PER_TASK))
                    .for_each(|(edges, lambda)| {
                        for (e, lambda) in edges.iter().zip(lambda) {
                            let (a, b) = (e.a as usize, e.b as usize);
                            let (wa, wb) = (inv_mass[a], inv_mass[b]);
                            if wa + wb == 0.0 {
                                continue;
                            }
                            // SAFETY: the edges of one colour share no particle, so this
                            // task alone reads and writes `a` and `b` during the colour;
                            // the ends are dense indices of these arrays.
                            unsafe {
                                let apart = positions.read(a) - positions.read(b);
                                let length = apart.length();
                                if length == 0.0 {
                                    continue;
                                }
                                let c = length - e.rest;
                                let delta = (-c - alpha * *lambda) / (wa + wb + alpha);
                                *lambda += delta;
                                let step = apart * (delta / length);
                                positions.write(a, positions.read(a) + step * wa);
                                corrections.write(a, corrections.read(a) + step * wa);
                                positions.write(b, positions.read(b) - step * wb);
                                corrections.write(b, corrections.read(b) - step * wb);
                            }
                        }
                    });
            }
        }
    }

    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        Some(self)
    }
}

impl ProjectiveTerm for Edges {
    fn version(&self) -> u64 {
        self.version
    }

    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    ) {
        for (a, b, _, compliance) in self.iter() {
            let w = unknowns.weight(compliance, &[a, b], step.dt);
            let (ra, rb) = (unknowns.row(a), unknowns.row(b));
            for row in [ra, rb].into_iter().flatten() {
                entries.push((row, row, w));
            }
            if let (Some(ra), Some(rb)) = (ra, rb) {
                entries.push((ra.max(rb), ra.min(rb), -w));
            }
        }
    }

    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        _orientations: &mut [glam::Quat],
        forces: &mut [DVec3],
    ) {
        for (a, b, rest, compliance) in self.iter() {
            let w = unknowns.weight(compliance, &[a, b], step.dt);
            let apart = (positions[a as usize] - positions[b as usize]).as_dvec3();
            let length = apart.length();
            // the projection: the edge at its rest length along its current direction
            let projected = if length > 0.0 {
                apart * (rest as f64 / length)
            } else {
                apart
            };
            let force = (projected - apart) * w;
            forces[a as usize] += force;
            forces[b as usize] -= force;
        }
    }
}
