//! The term seam with its ECS side: a constraint kind written here that reads a
//! component of its own is added by one call, solved under every scheme, and saved and
//! resumed bit for bit — its state carried through the save by the term itself; and a
//! kind that reads a resource of its own every substep follows it as it changes.

use cleave::bevy_ecs::prelude::*;
use cleave::bevy_ecs::system::SystemParamItem;
use cleave::ecs::ecs_term::{EcsSubstepTerm, EcsTerm};
use cleave::ecs::resources::SimSettings;
use cleave::io::save::LoadedEntities;
use cleave::prelude::*;
use cleave::solver::term::{
    ParticleKey, ParticleState, ProjectiveTerm, Substep, Term, Topology, Unknowns,
};
use cleave::systems::add_ecs_term;
use glam::{DVec3, Vec3A};

/// This file's component: a particle of a body tethered, by a spring of `compliance`
/// (m/N; 0: hard), to the place it was at when the tether first acted on it.
#[derive(Component, Clone, Copy)]
struct Tethered {
    body: Entity,
    particle: u32,
    compliance: f32,
}

/// The kind that solves [`Tethered`]. Its anchors are state of its own, carried from
/// frame to frame and saved through the term.
#[derive(Default)]
struct Tethers {
    /// Each tether, in entity order: its particle and compliance.
    list: Vec<(ParticleKey, f32)>,
    /// Each tether's dense particle, when in the layout.
    dense: Vec<Option<u32>>,
    /// Where each tether's particle was when the tether first acted on it.
    anchors: Vec<Option<Vec3A>>,
    /// Anchors by dense particle, from a save, taken up at the next topology change.
    resumed: Option<Vec<(u32, Vec3A)>>,
    lambda: Vec<Vec3A>,
    version: u64,
}

impl Tethers {
    /// The tethers in the layout and anchored: dense particle, anchor, compliance, index.
    fn held(&self) -> impl Iterator<Item = (usize, Vec3A, f32, usize)> + '_ {
        let each = self.list.iter().zip(&self.dense).zip(&self.anchors);
        each.enumerate()
            .filter_map(|(k, (((_, c), d), a))| Some((d.map(|d| d as usize)?, (*a)?, *c, k)))
    }
}

impl EcsTerm for Tethers {
    type Data = Query<'static, 'static, (Entity, &'static Tethered)>;

    /// Takes the tethers; one kept from the last frame keeps its anchor.
    fn sync(&mut self, tethers: SystemParamItem<Self::Data>) -> bool {
        let mut found: Vec<(Entity, &Tethered)> = tethers.iter().collect();
        found.sort_unstable_by_key(|(e, _)| *e);
        let list: Vec<(ParticleKey, f32)> = found
            .iter()
            .map(|(_, t)| {
                let key = ParticleKey {
                    body: t.body.to_bits(),
                    local: t.particle,
                };
                (key, t.compliance)
            })
            .collect();
        if list == self.list {
            return false;
        }
        self.anchors = (list.iter())
            .map(|(key, _)| {
                let kept = self.list.iter().position(|(k, _)| k == key);
                kept.and_then(|j| self.anchors[j])
            })
            .collect();
        self.list = list;
        true
    }
}

impl Term for Tethers {
    fn name(&self) -> &'static str {
        "tethers"
    }

    fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    fn topology(&mut self, change: &Topology) {
        self.dense = self
            .list
            .iter()
            .map(|(key, _)| change.dense(*key))
            .collect();
        self.lambda = vec![Vec3A::ZERO; self.list.len()];
        if let Some(resumed) = self.resumed.take() {
            for (d, anchor) in self.dense.iter().zip(&mut self.anchors) {
                if let Some((_, at)) = resumed.iter().find(|(r, _)| Some(*r) == *d) {
                    *anchor = Some(*at);
                }
            }
        }
        self.version += 1;
    }

    fn begin_substep(&mut self, _step: &Substep, state: &mut ParticleState) {
        for (d, anchor) in self.dense.iter().zip(&mut self.anchors) {
            if let (Some(d), None) = (d, &anchor) {
                *anchor = Some(state.positions[*d as usize]);
                // (one more spring in the projective matrix)
                self.version += 1;
            }
        }
        self.lambda.iter_mut().for_each(|l| *l = Vec3A::ZERO);
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        let held: Vec<_> = self.held().collect();
        for (i, anchor, compliance, k) in held {
            let (w, alpha) = (state.inv_mass[i], step.scaled(compliance));
            if w + alpha == 0.0 {
                continue;
            }
            let delta = (anchor - state.positions[i] - self.lambda[k] * alpha) / (w + alpha);
            self.lambda[k] += delta;
            state.shift(i, delta * w);
        }
    }

    fn projective(&self) -> Option<&dyn ProjectiveTerm> {
        Some(self)
    }

    /// The anchors by dense particle (a loaded simulation lays its particles out as
    /// they were saved).
    fn saved_state(&self) -> Option<Vec<u8>> {
        let mut out = Vec::new();
        for (i, anchor, ..) in self.held() {
            out.extend((i as u32).to_le_bytes());
            anchor
                .to_array()
                .iter()
                .for_each(|x| out.extend(x.to_le_bytes()));
        }
        Some(out)
    }

    fn resume_state(&mut self, state: &[u8]) -> Result<(), String> {
        const RECORD: usize = 4 + 12;
        if !state.len().is_multiple_of(RECORD) {
            return Err(format!("{} bytes are not whole anchors", state.len()));
        }
        let word = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
        let anchors = state.chunks(RECORD).map(|r| {
            let at = [4, 8, 12].map(|o| f32::from_bits(word(&r[o..o + 4])));
            (word(&r[..4]), Vec3A::from(at))
        });
        self.resumed = Some(anchors.collect());
        Ok(())
    }
}

impl ProjectiveTerm for Tethers {
    fn version(&self) -> u64 {
        self.version
    }

    fn add_hessian(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        entries: &mut Vec<(usize, usize, f64)>,
    ) {
        for (i, _, compliance, _) in self.held() {
            if let Some(row) = unknowns.row(i as u32) {
                let w = unknowns.weight(compliance, &[i as u32], step.dt);
                entries.push((row, row, w));
            }
        }
    }

    fn add_forces(
        &self,
        step: &Substep,
        unknowns: &Unknowns,
        positions: &[Vec3A],
        _orientations: &mut [cleave::glam::Quat],
        forces: &mut [DVec3],
    ) {
        for (i, anchor, compliance, _) in self.held() {
            let w = unknowns.weight(compliance, &[i as u32], step.dt);
            forces[i] += (anchor - positions[i]).as_dvec3() * w;
        }
    }
}

/// A 6×3×3 block in the air (no ground) and its two top particles at its −x end.
fn hung_block(solver: SolverMode) -> (Simulation, Entity, [u32; 2]) {
    let config = SimConfig {
        ground: None,
        solver,
        ..SimConfig::default()
    };
    let mut sim = Simulation::new(config).expect("a simulation");
    let mut desc = BodyDesc::new(Shape::cuboid(UVec3::new(6, 3, 3)), 0.1);
    desc.position = Vec3::new(0.0, 1.0, 0.0);
    let body = sim.spawn_body(&desc).expect("a block");
    let mut top: Vec<(u32, Vec3)> = sim.positions(body).expect("a body");
    // the −x end's top edge: least x, then greatest y, then z
    top.sort_by(|a, b| {
        (a.1.x, -a.1.y, a.1.z)
            .partial_cmp(&(b.1.x, -b.1.y, b.1.z))
            .expect("finite")
    });
    (sim, body, [top[0].0, top[top.len().min(3) - 1].0])
}

fn tether(world: &mut World, body: Entity, particles: [u32; 2]) {
    for particle in particles {
        world.spawn(Tethered {
            body,
            particle,
            compliance: 0.0,
        });
    }
}

fn position(sim: &Simulation, body: Entity, p: u32) -> Vec3 {
    let positions = sim.positions(body).expect("a body");
    positions.iter().find(|(q, _)| *q == p).expect("live").1
}

fn lowest(sim: &Simulation, body: Entity) -> f32 {
    let positions = sim.positions(body).expect("a body");
    positions
        .iter()
        .map(|(_, x)| x.y)
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn a_term_reading_its_own_component_is_solved_under_every_scheme_and_resumes_bit_for_bit() {
    for solver in SolverMode::ALL {
        let (mut sim, body, ends) = hung_block(solver);
        sim.add_ecs_term(Tethers::default());
        // falling freely for 10 frames, then tethered where the two particles are then
        let start = position(&sim, body, ends[0]);
        sim.run(10);
        let held_at = ends.map(|p| position(&sim, body, p));
        let fallen = start.y - held_at[0].y;
        assert!(fallen > 0.1, "{solver}: it fell first ({fallen} m)");
        tether(sim.world_mut(), body, ends);
        sim.run(20);
        let mut saved = Vec::new();
        sim.save(&mut saved).expect("saved");
        sim.run(20);
        // held where they were when tethered (hard springs), the body hanging from them
        for (p, at) in ends.iter().zip(held_at) {
            let now = position(&sim, body, *p);
            assert!(
                now.distance(at) < 0.02,
                "{solver}: particle {p} at {now}, tethered at {at}"
            );
        }
        let hanging = lowest(&sim, body);
        assert!(
            hanging > held_at[0].y - 1.0,
            "{solver}: it hangs ({hanging})"
        );
        // without the tethers it falls on: after 50 frames, more than a metre more
        let (mut free, free_body, _) = hung_block(solver);
        free.run(50);
        let free_lowest = lowest(&free, free_body);
        assert!(
            free_lowest < hanging - 1.0,
            "{solver}: free {free_lowest}, held {hanging}"
        );

        // resumed: the term added again while loading, its component given back
        let mut resumed = Simulation::load_with(&saved[..], |world| {
            let loaded = world.resource::<LoadedEntities>().get(body)?;
            tether(world, loaded, ends);
            add_ecs_term(world, Tethers::default());
            Ok(())
        })
        .expect("loaded");
        resumed.run(20);
        let loaded = resumed.loaded_entity(body).expect("the body");
        assert_eq!(
            resumed.positions(loaded).expect("a body"),
            sim.positions(body).expect("a body"),
            "{solver}: resumed bit for bit"
        );
        // the anchors are the term's own state: a save whose term is not registered
        // when loading is refused by name
        let refused = Simulation::load(&saved[..]).map(|_| ());
        let message = refused.expect_err("no term takes the anchors").to_string();
        assert!(message.contains("tethers"), "{solver}: {message}");
    }
}

/// This file's resource: a steady wind, as a velocity.
#[derive(Resource, Clone, Copy)]
struct Wind(Vec3);

/// A kind that reads [`Wind`] every substep and carries every free particle with it:
/// each is held where the wind takes it from its substep-start position.
#[derive(Default)]
struct Drift {
    step: Vec3A,
}

impl EcsSubstepTerm for Drift {
    type SubstepData = Option<Res<'static, Wind>>;

    fn substep(&mut self, wind: SystemParamItem<Self::SubstepData>) {
        self.step = Vec3A::from(wind.map_or(Vec3::ZERO, |w| w.0));
    }
}

impl Term for Drift {
    fn name(&self) -> &'static str {
        "drift"
    }

    fn is_empty(&self) -> bool {
        self.step == Vec3A::ZERO
    }

    fn project(&mut self, step: &Substep, state: &mut ParticleState) {
        for i in 0..state.positions.len() {
            if state.inv_mass[i] > 0.0 {
                let target = state.previous[i] + self.step * step.dt;
                state.shift(i, target - state.positions[i]);
            }
        }
    }
}

#[test]
fn a_term_reading_the_ecs_every_substep_follows_it_as_it_changes() {
    let (mut sim, body, _) = hung_block(SolverMode::Jacobi);
    sim.world_mut().resource_mut::<SimSettings>().0.gravity = Vec3::ZERO;
    sim.add_ecs_substep_term(Drift::default());
    let centre = |sim: &Simulation| {
        let positions = sim.positions(body).expect("a body");
        positions.iter().map(|(_, x)| *x).sum::<Vec3>() / positions.len() as f32
    };
    let start = centre(&sim);
    // no wind: the block stays; a wind of 1.5 m/s along x for 60 frames (1 s) carries it
    // 1.5 m; turned to z, it goes on along z
    sim.run(10);
    assert!(centre(&sim).distance(start) < 1e-4, "no wind, no drift");
    sim.world_mut()
        .insert_resource(Wind(Vec3::new(1.5, 0.0, 0.0)));
    sim.run(60);
    let moved = centre(&sim) - start;
    assert!(
        (moved.x - 1.5).abs() < 0.02 && moved.z.abs() < 1e-3,
        "{moved}"
    );
    sim.world_mut()
        .insert_resource(Wind(Vec3::new(0.0, 0.0, 1.5)));
    sim.run(60);
    let moved = centre(&sim) - start;
    assert!(
        (moved.x - 1.5).abs() < 0.05 && (moved.z - 1.5).abs() < 0.02,
        "{moved}"
    );
}
