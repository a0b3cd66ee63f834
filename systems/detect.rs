//! Stage detect (SPEC §2.3): READ-ONLY. Selects particles within half the cut width of a
//! tool's surface (or inside it), over the whole volume swept since the last frame.
//! Its only output is the `CutList`. Parallel over particles, deterministic order.

use crate::components::{Tool, ToolPose};
use crate::resources::{BodyCut, CutList, SolverCache};
use crate::tool::Sweep;
use bevy_ecs::prelude::*;
use glam::Vec3;
use rayon::prelude::*;

/// A tool prepared for testing: its sampled sweep and the bounding box of the sweep.
struct PreparedTool {
    tool: Tool,
    sweep: Sweep,
    min: Vec3,
    max: Vec3,
}

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(cache: Res<SolverCache>, tools: Query<(&Tool, &ToolPose)>, mut out: ResMut<CutList>) {
    out.cuts.clear();
    let prepared: Vec<PreparedTool> = tools
        .iter()
        .filter(|(t, p)| {
            t.shape.validate().is_ok()
                && t.cut_width.is_finite()
                && t.cut_width > 0.0
                && p.current.is_finite()
                && p.last.is_finite()
        })
        .map(|(tool, pose)| {
            let half = tool.cut_width * 0.5;
            let radius = tool.shape.bounding_radius();
            let sweep = Sweep::new(&pose.last, &pose.current, radius, half);
            let reach = Vec3::splat(radius + half);
            let (min, max) = sweep
                .samples
                .iter()
                .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), (p, _)| {
                    (lo.min(p.position - reach), hi.max(p.position + reach))
                });
            PreparedTool {
                tool: *tool,
                sweep,
                min,
                max,
            }
        })
        .collect();
    if prepared.is_empty() || cache.particles.is_empty() {
        return;
    }
    let positions = &cache.layout.positions;
    let hit: Vec<usize> = (0..positions.len())
        .into_par_iter()
        .with_min_len(4096)
        .filter(|&i| {
            if !cache.live[i] {
                return false;
            }
            let x = Vec3::from(positions[i]);
            prepared.iter().any(|t| {
                x.cmpge(t.min).all()
                    && x.cmple(t.max).all()
                    && t.sweep.hits(&t.tool.shape, x, t.tool.cut_width * 0.5)
            })
        })
        .collect();
    for i in hit {
        let (body, local) = cache.owners[i];
        match out.cuts.last_mut() {
            Some(c) if c.body == body => c.particles.push(local),
            _ => out.cuts.push(BodyCut {
                body,
                particles: vec![local],
            }),
        }
    }
    for c in &mut out.cuts {
        c.particles.sort_unstable();
    }
}
