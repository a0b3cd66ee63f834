//! The shape-matching groups of one body of the oriented model, built from its lattice
//! whenever it changes: one implicit group per live particle outside the explicit
//! groups — the particle and its live linked neighbours — and one group per connected
//! piece of each explicit group ([`crate::body::groups::ParticleGroups::explicit_pieces`]), coloured so that
//! the groups of one colour share no particle.
//!
//! Colours: an implicit group's is `(x + 3y + 9z) mod 13` of its centre's lattice
//! coordinate. Two implicit groups share a particle only if their centres are at most two
//! links apart, and the map sends none of those 24 offsets (`±eᵢ`, `±2eᵢ`, `±eᵢ ± eⱼ`)
//! to a multiple of 13 (their images are ±1, ±2, ±3, ±4, ±6, ±8, ±9, ±10, ±12, ±18),
//! so each colour is a set of disjoint groups. The two halves
//! of a split particle share a coordinate but no link, so their groups are disjoint too.
//! Explicit pieces may share particles (joints), so each is a colour of its own.

use super::batched::{ImplicitBatches, Memberships};
use crate::body::lattice::NO_PARTICLE;
use crate::config::{Material, Yield};
use crate::solver::term::{BodyTopology, NO_DENSE};
use glam::{IVec3, Vec3A};
use std::collections::HashMap;

/// Colours of the implicit groups.
pub const IMPLICIT_COLOURS: usize = 13;

/// Which of a group's members take its rotation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Turns {
    /// The centre particle only (an implicit group), by dense index.
    Centre(u32),
    /// Every oriented member (an explicit group: a rigid part).
    All,
}

/// One group: a range of the body's memberships.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Group {
    /// `[start, end)` of its memberships.
    pub range: [u32; 2],
    /// Who takes its rotation.
    pub turns: Turns,
}

/// One body's groups (see the module docs). Per membership: the member's dense index,
/// its rest position (body frame), the diagonal of its ellipsoid's
/// moment matrix per unit mass (`r²/5` per axis; zero for a non-oriented particle) and
/// the compliance of its pull toward its goal.
#[derive(Clone, Debug, Default)]
pub struct BodyGroups {
    /// The body's id.
    pub id: u64,
    /// The groups, colour by colour.
    pub groups: Vec<Group>,
    /// `[start, end)` of each colour's groups: the implicit colours, then one per
    /// explicit piece.
    pub colours: Vec<[u32; 2]>,
    /// Dense member of each membership.
    pub members: Vec<u32>,
    /// Rest position of each membership's particle.
    pub rest: Vec<Vec3A>,
    /// Moment diagonal of each membership's particle.
    pub moment: Vec<Vec3A>,
    /// Compliance (m/N) of each membership.
    pub compliance: Vec<f32>,
    /// Accumulated `λ` of each membership in this substep.
    pub lambda: Vec<Vec3A>,
    /// The body's plasticity, if its material yields.
    pub plastic: Option<Plasticity>,
    /// The implicit groups in batches, as the sweeps read them.
    pub batches: ImplicitBatches,
}

/// A group before its memberships are laid out: body-local members, the compliance
/// (1/Pa) of its material, who turns.
struct Draft {
    members: Vec<u32>,
    compliance: f32,
    turns_centre: Option<u32>,
    colour: usize,
}

impl BodyGroups {
    /// The groups of `body`, or `None` when its material is not of the oriented model.
    pub fn build(body: &BodyTopology) -> Option<Self> {
        if body.material.model != crate::config::Model::Oriented {
            return None;
        }
        let lattice = body.lattice;
        let h = lattice.spacing();
        let dense = |i: u32| {
            body.dense
                .get(i as usize)
                .copied()
                .filter(|d| *d != NO_DENSE)
        };
        let pieces = body.groups.explicit_pieces(lattice);
        let mut in_pieces = vec![0u32; lattice.len()];
        for m in pieces.iter().flat_map(|p| &p.members) {
            in_pieces[*m as usize] += 1;
        }
        let mut drafts: Vec<Draft> = Vec::new();
        for i in lattice.live_particles() {
            if in_pieces[i as usize] > 0 || dense(i).is_none() {
                continue;
            }
            let mut members = vec![i];
            members.extend(
                lattice
                    .links(i)
                    .into_iter()
                    .filter(|&n| n != NO_PARTICLE && dense(n).is_some()),
            );
            drafts.push(Draft {
                members,
                compliance: body.groups.compliance_of(i, body.material.compliance),
                turns_centre: Some(i),
                colour: colour(lattice.coord(i)),
            });
        }
        drafts.sort_by_key(|d| d.colour);
        for (k, piece) in pieces.iter().enumerate() {
            let members: Vec<u32> = piece
                .members
                .iter()
                .copied()
                .filter(|&m| dense(m).is_some())
                .collect();
            if !members.is_empty() {
                drafts.push(Draft {
                    members,
                    compliance: piece.compliance,
                    turns_centre: None,
                    colour: IMPLICIT_COLOURS + k,
                });
            }
        }
        let mut count = vec![0u32; lattice.len()];
        for m in drafts.iter().flat_map(|d| &d.members) {
            count[*m as usize] += 1;
        }
        let radii = Vec3A::from(body.material.particle_radii_at(h));
        let moment = radii * radii / 5.0;
        let mut out = BodyGroups {
            id: body.id,
            ..Default::default()
        };
        for draft in &drafts {
            let start = out.members.len() as u32;
            let rest: Vec<Vec3A> = draft
                .members
                .iter()
                .map(|&m| Vec3A::from(lattice.rest_position(m)))
                .collect();
            let centroid = rest.iter().copied().sum::<Vec3A>() / rest.len() as f32;
            let spread: f32 = rest.iter().map(|r| (*r - centroid).length_squared()).sum();
            // per-axis spread σ² of the rest offsets (a lone particle: its own cell's)
            let sigma2 = (spread / (3.0 * rest.len() as f32)).max(h * h / 12.0);
            // the group stores (κ/2) Σ |x − g|²/n with κ = E h³/σ² (see the term's docs)
            let per_count = draft.compliance * sigma2 / (h * h * h);
            for (&m, r) in draft.members.iter().zip(&rest) {
                out.members.push(dense(m).unwrap_or(NO_DENSE));
                out.rest.push(*r);
                // (a particle in two or more explicit pieces is non-oriented: a joint)
                let oriented = in_pieces[m as usize] < 2;
                out.moment.push(if oriented { moment } else { Vec3A::ZERO });
                out.compliance.push(per_count * count[m as usize] as f32);
            }
            let end = out.members.len() as u32;
            let turns = match draft.turns_centre {
                Some(c) => Turns::Centre(dense(c).unwrap_or(NO_DENSE)),
                None => Turns::All,
            };
            out.groups.push(Group {
                range: [start, end],
                turns,
            });
        }
        // (drafts run colour by colour; every explicit piece has a colour of its own)
        for (g, draft) in drafts.iter().enumerate() {
            let g = g as u32;
            match out.colours.last_mut() {
                Some(last) if g > 0 && drafts[g as usize - 1].colour == draft.colour => {
                    last[1] = g + 1
                }
                _ => out.colours.push([g, g + 1]),
            }
        }
        out.lambda = vec![Vec3A::ZERO; out.members.len()];
        out.plastic = Plasticity::of(body.material, &out.rest);
        out.batches = out.batched();
        Some(out)
    }

    /// Takes the plastic rest shapes of `old`, the body's groups before a change, for
    /// every group whose members are the same particles in the same order (matched by
    /// their lattice rest positions, which dense indices renumbered by a new layout do
    /// not change): a cut loses only the dents of the groups it touches.
    pub fn keep_dents(&mut self, old: &BodyGroups) {
        let (Some(new_plastic), Some(old_plastic)) = (&self.plastic, &old.plastic) else {
            return;
        };
        let key = |lattice_rest: &[Vec3A], g: &Group| {
            let first = lattice_rest[g.range[0] as usize];
            (first.to_array().map(f32::to_bits), g.range[1] - g.range[0])
        };
        let before: HashMap<([u32; 3], u32), &Group> = old
            .groups
            .iter()
            .map(|g| (key(&old_plastic.lattice_rest, g), g))
            .collect();
        let mut kept = false;
        for g in &self.groups {
            let Some(was) = before.get(&key(&new_plastic.lattice_rest, g)) else {
                continue;
            };
            let (now, then) = (self.range(g), old.range(was));
            if new_plastic.lattice_rest[now.clone()] == old_plastic.lattice_rest[then.clone()] {
                self.rest[now].copy_from_slice(&old.rest[then]);
                kept = true;
            }
        }
        if kept {
            self.batches.refresh_rest(&self.rest);
        }
    }

    /// The implicit groups in batches (every colour whose groups have a centre).
    fn batched(&self) -> ImplicitBatches {
        let colours: Vec<Option<Vec<[u32; 2]>>> = (self.colours.iter())
            .map(|c| {
                let groups = &self.groups[c[0] as usize..c[1] as usize];
                let implicit = groups.iter().all(|g| matches!(g.turns, Turns::Centre(_)));
                implicit.then(|| groups.iter().map(|g| g.range).collect())
            })
            .collect();
        let memberships = Memberships {
            members: &self.members,
            rest: &self.rest,
            moment: &self.moment,
            compliance: &self.compliance,
        };
        ImplicitBatches::build(&colours, &memberships)
    }

    /// The memberships of group `g`.
    pub fn range(&self, g: &Group) -> std::ops::Range<usize> {
        g.range[0] as usize..g.range[1] as usize
    }
}

/// A body's plasticity (see [`super::plastic`]), and its groups' lattice rest shapes.
#[derive(Clone, Debug)]
pub struct Plasticity {
    /// The material's yield.
    pub yielding: Yield,
    /// Each membership's lattice rest position.
    pub lattice_rest: Vec<Vec3A>,
}

impl Plasticity {
    /// The plasticity of a body of `material` whose groups rest at `rest`, or `None` for
    /// an elastic material.
    pub fn of(material: &Material, rest: &[Vec3A]) -> Option<Self> {
        material.yielding().map(|yielding| Plasticity {
            yielding,
            lattice_rest: rest.to_vec(),
        })
    }
}

/// The colour of an implicit group centred at lattice coordinate `c`.
pub fn colour(c: IVec3) -> usize {
    (c.x + 3 * c.y + 9 * c.z).rem_euclid(IMPLICIT_COLOURS as i32) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centres_two_links_apart_never_share_a_colour() {
        let mut offsets = Vec::new();
        for a in -2..=2i32 {
            for b in -2..=2i32 {
                for c in -2..=2i32 {
                    let o = IVec3::new(a, b, c);
                    let l1 = a.abs() + b.abs() + c.abs();
                    if (1..=2).contains(&l1) {
                        offsets.push(o);
                    }
                }
            }
        }
        assert_eq!(offsets.len(), 24);
        for base in [IVec3::ZERO, IVec3::new(5, -3, 11), IVec3::new(-7, 2, -1)] {
            for o in &offsets {
                assert_ne!(colour(base), colour(base + *o), "{base} + {o}");
            }
        }
    }
}
