//! Stage detect: READ-ONLY. Selects, over the whole volume each tool swept
//! since the last frame, the particles a `remove` tool comes within half its cut width
//! of, and the edges a `sever` or `split` tool separates; and, in bodies whose material
//! tears, the edges of voxels stretched past the limit. Its output is the `CutList`;
//! besides, it keeps its culling memory ([`crate::cut::culling`], with the `culling`
//! setting): a block of particles is not tested against a tool that cannot have
//! reached it since the two were last measured. The tests themselves are [`crate::cut::detection::particles_hit`],
//! [`crate::cut::detection::edges_separated`] and [`crate::cut::tear::find_tears`] (parallel,
//! deterministic order).

use crate::body::lattice::{Lattice, NO_PARTICLE};
use crate::cut::blocks::{Blocks, DenseParticles};
use crate::cut::crossings::rest_crossing;
use crate::cut::culling::{FollowedTool, NearTools};
use crate::cut::detection::{
    NearBlocks, Reported, edges_separated, particles_hit, particles_inside,
};
use crate::cut::particle_split::plan_splits;
use crate::cut::tear::find_tears;
use crate::cut::tool::CutMode;
use crate::cut::tool_sweep::ToolSweep;
use crate::ecs::components::{Body, BodyLattice, Tool, ToolPose};
use crate::ecs::layout::SolverCache;
use crate::ecs::resources::{BodyCut, CutList, CutReport, DetectCulling, SimSettings};
use bevy_ecs::prelude::*;
use glam::Quat;

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(
    settings: Res<SimSettings>,
    cache: Res<SolverCache>,
    report: Res<CutReport>,
    tools: Query<(Entity, Ref<Tool>, &ToolPose)>,
    bodies: Query<(&Body, &BodyLattice)>,
    mut out: ResMut<CutList>,
    mut culling: ResMut<DetectCulling>,
) {
    let start = std::time::Instant::now();
    out.cuts.clear();
    if cache.layout.is_empty() {
        return;
    }
    detect_tears(&cache, &bodies, &mut out.cuts);
    let culling = &mut *culling;
    if culling.blocks_for != Some(cache.layout.version())
        || culling.blocks.particles() != cache.particles.positions.len()
    {
        culling.blocks = dense_blocks(&cache, &bodies);
        culling.blocks_for = Some(cache.layout.version());
    }
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
    let dense = DenseParticles {
        positions: &cache.particles.positions,
        live: cache.layout.live(),
        blocks: &culling.blocks,
    };
    let near = settings.0.culling.then(|| {
        near_blocks(
            &cache,
            dense,
            &report,
            &bodies,
            &mut culling.culling,
            &followed,
        )
    });
    // the tools in groups by what they do, each in the order followed (which names an
    // edge's first tool), with its column in the culling's table
    let group = |wanted: &dyn Fn(&ToolSweep) -> bool| -> (Vec<&ToolSweep>, Vec<usize>) {
        (followed.iter().enumerate())
            .filter(|(_, (_, s))| wanted(s))
            .map(|(k, (_, s))| (s, k))
            .unzip()
    };
    let near = near.as_ref();
    // removers remove what they hit; blades sever what they cross; spheres and capsules
    // carve what they have ever been inside and sever what they graze; a split blade's
    // separated edges go to its plan (each body's, each tool's plane)
    let removes = |t: &ToolSweep| t.mode() == CutMode::Remove;
    let splits = |t: &ToolSweep| t.mode() == CutMode::Split && t.blade_plane().is_some();
    let (removers, removing) = group(&removes);
    let (carving, carves) = group(&|t| !removes(t) && t.carves());
    let (splitting, split_columns) = group(&|t| !removes(t) && !t.carves() && splits(t));
    let (severing, sever_columns) = group(&|t| !removes(t) && !t.carves() && !splits(t));
    for i in particles_hit(dense, &removers, near.map(|n| (n, &removing[..]))) {
        if let Some((body, local)) = cache.layout.owner(i) {
            BodyCut::entry(&mut out.cuts, body).particles.push(local);
        }
    }
    for i in particles_inside(dense, &carving, near.map(|n| (n, &carves[..]))) {
        if let Some((body, local)) = cache.layout.owner(i) {
            BodyCut::entry(&mut out.cuts, body).carved.push(local);
        }
    }
    carve_crossings(&cache, &bodies, &carving, &mut out.cuts);
    let groups = [
        (&severing, &sever_columns, Severed::Edges),
        (&splitting, &split_columns, Severed::Split),
        (&carving, &carves, Severed::Grazed),
    ];
    for (tools, columns, kind) in groups {
        if !tools.is_empty() {
            let near = near.map(|n| (n, &columns[..]));
            separate_edges(&cache, dense, &bodies, tools, kind, near, &mut out.cuts);
        }
    }
    out.cuts.sort_by_key(|c| c.body);
    for c in &mut out.cuts {
        c.particles.sort_unstable();
        c.edges.sort_unstable();
        c.grazed.sort_unstable();
        c.carved.sort_unstable();
        // (the first tool listed that crossed an edge names its crossing)
        c.crossings.sort_by_key(|(e, _)| *e);
        c.crossings.dedup_by_key(|(e, _)| *e);
        if let Ok((_, lattice)) = bodies.get(c.body) {
            c.splits.merge_tools(&lattice.lattice);
        }
    }
    culling.last_ms = start.elapsed().as_secs_f64() * 1e3;
}

/// Adds to each body's cut the edges `tools` separate, with where each is crossed,
/// as `kind` says (severed, grazed, or planned as splits).
fn separate_edges(
    cache: &SolverCache,
    dense: DenseParticles,
    bodies: &Query<(&Body, &BodyLattice)>,
    tools: &[&ToolSweep],
    kind: Severed,
    near: NearBlocks,
    cuts: &mut Vec<BodyCut>,
) {
    let positions = &cache.particles.positions;
    let (bodies_dense, locals) = (cache.layout.bodies(), cache.layout.locals());
    for (k, b) in bodies_dense.iter().enumerate() {
        let Ok((_, lattice)) = bodies.get(b.body) else {
            continue;
        };
        let lattice = &lattice.lattice;
        // the body's slots: up to the next body's (its lattice may have more
        // particles than slots, those it had lost when it was laid out)
        let next = bodies_dense
            .get(k + 1)
            .map_or(positions.len(), |n| n.first as usize);
        let range = b.first as usize..next.min(positions.len());
        let partners = |i: usize| {
            let local = locals[i];
            [1, 3, 5].map(|d| match lattice.link(local, d) {
                NO_PARTICLE => u32::MAX,
                n => b.slot(n).map_or(u32::MAX, |s| s as u32),
            })
        };
        // each split blade plans the edges it separates by its own plane, so every
        // blade that separates an edge is listed (one pass over the particles for all)
        let reported = match kind {
            Severed::Split => Reported::EveryTool,
            Severed::Edges | Severed::Grazed => Reported::FirstTool,
        };
        let mut separated = edges_separated(dense, range, partners, tools, near, reported);
        if separated.is_empty() {
            continue;
        }
        let position = |p: u32| b.position(positions, p);
        // (the others' edges are one list; a split blade's its own, in the tools' order:
        // a stable sort keeps each blade's edges in their order)
        if kind == Severed::Split {
            separated.sort_by_key(|s| s.tool);
        }
        let lists = separated.chunk_by(|a, b| kind != Severed::Split || a.tool == b.tool);
        for list in lists {
            let tool = tools[list[0].tool];
            let mut edges = Vec::with_capacity(list.len());
            let mut crossings = Vec::with_capacity(list.len());
            let mut turn = Quat::IDENTITY;
            for s in list {
                let (a, q) = (locals[s.ends.0], locals[s.ends.1]);
                let c = rest_crossing(lattice, a, s.fraction, s.normal, position, &mut turn);
                edges.push((a.min(q), a.max(q)));
                crossings.push(((a.min(q), a.max(q)), if a < q { c } else { c.reversed() }));
            }
            let cut = BodyCut::entry(cuts, b.body);
            cut.crossings.append(&mut crossings);
            match (kind, tool.blade_plane()) {
                (Severed::Edges, _) => cut.edges.append(&mut edges),
                (Severed::Grazed, _) => cut.grazed.append(&mut edges),
                (Severed::Split, Some(plane)) => {
                    edges.sort_unstable();
                    let plan = plan_splits(lattice, &edges, position, plane);
                    cut.splits.splits.extend(plan.splits);
                    cut.splits.sever.extend(plan.sever);
                }
                // (only blades with a plane are split blades)
                (Severed::Split, None) => {}
            }
        }
    }
}

/// Adds to each body's cut where the carving tools cross the edges from the particles
/// they are inside this frame to linked particles neither inside nor carved before
/// (the edges the carve will sever), each crossed by the first tool its inside end is
/// in.
fn carve_crossings(
    cache: &SolverCache,
    bodies: &Query<(&Body, &BodyLattice)>,
    carving: &[&ToolSweep],
    cuts: &mut [BodyCut],
) {
    let positions = &cache.particles.positions;
    for cut in cuts.iter_mut().filter(|c| !c.carved.is_empty()) {
        cut.carved.sort_unstable();
        let (Ok((_, lattice)), Some(b)) = (bodies.get(cut.body), cache.layout.body(cut.body))
        else {
            continue;
        };
        let lattice = &lattice.lattice;
        let position = |p: u32| b.position(positions, p);
        let mut turn = Quat::IDENTITY;
        for &c in &cut.carved {
            let x = position(c);
            let Some(tool) = carving.iter().find(|t| t.contains(x)) else {
                continue;
            };
            for q in lattice.neighbours(c) {
                if cut.carved.binary_search(&q).is_ok() || lattice.is_carved(q) {
                    continue;
                }
                let (fraction, normal) = tool.crossing(x, position(q));
                let crossing = rest_crossing(lattice, c, fraction, normal, position, &mut turn);
                let oriented = if c < q { crossing } else { crossing.reversed() };
                cut.crossings.push(((c.min(q), c.max(q)), oriented));
            }
        }
    }
}

/// The blocks of the layout's dense particles: each body's particles (in Morton order)
/// broken where their aligned cube of 4³ cells changes, so that every block is compact
/// however many particles the body lost or gained since it was intact.
fn dense_blocks(cache: &SolverCache, bodies: &Query<(&Body, &BodyLattice)>) -> Blocks {
    let layout = &cache.layout;
    let lattices = layout_lattices(cache, bodies);
    Blocks::by_key(cache.particles.positions.len(), |d| {
        let body = layout.body_index_of(d);
        let lattice = body.and_then(|b| lattices[b]);
        (body, lattice.map(|l| l.morton_cube(layout.locals()[d])))
    })
}

/// The lattice of each body of the layout (by its index in the layout's bodies), looked
/// up once rather than per dense particle.
fn layout_lattices<'a>(
    cache: &SolverCache,
    bodies: &'a Query<(&Body, &BodyLattice)>,
) -> Vec<Option<&'a Lattice>> {
    (cache.layout.bodies().iter())
        .map(|b| bodies.get(b.body).ok().map(|(_, l)| &l.lattice))
        .collect()
}

/// Which blocks of the dense particles some tool may reach this frame (see
/// [`crate::cut::culling`]).
fn near_blocks(
    cache: &SolverCache,
    dense: DenseParticles,
    report: &CutReport,
    bodies: &Query<(&Body, &BodyLattice)>,
    culling: &mut crate::cut::culling::ToolCulling,
    tools: &[(FollowedTool, ToolSweep)],
) -> NearTools {
    // a cut severs edges (a block's partners only become fewer: its ball stays a bound)
    // and keeps every particle's dense index; only edges linked again can reach blocks
    // the table does not name
    if report.bodies.iter().any(|b| !b.relinked.is_empty()) {
        culling.forget_layout();
    }
    // each dense particle's +x, +y, +z partners, by the links of its body's lattice
    let layout = &cache.layout;
    let lattices = layout_lattices(cache, bodies);
    culling.set_layout(layout.version(), dense.blocks, |i| {
        let Some(b) = layout.body_index_of(i) else {
            return [u32::MAX; 3];
        };
        let (body, Some(lattice)) = (&layout.bodies()[b], lattices[b]) else {
            return [u32::MAX; 3];
        };
        let local = layout.locals()[i];
        [1, 3, 5].map(|d| match lattice.link(local, d) {
            NO_PARTICLE => u32::MAX,
            p => body.slot(p).map_or(u32::MAX, |s| s as u32),
        })
    });
    let pairs: Vec<(FollowedTool, &ToolSweep)> =
        tools.iter().map(|(t, s)| (t.clone(), s)).collect();
    culling.follow(&pairs);
    let sweeps: Vec<&ToolSweep> = tools.iter().map(|(_, s)| s).collect();
    culling.near_blocks(dense, &sweeps)
}

/// What a group of tools does with the edges it separates.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Severed {
    /// Severs them (`sever` blades).
    Edges,
    /// Splits the particles at them or severs them, by each `split` blade's plan.
    Split,
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
    for b in cache.layout.bodies() {
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
