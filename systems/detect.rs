//! Stage detect (SPEC §2.3): READ-ONLY. Selects, over the whole volume each tool swept
//! since the last frame, the particles a `remove` tool comes within half its cut width
//! of, and the edges a `sever` or `split` tool separates; and, in bodies whose material
//! tears, the edges of voxels stretched past the limit. Its only output is the
//! `CutList`. The tests themselves are [`crate::detection::particles_hit`],
//! [`crate::detection::edges_separated`] and [`crate::tear::find_tears`] (parallel,
//! deterministic order).

use crate::components::{Body, BodyLattice, Tool, ToolPose};
use crate::detection::{ToolSweep, edges_separated, particles_hit};
use crate::lattice::NO_PARTICLE;
use crate::resources::{BodyCut, CutList, SolverCache};
use crate::tear::find_tears;
use crate::tool::CutMode;
use bevy_ecs::prelude::*;
use glam::Vec3;

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(
    cache: Res<SolverCache>,
    tools: Query<(&Tool, &ToolPose)>,
    bodies: Query<(&Body, &BodyLattice)>,
    mut out: ResMut<CutList>,
) {
    out.cuts.clear();
    if cache.particles.is_empty() {
        return;
    }
    detect_tears(&cache, &bodies, &mut out.cuts);
    let sweeps: Vec<ToolSweep> = tools
        .iter()
        .filter_map(|(tool, pose)| ToolSweep::new(tool, &pose.last, &pose.current))
        .collect();
    let (removers, severers): (Vec<ToolSweep>, Vec<ToolSweep>) = sweeps
        .into_iter()
        .partition(|t| t.mode() == CutMode::Remove);
    let positions = &cache.layout.positions;
    for i in particles_hit(positions, &cache.live, &removers) {
        if let Some((body, local)) = cache.owner(i) {
            cut_of(&mut out.cuts, body).particles.push(local);
        }
    }
    if !severers.is_empty() {
        let severers: Vec<&ToolSweep> = severers.iter().collect();
        for b in &cache.body_dense {
            let Ok((_, lattice)) = bodies.get(b.body) else {
                continue;
            };
            let first = b.first as usize;
            let range = first..first + b.dense.len().min(positions.len() - first);
            let partners = |i: usize| {
                let local = cache.locals[i];
                [1, 3, 5].map(|d| match lattice.lattice.link(local, d) {
                    NO_PARTICLE => u32::MAX,
                    n => b.dense.get(n as usize).copied().unwrap_or(u32::MAX),
                })
            };
            let edges = edges_separated(positions, &cache.live, range, partners, &severers);
            if edges.is_empty() {
                continue;
            }
            let cut = cut_of(&mut out.cuts, b.body);
            cut.edges.extend(edges.into_iter().map(|(i, j)| {
                let (a, b) = (cache.locals[i], cache.locals[j]);
                (a.min(b), a.max(b))
            }));
        }
    }
    out.cuts.sort_by_key(|c| c.body);
    for c in &mut out.cuts {
        c.particles.sort_unstable();
        c.edges.sort_unstable();
    }
}

/// Lists the torn edges of every body whose material tears.
fn detect_tears(
    cache: &SolverCache,
    bodies: &Query<(&Body, &BodyLattice)>,
    cuts: &mut Vec<BodyCut>,
) {
    let positions = &cache.layout.positions;
    for b in &cache.body_dense {
        let Ok((body, lattice)) = bodies.get(b.body) else {
            continue;
        };
        let Some(limit) = body.material.tear_stretch else {
            continue;
        };
        let position = |p: u32| {
            b.dense
                .get(p as usize)
                .and_then(|&d| positions.get(d as usize))
                .map_or(Vec3::NAN, |x| Vec3::from(*x))
        };
        let held = |p: u32| {
            b.dense
                .get(p as usize)
                .and_then(|&d| cache.layout.inv_mass.get(d as usize))
                .is_some_and(|w| *w == 0.0)
        };
        let budget = body.material.tear_budget as usize;
        let tears = find_tears(&lattice.lattice, position, held, limit, budget);
        if !tears.is_empty() {
            cut_of(cuts, b.body)
                .torn
                .extend(tears.into_iter().flat_map(|t| t.edges));
        }
    }
}

/// The cut list's entry for `body`, added when missing (found at once when the last
/// entry is the body's, as it is for particles listed in body order).
fn cut_of(cuts: &mut Vec<BodyCut>, body: Entity) -> &mut BodyCut {
    let k = match cuts.iter().rposition(|c| c.body == body) {
        Some(k) => k,
        None => {
            cuts.push(BodyCut {
                body,
                particles: Vec::new(),
                edges: Vec::new(),
                torn: Vec::new(),
            });
            cuts.len() - 1
        }
    };
    &mut cuts[k]
}
