//! Stage detect: READ-ONLY. Selects, over the whole volume each tool swept
//! since the last frame, the particles a `remove` tool comes within half its cut width
//! of, and the edges a `sever` or `split` tool separates; and, in bodies whose material
//! tears, the edges of voxels stretched past the limit. Its output is the `CutList`;
//! besides, it keeps its culling memory ([`crate::cut::culling`], with the `culling`
//! setting): the blocks of particles no tool can have reached since they were last
//! measured are not tested. The tests themselves are [`crate::cut::detection::particles_hit`],
//! [`crate::cut::detection::edges_separated`] and [`crate::cut::tear::find_tears`] (parallel,
//! deterministic order).

use crate::body::lattice::NO_PARTICLE;
use crate::cut::culling::FollowedTool;
use crate::cut::detection::{edges_separated, particles_hit, particles_inside};
use crate::cut::particle_split::plan_splits;
use crate::cut::tear::find_tears;
use crate::cut::tool::{BladePlane, CutMode};
use crate::cut::tool_sweep::ToolSweep;
use crate::ecs::components::{Body, BodyLattice, Tool, ToolPose};
use crate::ecs::resources::{BodyCut, CutList, DetectCulling, SimSettings, SolverCache};
use bevy_ecs::prelude::*;

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(
    settings: Res<SimSettings>,
    cache: Res<SolverCache>,
    tools: Query<(Entity, Ref<Tool>, &ToolPose)>,
    bodies: Query<(&Body, &BodyLattice)>,
    mut out: ResMut<CutList>,
    mut culling: ResMut<DetectCulling>,
) {
    let start = std::time::Instant::now();
    out.cuts.clear();
    if cache.entities.is_empty() {
        return;
    }
    detect_tears(&cache, &bodies, &mut out.cuts);
    let mut followed: Vec<(FollowedTool, ToolSweep)> = tools
        .iter()
        .filter_map(|(entity, tool, pose)| {
            let sweep = ToolSweep::new(&tool, &pose.last, &pose.current)?;
            let id = FollowedTool {
                id: entity.to_bits(),
                changed: tool.is_changed(),
                current: pose.current,
            };
            Some((id, sweep))
        })
        .collect();
    followed.sort_unstable_by_key(|(t, _)| t.id);
    let near = settings
        .0
        .culling
        .then(|| near_blocks(&cache, &bodies, &mut culling, &followed));
    let near = near.as_deref();
    let sweeps: Vec<ToolSweep> = followed.into_iter().map(|(_, s)| s).collect();
    let (removers, severers): (Vec<ToolSweep>, Vec<ToolSweep>) = sweeps
        .into_iter()
        .partition(|t| t.mode() == CutMode::Remove);
    // blades sever what they cross; spheres and capsules carve what they have ever been
    // inside and sever what they graze
    let (carving, slicing): (Vec<ToolSweep>, Vec<ToolSweep>) =
        severers.into_iter().partition(|t| t.carves());
    let positions = &cache.particles.positions;
    for i in particles_hit(positions, &cache.live, &removers, near) {
        if let Some((body, local)) = cache.owner(i) {
            BodyCut::entry(&mut out.cuts, body).particles.push(local);
        }
    }
    for i in particles_inside(positions, &cache.live, &carving, near) {
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
                edges_separated(positions, &cache.live, range, partners, &tools, near)
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
    culling.last_ms = start.elapsed().as_secs_f64() * 1e3;
}

/// Which blocks of the dense particles some tool may reach this frame (see
/// [`crate::cut::culling`]).
fn near_blocks(
    cache: &SolverCache,
    bodies: &Query<(&Body, &BodyLattice)>,
    culling: &mut DetectCulling,
    tools: &[(FollowedTool, ToolSweep)],
) -> Vec<bool> {
    let culling = &mut culling.culling;
    let n = cache.particles.positions.len();
    // each dense particle's +x, +y, +z partners, by the links of its body's lattice
    // (its body: the last whose dense range starts at or before it)
    culling.set_layout(cache.layout_version, n, |i| {
        let body = cache.body_dense.partition_point(|b| b.first as usize <= i);
        let Some(b) = body.checked_sub(1).and_then(|b| cache.body_dense.get(b)) else {
            return [u32::MAX; 3];
        };
        let Ok((_, lattice)) = bodies.get(b.body) else {
            return [u32::MAX; 3];
        };
        let local = cache.locals[i];
        [1, 3, 5].map(|d| match lattice.lattice.link(local, d) {
            NO_PARTICLE => u32::MAX,
            p => b.slot(p).map_or(u32::MAX, |s| s as u32),
        })
    });
    let pairs: Vec<(FollowedTool, &ToolSweep)> =
        tools.iter().map(|(t, s)| (t.clone(), s)).collect();
    culling.follow(&pairs);
    let sweeps: Vec<&ToolSweep> = tools.iter().map(|(_, s)| s).collect();
    culling.near_blocks(&cache.particles.positions, &cache.live, &sweeps)
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
