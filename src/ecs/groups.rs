//! A spawning body's explicit groups and stiffness regions (SPEC §5): the regions its
//! description gives ([`GroupDesc`], [`StiffnessRegion`]), checked and turned into the particle lists the body keeps
//! ([`ParticleGroups`]), and the compliance a cluster takes from its particles.

use crate::body::groups::{ExplicitGroup, ParticleGroups};
use crate::config::{Material, Model, ranges};
use crate::ecs::desc::{GroupDesc, Region, StiffnessRegion};
use crate::error::{Result, out_of_range};
use glam::Vec3;

/// The groups and compliances of a body of `material` whose live particles `live` sit
/// at `placed(i)`. Errors name the field (`body.groups[i]…`,
/// `body.stiffness_regions[i]…`): a region that holds none of the body's particles, a
/// compliance out of range, groups on a body of the cluster model.
pub fn select_groups(
    groups: &[GroupDesc],
    regions: &[StiffnessRegion],
    material: &Material,
    live: &[u32],
    placed: impl Fn(u32) -> Vec3,
) -> Result<ParticleGroups> {
    if !groups.is_empty() && material.model != Model::Oriented {
        return Err(out_of_range(
            "body.groups",
            groups.len(),
            "none unless material.model is \"oriented\"",
        ));
    }
    let select = |field: String, region: &Region, compliance: f32| -> Result<Vec<u32>> {
        region.validate(&format!("{field}.region"))?;
        ranges::COMPLIANCE.check(&format!("{field}.compliance"), compliance)?;
        let members: Vec<u32> = live
            .iter()
            .copied()
            .filter(|&i| region.contains(placed(i)))
            .collect();
        if members.is_empty() {
            return Err(out_of_range(
                &format!("{field}.region"),
                (region.min, region.max),
                "a region holding at least one of the body's particles",
            ));
        }
        Ok(members)
    };
    let mut out = ParticleGroups::default();
    for (i, g) in groups.iter().enumerate() {
        let mut members = select(format!("body.groups[{i}]"), &g.region, g.compliance)?;
        members.sort_unstable();
        out.explicit.push(ExplicitGroup {
            members,
            compliance: g.compliance,
        });
    }
    for (i, r) in regions.iter().enumerate() {
        let field = format!("body.stiffness_regions[{i}]");
        let members = select(field, &r.region, r.compliance)?;
        let len = live.iter().max().map_or(0, |m| *m as usize + 1);
        out.compliance.resize(len, f32::NAN);
        for m in members {
            out.compliance[m as usize] = r.compliance;
        }
    }
    Ok(out)
}

/// The compliance `1/κ` (m/N) of a cluster of particles `members` of a body: the
/// material's cluster compliance at the mean of its particles' compliances.
pub fn cluster_compliance(
    material: &Material,
    groups: &ParticleGroups,
    members: &[u32],
    spacing: f32,
) -> f32 {
    let mean = groups.mean_compliance(members, material.compliance);
    material.cluster_compliance_of(mean, spacing)
}
