//! Anisotropic patch constraints (SPEC §6.1, Yuksel et al. 2012, eq. 6–7): around every
//! surface particle, the tent-weighted mean displacement `v` of its surface patch
//! ([`crate::body::patches`]) is held stiffly along the patch's rest normal and softly
//! across it, so a surface keeps its place while it may slide along itself.
//!
//! ## Displacement in the patch's own frame
//!
//! The displacement is measured from where the rest shape would put the patch if it
//! moved as its surroundings do: the frame set (the particles around the patch, mostly
//! the body beneath it) is fitted rigidly, as a cluster's shape matching fits
//! its members — centroid `c`, rotation `R` from the polar decomposition of
//! `Σ (xᵢ − c)(x̄ᵢ − c̄)ᵀ` — and member `j`'s goal is `gⱼ = c + R (x̄ⱼ − c̄)`. Then
//! `v = Σⱼ ŵⱼ (xⱼ − gⱼ)` (weights `ŵ` normalised to sum 1: the energy is normalised by
//! the weight sum) and the normal is `n = R n̄`. A body that moves or turns as a whole
//! leaves every `v` zero: the term keeps shape without pinning the body in space.
//!
//! ## Projection
//!
//! Two constraints per patch, `C_N = n·v` and `C_T = (I − nnᵀ) v`, projected XPBD-style
//! with the frame held (a lagged fit, taken again before every projection) and their
//! `λ` accumulated over the substep. `∇ₓⱼ v = ŵⱼ I`, so both share the generalised
//! inverse mass `G = Σ ŵⱼ² wⱼ` and each moves member `j` by `wⱼ ŵⱼ Δλ`. Compliances:
//! `α_T = patch_tangent_compliance / h` and `α_N = patch_normal_compliance / h`, the
//! latter divided by `(|C_N|/τ)²` once `|C_N|` passes the threshold `τ =
//! patch_threshold · h` — the normal stiffness grows with the square of the excess.
//! Patches overlap, so they are projected one after another in a fixed order
//! (Gauss–Seidel, deterministic for any thread count). No projective-dynamics form
//! (the frames change every iteration): projective dynamics projects the patches after
//! its global step.

use crate::body::patches::surface_patches;
use crate::math::rotation::extract_rotation;
use crate::solver::term::{BodyTopology, NO_DENSE, ParticleState, Substep, Term, Topology};
use glam::{Mat3A, Quat, Vec3A};

/// Iterations of the rotation fit per projection, warm-started from the last fit; the
/// first fit after the patches are found starts from no turn and may need many.
const FIT_ITERATIONS: u32 = 4;
const FIRST_FIT_ITERATIONS: u32 = 40;

/// One patch in the layout: ranges into its body's member and frame arrays.
#[derive(Clone, Debug)]
struct Patch {
    members: std::ops::Range<u32>,
    frame: std::ops::Range<u32>,
    /// The rest normal (lattice frame).
    normal: Vec3A,
    /// The frame set's rest centroid.
    rest_centre: Vec3A,
}

/// One body's patches with their compliances (m/N) and threshold (m).
#[derive(Clone, Debug, Default)]
struct BodyPatches {
    id: u64,
    normal_compliance: f32,
    tangent_compliance: f32,
    threshold: f32,
    patches: Vec<Patch>,
    /// Members: dense index, normalised tent weight, rest position.
    members: Vec<(u32, f32, Vec3A)>,
    /// Frame sets: dense index, rest offset from the set's rest centroid.
    frame: Vec<(u32, Vec3A)>,
    /// Each patch's last fitted rotation (the next fit's warm start).
    rotations: Vec<Quat>,
    /// Whether the rotations have been fitted since the patches were found.
    fitted: bool,
    /// Each patch's accumulated normal and tangential `λ` in this substep.
    lambda: Vec<(f32, Vec3A)>,
}

/// The patch term; see the module docs.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    /// By body id; bodies without patch constraints are absent.
    bodies: Vec<BodyPatches>,
    /// A saved state to take up at the next topology change.
    resumed: Option<SavedPatches>,
}

/// What a saved simulation keeps of the term: each body's last fitted rotations, the
/// fits' warm start (everything else is found again on the lattices). Without them a
/// loaded run would fit from no turn and part from the run that went on.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
struct SavedPatches {
    /// Body after body: whether its patches were fitted, and each patch's rotation.
    bodies: Vec<(bool, Vec<Quat>)>,
}

impl Patches {
    /// Number of patches in the layout.
    pub fn len(&self) -> usize {
        self.bodies.iter().map(|b| b.patches.len()).sum()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The patches of one body, or `None` when its material holds none.
fn body_patches(body: &BodyTopology) -> Option<BodyPatches> {
    let material = body.material;
    let (normal, tangent) = material.patch_compliances()?;
    let h = body.lattice.spacing();
    let mut out = BodyPatches {
        id: body.id,
        normal_compliance: normal / h,
        tangent_compliance: tangent / h,
        threshold: material.patch_threshold * h,
        ..Default::default()
    };
    let dense = |p: u32| {
        body.dense
            .get(p as usize)
            .copied()
            .filter(|d| *d != NO_DENSE)
    };
    let rest = |p: u32| Vec3A::from(body.lattice.rest_position(p));
    for patch in surface_patches(body.lattice, material.patch_rings) {
        let frame: Vec<(u32, Vec3A)> = patch
            .frame
            .iter()
            .filter_map(|&p| Some((dense(p)?, rest(p))))
            .collect();
        let members: Vec<(u32, f32, Vec3A)> = patch
            .members
            .iter()
            .filter_map(|&(p, w)| Some((dense(p)?, w, rest(p))))
            .collect();
        // fewer than four points may lie in a line, and leave the fit's turn undetermined
        if frame.len() < 4 || members.len() != patch.members.len() {
            continue;
        }
        let rest_centre = frame.iter().map(|f| f.1).sum::<Vec3A>() / frame.len() as f32;
        let start = (out.members.len() as u32, out.frame.len() as u32);
        out.members.extend(members);
        out.frame
            .extend(frame.into_iter().map(|(d, x)| (d, x - rest_centre)));
        out.patches.push(Patch {
            members: start.0..out.members.len() as u32,
            frame: start.1..out.frame.len() as u32,
            normal: Vec3A::from(patch.normal),
            rest_centre,
        });
    }
    out.rotations = vec![Quat::IDENTITY; out.patches.len()];
    out.lambda = vec![(0.0, Vec3A::ZERO); out.patches.len()];
    Some(out)
}

impl BodyPatches {
    /// Projects patch `k` once (see the module docs).
    fn project(&mut self, k: usize, step: &Substep, state: &mut ParticleState) {
        let patch = &self.patches[k];
        let frame = &self.frame[patch.frame.start as usize..patch.frame.end as usize];
        let members = &self.members[patch.members.start as usize..patch.members.end as usize];
        let generalised: f32 = members
            .iter()
            .map(|&(d, w, _)| w * w * state.inv_mass[d as usize])
            .sum();
        if generalised == 0.0 {
            return;
        }
        let centre = frame
            .iter()
            .map(|&(d, _)| state.positions[d as usize])
            .sum::<Vec3A>()
            / frame.len() as f32;
        let mut moment = Mat3A::ZERO;
        for &(d, q) in frame {
            let p = state.positions[d as usize] - centre;
            moment += Mat3A::from_cols(p * q.x, p * q.y, p * q.z);
        }
        let iterations = if self.fitted {
            FIT_ITERATIONS
        } else {
            FIRST_FIT_ITERATIONS
        };
        let rotation = extract_rotation(moment, self.rotations[k], iterations);
        self.rotations[k] = rotation;
        let displacement: Vec3A = members
            .iter()
            .map(|&(d, w, rest)| {
                let goal = centre + rotation * (rest - patch.rest_centre);
                (state.positions[d as usize] - goal) * w
            })
            .sum();
        if !displacement.is_finite() {
            return;
        }
        let normal = rotation * patch.normal;
        let c_normal = normal.dot(displacement);
        let c_tangent = displacement - normal * c_normal;
        let stiffening = (c_normal.abs() / self.threshold).max(1.0);
        let alpha_normal = step.scaled(self.normal_compliance) / (stiffening * stiffening);
        let alpha_tangent = step.scaled(self.tangent_compliance);
        let (lambda_normal, lambda_tangent) = &mut self.lambda[k];
        let delta_normal =
            (-c_normal - alpha_normal * *lambda_normal) / (generalised + alpha_normal);
        let delta_tangent =
            (-c_tangent - *lambda_tangent * alpha_tangent) / (generalised + alpha_tangent);
        *lambda_normal += delta_normal;
        *lambda_tangent += delta_tangent;
        let step = normal * delta_normal + delta_tangent;
        for &(d, w, _) in members {
            let inv_mass = state.inv_mass[d as usize];
            state.shift(d as usize, step * (w * inv_mass));
        }
    }
}

impl Term for Patches {
    fn name(&self) -> &'static str {
        "patches"
    }

    fn is_empty(&self) -> bool {
        Patches::is_empty(self)
    }

    fn saved_state(&self) -> Option<Vec<u8>> {
        let saved = SavedPatches {
            bodies: self
                .bodies
                .iter()
                .map(|b| (b.fitted, b.rotations.clone()))
                .collect(),
        };
        postcard::to_stdvec(&saved).ok()
    }

    /// (a loaded simulation's first topology change finds the same patches on the same
    /// lattices; a body whose count differs, which only a damaged file gives, starts
    /// unfitted)
    fn resume_state(&mut self, state: &[u8]) -> Result<(), String> {
        self.resumed = Some(postcard::from_bytes(state).map_err(|e| e.to_string())?);
        Ok(())
    }

    /// Finds the patches of every body that changed (all, after a rebuild) on its
    /// lattice again; forgets the bodies that are gone.
    fn topology(&mut self, change: &Topology) {
        let kept = std::mem::take(&mut self.bodies);
        self.bodies = change.rebuild_bodies(kept, |b| b.id, body_patches);
        let saved = self.resumed.take().unwrap_or_default();
        for (body, (fitted, rotations)) in self.bodies.iter_mut().zip(saved.bodies) {
            let fits = rotations.len() == body.rotations.len()
                && rotations.iter().all(|q| q.is_finite() && q.is_normalized());
            if fits {
                (body.fitted, body.rotations) = (fitted, rotations);
            }
        }
    }

    fn begin_substep(&mut self, _step: &Substep, _state: &mut ParticleState) {
        for body in &mut self.bodies {
            body.lambda.iter_mut().for_each(|l| *l = (0.0, Vec3A::ZERO));
        }
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        for body in &mut self.bodies {
            for k in 0..body.patches.len() {
                body.project(k, step, state);
            }
            body.fitted = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::lattice::Lattice;
    use crate::config::Material;
    use glam::{IVec3, Vec3};

    const H: f32 = 0.1;

    /// A 9×9×5 block at spacing `H` whose material holds patches as given, its term,
    /// its rest positions and the middle of its top face.
    fn block(material: &Material) -> (Patches, Vec<Vec3A>, u32) {
        let coords = (0..5)
            .flat_map(|z| (0..9).flat_map(move |y| (0..9).map(move |x| IVec3::new(x, y, z))))
            .collect();
        let lattice = Lattice::from_coords(H, coords).expect("a block");
        let dense: Vec<u32> = (0..lattice.len() as u32).collect();
        let body = BodyTopology {
            id: 1,
            lattice: &lattice,
            dense: &dense,
            material,
            groups: &Default::default(),
            pieces: 1,
            changed: true,
        };
        let mut term = Patches::default();
        term.topology(&Topology {
            bodies: &[body],
            relaid: true,
        });
        let rest = (0..lattice.len() as u32)
            .map(|i| Vec3A::from(lattice.rest_position(i)))
            .collect();
        (term, rest, lattice.at(IVec3::new(4, 4, 4)).expect("top"))
    }

    /// Projects `term` once on `positions` (a substep of 1/120 s, particles of 1.1 kg);
    /// returns the corrections.
    fn project_once(term: &mut Patches, positions: &mut [Vec3A]) -> Vec<Vec3A> {
        let previous = positions.to_vec();
        let inv_mass = vec![1.0 / 1.1; positions.len()];
        let mut corrections = vec![Vec3A::ZERO; positions.len()];
        let step = Substep {
            dt: 1.0 / 120.0,
            iterations: 1,
            frame_span: [0.0, 0.5],
        };
        let mut state = ParticleState {
            positions,
            previous: &previous,
            inv_mass: &inv_mass,
            corrections: &mut corrections,
            orientations: &mut vec![glam::Quat::IDENTITY; previous.len()],
            spins: &vec![Vec3A::ZERO; previous.len()],
        };
        term.begin_substep(&step, &mut state);
        term.project(&step, &mut state);
        corrections
    }

    fn holding(normal: f32) -> Material {
        Material {
            patch_normal_compliance: Some(normal),
            ..Material::default()
        }
    }

    /// The restoring correction of `centre` per unit displacement when the members of
    /// its patch are moved by `offset`.
    fn restoring(material: &Material, offset: Vec3) -> f32 {
        let (mut term, mut positions, centre) = block(material);
        let body = &term.bodies[0];
        let patch = body
            .patches
            .iter()
            .find(|p| body.members[p.members.start as usize].0 == centre)
            .expect("the centre's patch");
        for &(d, ..) in &body.members[patch.members.start as usize..patch.members.end as usize] {
            positions[d as usize] += Vec3A::from(offset);
        }
        let corrections = project_once(&mut term, &mut positions);
        -corrections[centre as usize].dot(Vec3A::from(offset)) / offset.length_squared()
    }

    #[test]
    fn a_body_moved_and_turned_whole_is_left_alone() {
        let (mut term, rest, _) = block(&holding(1e-6));
        assert!(term.len() > 200);
        let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 0.7);
        let mut moved: Vec<Vec3A> = rest
            .iter()
            .map(|x| turn * *x + Vec3A::new(3.0, -1.0, 2.0))
            .collect();
        let corrections = project_once(&mut term, &mut moved);
        let largest = corrections.iter().map(|c| c.length()).fold(0.0, f32::max);
        // f32 rounding of positions 3 m from the origin
        assert!(largest < 1e-4 * H, "{largest}");
        // and without patch compliance the material holds none
        assert!(block(&Material::default()).0.is_empty());
    }

    #[test]
    fn the_normal_resists_ten_times_more_than_the_tangent_and_stiffens_past_the_threshold() {
        let material = holding(1e-6);
        let small = 0.02 * H;
        let normal = restoring(&material, Vec3::new(0.0, 0.0, -small));
        let tangent = restoring(&material, Vec3::new(small, 0.0, 0.0));
        assert!(normal > 0.0 && tangent > 0.0, "{normal} {tangent}");
        eprintln!("restoring correction per unit displacement: normal {normal}, tangent {tangent}");
        assert!(
            normal >= 10.0 * tangent,
            "normal {normal}, tangent {tangent}"
        );
        // the threshold is 0.1 h: at 0.5 h in, a soft surface is several times stiffer
        let soft = holding(1e-4);
        let shallow = restoring(&soft, Vec3::new(0.0, 0.0, -small));
        let deep = restoring(&soft, Vec3::new(0.0, 0.0, -0.5 * H));
        eprintln!("soft normal: {deep} per unit at 0.5 h deep, {shallow} at 0.02 h");
        assert!(deep > 5.0 * shallow, "{deep} against {shallow}");
    }
}
