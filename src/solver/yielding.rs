//! Plastic flow of a rest shape, shared by the cluster term and the oriented groups
//! (material `yield_strain`, `creep`, `max_plastic_strain`): where a shape-matching
//! constraint's deformation passes the yield strain, its rest shape creeps toward the
//! deformed shape, up to the largest plastic strain. Rest shapes here are the
//! constraints' own; the lattice's rest positions, which the reconstruction and the
//! fidelity comparison use, never change.
//!
//! With member `j`'s rest offset `oⱼ` (weighted-centred), its deformation
//! `dⱼ = Rᵀ(xⱼ − c) − oⱼ` in the rest frame of the fitted rigid motion `(R, c)` and its
//! weight `wⱼ`, the strain is `ε = √(Σ wⱼ|dⱼ|² / Σ wⱼ|oⱼ|²)`. Past the yield, each rest
//! offset takes the share `min(creep·dt, 1)·(1 − ε_yield/ε)` of its deformation every
//! substep (so the elastic strain left tends to the yield); the rest shape's own strain
//! from the lattice shape `ℓ`, `√(Σ wⱼ|oⱼ − ℓⱼ|² / Σ wⱼ|ℓⱼ|²)`, is then capped at the
//! maximum.

use crate::config::Yield;
use glam::Vec3A;

/// Lets the rest offsets `offsets` (weighted-centred, as `lattice`, the same members'
/// lattice offsets) flow toward the deformation `deformation` over a substep of `dt`
/// (see the module docs), each member weighted by `weight(j)`. Returns whether the
/// shape yielded; then `offsets` are the new rest offsets, weighted-centred.
pub fn flow(
    yielding: &Yield,
    dt: f32,
    weight: impl Fn(usize) -> f32,
    lattice: &[Vec3A],
    offsets: &mut [Vec3A],
    deformation: &[Vec3A],
) -> bool {
    let (mut deformed, mut spread, mut total) = (0.0f32, 0.0f32, 0.0f32);
    for (j, (o, d)) in offsets.iter().zip(deformation).enumerate() {
        let w = weight(j);
        deformed += w * d.length_squared();
        spread += w * o.length_squared();
        total += w;
    }
    let strain = (deformed / spread).sqrt();
    // (a shape with no extent, or a NaN strain, yields nothing)
    if spread == 0.0 || strain.is_nan() || strain <= yielding.strain {
        return false;
    }
    let take = (yielding.creep * dt).min(1.0) * (1.0 - yielding.strain / strain);
    let mut centre = Vec3A::ZERO;
    for (j, (o, d)) in offsets.iter_mut().zip(deformation).enumerate() {
        *o += *d * take;
        centre += *o * weight(j);
    }
    centre /= total;
    // the rest shape's drift from the lattice's, capped
    let (mut drift, mut base) = (0.0f32, 0.0f32);
    for (j, (o, l)) in offsets.iter().zip(lattice).enumerate() {
        let w = weight(j);
        drift += w * (*o - centre - *l).length_squared();
        base += w * l.length_squared();
    }
    let plastic_strain = (drift / base.max(f32::MIN_POSITIVE)).sqrt();
    let keep = if plastic_strain > yielding.max_strain {
        yielding.max_strain / plastic_strain
    } else {
        1.0
    };
    for (o, l) in offsets.iter_mut().zip(lattice) {
        *o = *l + (*o - centre - *l) * keep;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square's corners, centred.
    fn square() -> Vec<Vec3A> {
        [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
            .map(|(x, y)| Vec3A::new(x, y, 0.0))
            .to_vec()
    }

    /// The deformation of `offsets` stretched along x by the factor `1 + e`.
    fn stretch(offsets: &[Vec3A], e: f32) -> Vec<Vec3A> {
        offsets
            .iter()
            .map(|o| Vec3A::new(o.x * e, 0.0, 0.0))
            .collect()
    }

    const YIELD: Yield = Yield {
        strain: 0.1,
        creep: 1.0,
        max_strain: 0.3,
    };

    #[test]
    fn below_the_yield_nothing_flows() {
        let lattice = square();
        let mut offsets = lattice.clone();
        // strain √(4·0.01 / 8) ≈ 0.07
        let d = stretch(&lattice, 0.1);
        assert!(!flow(&YIELD, 1.0, |_| 1.0, &lattice, &mut offsets, &d));
        assert_eq!(offsets, lattice);
    }

    #[test]
    fn past_the_yield_the_rest_shape_takes_the_excess_and_stays_centred() {
        let lattice = square();
        let mut offsets = lattice.clone();
        // strain √(4·0.09/8) = 0.3/√2 ≈ 0.212: half a second at creep 1 takes half of
        // 1 − 0.1/0.212 of the deformation
        let d = stretch(&lattice, 0.3);
        let strain = (0.09f32 / 2.0).sqrt();
        assert!(flow(&YIELD, 0.5, |_| 1.0, &lattice, &mut offsets, &d));
        let take = 0.5 * (1.0 - 0.1 / strain);
        for ((o, l), d) in offsets.iter().zip(&lattice).zip(&d) {
            assert!(
                (*o - (*l + *d * take)).length() < 1e-6,
                "{o} vs {l} + {take}·{d}"
            );
        }
        let centre: Vec3A = offsets.iter().copied().sum();
        assert!(centre.length() < 1e-6);
    }

    #[test]
    fn the_drift_from_the_lattice_shape_is_capped() {
        let lattice = square();
        let mut offsets = lattice.clone();
        // a huge stretch taken whole: the rest shape would drift by strain ≈ 2
        let d = stretch(&lattice, 3.0);
        assert!(flow(&YIELD, 10.0, |_| 1.0, &lattice, &mut offsets, &d));
        let drift: f32 = offsets
            .iter()
            .zip(&lattice)
            .map(|(o, l)| (*o - *l).length_squared())
            .sum();
        let base: f32 = lattice.iter().map(|l| l.length_squared()).sum();
        assert!(((drift / base).sqrt() - YIELD.max_strain).abs() < 1e-5);
        // along the deformation: only x changed
        assert!(offsets.iter().zip(&lattice).all(|(o, l)| o.y == l.y));
    }

    #[test]
    fn weights_decide_the_strain() {
        let lattice = square();
        // only member 0 deformed, by 0.5 along x: with weight 1 each, strain
        // √(0.25/8) ≈ 0.18 yields; weighted 0.01 against the others' 1 it is below 0.1
        let mut d = vec![Vec3A::ZERO; 4];
        d[0] = Vec3A::new(0.5, 0.0, 0.0);
        let mut offsets = lattice.clone();
        assert!(flow(&YIELD, 1.0, |_| 1.0, &lattice, &mut offsets, &d));
        let mut offsets = lattice.clone();
        let light = |j: usize| if j == 0 { 0.01 } else { 1.0 };
        assert!(!flow(&YIELD, 1.0, light, &lattice, &mut offsets, &d));
    }
}
