//! Stage detect (SPEC §2.3): READ-ONLY. Selects particles within half the cut width of a
//! tool's surface (or inside it), over the whole volume swept since the last frame.
//! Its only output is the `CutList`. The test itself is [`crate::detection::particles_hit`]
//! (parallel, culled by blocks, deterministic order).

use crate::components::{Tool, ToolPose};
use crate::detection::{ToolSweep, particles_hit};
use crate::resources::{BodyCut, CutList, SolverCache};
use bevy_ecs::prelude::*;

/// Fills the cut list from the solver cache's dense positions.
pub fn detect(cache: Res<SolverCache>, tools: Query<(&Tool, &ToolPose)>, mut out: ResMut<CutList>) {
    out.cuts.clear();
    let sweeps: Vec<ToolSweep> = tools
        .iter()
        .filter_map(|(tool, pose)| ToolSweep::new(tool, &pose.last, &pose.current))
        .collect();
    if sweeps.is_empty() || cache.particles.is_empty() {
        return;
    }
    for i in particles_hit(&cache.layout.positions, &cache.live, &sweeps) {
        let Some((body, local)) = cache.owner(i) else {
            continue;
        };
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
