//! Stage detect: READ-ONLY. Selects, over the whole volume each tool swept
//! since the last frame, the particles a `remove` tool comes within half its cut width
//! of, and the edges a `sever` or `split` tool separates; and, in bodies whose material
//! tears, the edges of voxels stretched past the limit. Its only output is the
//! `CutList`. The tests themselves are [`crate::cut::detection::particles_hit`],
//! [`crate::cut::detection::edges_separated`] and [`crate::cut::tear::find_tears`] (parallel,
//! deterministic order).

use crate::body::lattice::NO_PARTICLE;
use crate::cut::detection::{ToolSweep, edges_separated, particles_hit, particles_inside};
use crate::cut::particle_split::plan_splits;
use crate::cut::tear::find_tears;
use crate::cut::tool::{BladePlane, CutMode};
use crate::ecs::components::{Body, BodyLattice, Tool, ToolPose};
use crate::ecs::resources::{BodyCut, CutList, SolverCache};
use bevy_ecs::prelude::*;

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(
    cache: Res<SolverCache>,
    tools: Query<(&Tool, &ToolPose)>,
    bodies: Query<(&Body, &BodyLattice)>,
    mut out: ResMut<CutList>,
) {
    out.cuts.clear();
    if cache.entities.is_empty() {
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
    // blades sever what they cross; spheres and capsules carve what they have ever been
    // inside and sever what they graze
    let (carving, slicing): (Vec<ToolSweep>, Vec<ToolSweep>) =
        severers.into_iter().partition(|t| t.carves());
    let positions = &cache.particles.positions;
    for i in particles_hit(positions, &cache.live, &removers) {
        if let Some((body, local)) = cache.owner(i) {
            BodyCut::entry(&mut out.cuts, body).particles.push(local);
        }
    }
    for i in particles_inside(positions, &cache.live, &carving) {
        if let Some((body, local)) = cache.owner(i) {
            BodyCut::entry(&mut out.cuts, body).carved.push(local);
        }
    }
    // a split blade's separated edges go to its plan (each body's, each tool's plane),
    // the others' to the lists they sever from
    let (splitting, severing): (Vec<ToolSweep>, Vec<ToolSweep>) = slicing
        .into_iter()
        .partition(|t| t.mode() == CutMode::Split && t.blade_plane().is_some());
    let groups = std::iter::once((severing.iter().collect::<Vec<_>>(), Severed::Edges))
        .chain(
            splitting
                .iter()
                .filter_map(|t| Some((vec![t], Severed::Split(t.blade_plane()?)))),
        )
        .chain(std::iter::once((carving.iter().collect(), Severed::Grazed)));
    for (tools, kind) in groups {
        if tools.is_empty() {
            continue;
        }
        for b in &cache.body_dense {
            let Ok((_, lattice)) = bodies.get(b.body) else {
                continue;
            };
            let lattice = &lattice.lattice;
            let first = b.first as usize;
            let range = first..first + b.dense.len().min(positions.len() - first);
            let partners = |i: usize| {
                let local = cache.locals[i];
                [1, 3, 5].map(|d| match lattice.link(local, d) {
                    NO_PARTICLE => u32::MAX,
                    n => b.slot(n).map_or(u32::MAX, |s| s as u32),
                })
            };
            let mut edges: Vec<(u32, u32)> =
                edges_separated(positions, &cache.live, range, partners, &tools)
                    .into_iter()
                    .map(|(i, j)| {
                        let (a, b) = (cache.locals[i], cache.locals[j]);
                        (a.min(b), a.max(b))
                    })
                    .collect();
            if edges.is_empty() {
                continue;
            }
            let cut = BodyCut::entry(&mut out.cuts, b.body);
            match kind {
                Severed::Edges => cut.edges.append(&mut edges),
                Severed::Grazed => cut.grazed.append(&mut edges),
                Severed::Split(plane) => {
                    edges.sort_unstable();
                    let plan = plan_splits(lattice, &edges, |p| b.position(positions, p), plane);
                    cut.splits.splits.extend(plan.splits);
                    cut.splits.sever.extend(plan.sever);
                }
            }
        }
    }
    out.cuts.sort_by_key(|c| c.body);
    for c in &mut out.cuts {
        c.particles.sort_unstable();
        c.edges.sort_unstable();
        c.grazed.sort_unstable();
        c.carved.sort_unstable();
        if let Ok((_, lattice)) = bodies.get(c.body) {
            c.splits.merge_tools(&lattice.lattice);
        }
    }
}

/// What a group of tools does with the edges it separates.
#[derive(Clone, Copy)]
enum Severed {
    /// Severs them (`sever` blades).
    Edges,
    /// Splits the particles at them or severs them, by its plan (one `split` blade).
    Split(BladePlane),
    /// Severs them unless both ends are carved (spheres and capsules).
    Grazed,
}

/// Lists the torn edges of every body whose material tears.
fn detect_tears(
    cache: &SolverCache,
    bodies: &Query<(&Body, &BodyLattice)>,
    cuts: &mut Vec<BodyCut>,
) {
    let positions = &cache.particles.positions;
    for b in &cache.body_dense {
        let Ok((body, lattice)) = bodies.get(b.body) else {
            continue;
        };
        let Some(limit) = body.material.tear_stretch else {
            continue;
        };
        let position = |p: u32| b.position(positions, p);
        let held = |p: u32| {
            b.slot(p)
                .and_then(|d| cache.particles.inv_mass.get(d))
                .is_some_and(|w| *w == 0.0)
        };
        let budget = body.material.tear_budget as usize;
        let tears = find_tears(&lattice.lattice, position, held, limit, budget);
        if !tears.is_empty() {
            BodyCut::entry(cuts, b.body)
                .torn
                .extend(tears.into_iter().flat_map(|t| t.edges));
        }
    }
}
