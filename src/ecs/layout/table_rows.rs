//! The solver slot of every row of the particles' ECS table, and the row of every slot,
//! so that particle state is copied between the table's columns and the solver's dense
//! arrays in parallel (loaded at the start of a frame, stored after its substeps),
//! without an entity lookup per particle.
//!
//! The map is checked on every load — the table must have the length it had, each
//! mapped slot's entity must still sit at its row, and each row that held no particle of
//! the layout must still hold the same entity, so every row is accounted for — and
//! rebuilt when the table changed: particles despawned by a cut, or entities spawned
//! into the same table.

use crate::ecs::components::{AngularVelocity, InvMass, Orientation, Position, Velocity};
use crate::solver::particles::Particles;
use bevy_ecs::prelude::Entity;
use glam::{Vec3, Vec3A};
use rayon::prelude::*;

/// No row / no slot.
const NONE: u32 = u32::MAX;
/// Particles per parallel task.
const CHUNK: usize = 4096;

/// One ECS table's particle columns, row by row.
#[derive(Clone, Copy)]
pub struct ParticleColumns<'a> {
    /// Entity of each row.
    pub entities: &'a [Entity],
    /// Positions.
    pub positions: &'a [Position],
    /// Velocities.
    pub velocities: &'a [Velocity],
    /// Orientations.
    pub orientations: &'a [Orientation],
    /// Angular velocities.
    pub spins: &'a [AngularVelocity],
    /// Inverse masses.
    pub inv_mass: &'a [InvMass],
}

/// The columns of one ECS table that [`TableRows::store`] writes, row by row.
pub struct StoredColumns<'a> {
    /// Positions.
    pub positions: &'a mut [Position],
    /// Velocities.
    pub velocities: &'a mut [Velocity],
    /// Orientations.
    pub orientations: &'a mut [Orientation],
    /// Angular velocities.
    pub spins: &'a mut [AngularVelocity],
}

/// Rows ↔ solver slots of one particle table (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct TableRows {
    row_of_slot: Vec<u32>,
    slot_of_row: Vec<u32>,
    /// The rows that hold no particle of the layout, and their entities.
    strangers: Vec<(u32, Entity)>,
}

impl TableRows {
    /// Copies the table's particle state (positions, velocities, orientations, angular
    /// velocities, inverse masses) into
    /// `particles`. `slots` is the particle entity of
    /// each solver slot, `slot_of_index` the slot of each entity index (`u32::MAX` for
    /// none). Rows of entities the layout does not hold are skipped; so are slots whose
    /// entity is not in the table (cut particles), which keep their state.
    pub fn load(
        &mut self,
        particles: &mut Particles,
        slots: &[Entity],
        slot_of_index: &[u32],
        table: ParticleColumns,
    ) {
        if !self.try_load(particles, slots, table) {
            self.rebuild(slots, slot_of_index, table.entities);
            let loaded = self.try_load(particles, slots, table);
            debug_assert!(loaded, "a freshly built row map matches its table");
        }
    }

    /// Writes the particles' positions, velocities, orientations and angular velocities
    /// into the table's columns (the rows of the last [`TableRows::load`]).
    pub fn store(&self, particles: &Particles, table: StoredColumns) {
        (
            table.positions.par_chunks_mut(CHUNK),
            table.velocities.par_chunks_mut(CHUNK),
            table.orientations.par_chunks_mut(CHUNK),
            table.spins.par_chunks_mut(CHUNK),
            self.slot_of_row.par_chunks(CHUNK),
        )
            .into_par_iter()
            .for_each(|(x, v, q, w, slots)| {
                if let Some(first) = run_start(slots) {
                    let run = first as usize..first as usize + x.len();
                    let from = (particles.positions.get(run.clone()))
                        .zip(particles.velocities.get(run.clone()))
                        .zip(particles.orientations.get(run.clone()))
                        .zip(particles.spins.get(run));
                    if let Some((((px, pv), pq), pw)) = from {
                        for (x, p) in x.iter_mut().zip(px) {
                            x.0 = Vec3::from(*p);
                        }
                        for (v, p) in v.iter_mut().zip(pv) {
                            v.0 = Vec3::from(*p);
                        }
                        for (q, p) in q.iter_mut().zip(pq) {
                            q.0 = *p;
                        }
                        for (w, p) in w.iter_mut().zip(pw) {
                            w.0 = Vec3::from(*p);
                        }
                        return;
                    }
                }
                for ((((x, v), q), w), &slot) in x.iter_mut().zip(v).zip(q).zip(w).zip(slots) {
                    if slot != NONE {
                        let slot = slot as usize;
                        x.0 = Vec3::from(particles.positions[slot]);
                        v.0 = Vec3::from(particles.velocities[slot]);
                        q.0 = particles.orientations[slot];
                        w.0 = Vec3::from(particles.spins[slot]);
                    }
                }
            });
    }

    /// Loads through the current map; false (with the particles partly loaded) when the
    /// map no longer matches the table.
    fn try_load(
        &self,
        particles: &mut Particles,
        slots: &[Entity],
        table: ParticleColumns,
    ) -> bool {
        if self.slot_of_row.len() != table.entities.len()
            || self.row_of_slot.len() != slots.len()
            || self
                .strangers
                .iter()
                .any(|(row, e)| table.entities.get(*row as usize) != Some(e))
        {
            return false;
        }
        // (zipped to the shortest: every particle array has one entry per slot)
        (
            particles.positions.par_chunks_mut(CHUNK),
            particles.velocities.par_chunks_mut(CHUNK),
            particles.orientations.par_chunks_mut(CHUNK),
            particles.spins.par_chunks_mut(CHUNK),
            particles.inv_mass.par_chunks_mut(CHUNK),
            self.row_of_slot.par_chunks(CHUNK),
            slots.par_chunks(CHUNK),
        )
            .into_par_iter()
            .all(|(x, v, q, w, inv_mass, rows, entities)| {
                if let Some(first) = run_start(rows) {
                    let run = first as usize..first as usize + x.len();
                    return table.entities.get(run.clone()) == Some(entities)
                        && copy_run(&table, run, x, v, q, w, inv_mass);
                }
                let slots = x.iter_mut().zip(v).zip(q).zip(w).zip(inv_mass);
                for (((((x, v), q), w), inv_mass), (&row, entity)) in
                    slots.zip(rows.iter().zip(entities))
                {
                    if row == NONE {
                        continue;
                    }
                    let row = row as usize;
                    if table.entities.get(row) != Some(entity) {
                        return false;
                    }
                    *x = Vec3A::from(table.positions[row].0);
                    *v = Vec3A::from(table.velocities[row].0);
                    *q = table.orientations[row].0;
                    *w = Vec3A::from(table.spins[row].0);
                    *inv_mass = table.inv_mass[row].0;
                }
                true
            })
    }

    /// Maps every row whose entity owns a slot (same index and generation).
    fn rebuild(&mut self, slots: &[Entity], slot_of_index: &[u32], entities: &[Entity]) {
        self.row_of_slot.clear();
        self.row_of_slot.resize(slots.len(), NONE);
        self.slot_of_row.clear();
        self.slot_of_row.resize(entities.len(), NONE);
        self.strangers.clear();
        for (row, entity) in entities.iter().enumerate() {
            let slot = slot_of_index
                .get(entity.index_u32() as usize)
                .copied()
                .unwrap_or(NONE);
            if slots.get(slot as usize) == Some(entity) {
                self.row_of_slot[slot as usize] = row as u32;
                self.slot_of_row[row] = slot;
            } else {
                self.strangers.push((row as u32, *entity));
            }
        }
    }
}

/// The first of `map` when the rest follow on from it one by one (and none is
/// [`NONE`]): a chunk of slots whose rows so follow (a body's particles spawn in the
/// solver's order, so they mostly do) is copied slice to slice.
fn run_start(map: &[u32]) -> Option<u32> {
    let first = *map.first()?;
    let last = first.checked_add(map.len() as u32 - 1)?;
    (last != NONE && (first..).zip(map).all(|(want, &is)| want == is)).then_some(first)
}

/// Copies the particle state of the table's rows `run` into these slots (as many), or
/// false when the table has fewer rows.
fn copy_run(
    table: &ParticleColumns,
    run: std::ops::Range<usize>,
    x: &mut [Vec3A],
    v: &mut [Vec3A],
    q: &mut [glam::Quat],
    w: &mut [Vec3A],
    inv_mass: &mut [f32],
) -> bool {
    let from = (table.positions.get(run.clone()))
        .zip(table.velocities.get(run.clone()))
        .zip(table.orientations.get(run.clone()))
        .zip(table.spins.get(run.clone()))
        .zip(table.inv_mass.get(run));
    let Some(((((tx, tv), tq), tw), tm)) = from else {
        return false;
    };
    for (x, t) in x.iter_mut().zip(tx) {
        *x = Vec3A::from(t.0);
    }
    for (v, t) in v.iter_mut().zip(tv) {
        *v = Vec3A::from(t.0);
    }
    for (q, t) in q.iter_mut().zip(tq) {
        *q = t.0;
    }
    for (w, t) in w.iter_mut().zip(tw) {
        *w = Vec3A::from(t.0);
    }
    for (m, t) in inv_mass.iter_mut().zip(tm) {
        *m = t.0;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy_ecs::world::World;
    use glam::Quat;

    /// Particles of `n` slots and the entity of each slot.
    fn particles_and_slots(world: &mut World, n: usize) -> (Particles, Vec<Entity>, Vec<u32>) {
        let particles = Particles::at_rest(&vec![Vec3::ZERO; n]);
        let slots: Vec<Entity> = (0..n).map(|_| world.spawn_empty().id()).collect();
        let max = slots
            .iter()
            .map(|e| e.index_u32() as usize + 1)
            .max()
            .unwrap_or(0);
        let mut slot_of_index = vec![NONE; max];
        for (s, e) in slots.iter().enumerate() {
            slot_of_index[e.index_u32() as usize] = s as u32;
        }
        (particles, slots, slot_of_index)
    }

    /// Table columns whose values name the entity they belong to (its index).
    struct Columns {
        x: Vec<Position>,
        v: Vec<Velocity>,
        q: Vec<Orientation>,
        w: Vec<AngularVelocity>,
        m: Vec<InvMass>,
    }

    fn columns(rows: &[Entity]) -> Columns {
        let id = |e: &Entity| e.index_u32() as f32;
        Columns {
            x: rows.iter().map(|e| Position(Vec3::splat(id(e)))).collect(),
            v: rows
                .iter()
                .map(|e| Velocity(Vec3::new(id(e), 0.0, -1.0)))
                .collect(),
            q: rows.iter().map(|e| Orientation(turned(id(e)))).collect(),
            w: rows
                .iter()
                .map(|e| AngularVelocity(Vec3::new(0.0, id(e), 1.0)))
                .collect(),
            m: rows.iter().map(|e| InvMass(id(e) + 0.5)).collect(),
        }
    }

    /// The columns of `table` ([`columns`]), edited, after `rows` stored `particles`
    /// into them.
    fn stored(
        rows: &TableRows,
        particles: &Particles,
        table: &[Entity],
        edit: impl FnOnce(&mut Columns),
    ) -> Columns {
        let mut c = columns(table);
        edit(&mut c);
        let stored = StoredColumns {
            positions: &mut c.x,
            velocities: &mut c.v,
            orientations: &mut c.q,
            spins: &mut c.w,
        };
        rows.store(particles, stored);
        c
    }

    fn turned(id: f32) -> Quat {
        Quat::from_rotation_z(id * 1e-3)
    }

    fn load(
        rows: &mut TableRows,
        particles: &mut Particles,
        slots: &[Entity],
        map: &[u32],
        table: &[Entity],
    ) {
        let c = columns(table);
        let columns = ParticleColumns {
            entities: table,
            positions: &c.x,
            velocities: &c.v,
            orientations: &c.q,
            spins: &c.w,
            inv_mass: &c.m,
        };
        rows.load(particles, slots, map, columns);
    }

    /// Every slot holds its own entity's values.
    fn assert_loaded(particles: &Particles, slots: &[Entity]) {
        for (s, e) in slots.iter().enumerate() {
            let id = e.index_u32() as f32;
            assert_eq!(particles.positions[s], Vec3A::splat(id), "slot {s}");
            assert_eq!(particles.velocities[s], Vec3A::new(id, 0.0, -1.0));
            assert_eq!(particles.orientations[s], turned(id));
            assert_eq!(particles.spins[s], Vec3A::new(0.0, id, 1.0));
            assert_eq!(particles.inv_mass[s], id + 0.5);
        }
    }

    #[test]
    fn rows_follow_the_table_through_reorders() {
        let mut world = World::new();
        let n = 3 * CHUNK + 17; // several parallel chunks
        let (mut particles, slots, map) = particles_and_slots(&mut world, n);
        let mut rows = TableRows::default();
        // the table in another order than the slots, with a stranger entity in it
        let stranger = world.spawn_empty().id();
        let mut table: Vec<Entity> = slots.iter().rev().copied().collect();
        table.insert(5, stranger);
        load(&mut rows, &mut particles, &slots, &map, &table);
        assert_loaded(&particles, &slots);
        // a swap-remove (what a despawn does to a table) moves the last row
        table.swap_remove(9);
        let gone = slots.iter().position(|e| !table.contains(e)).unwrap();
        particles.positions[gone] = Vec3A::splat(-7.0);
        load(&mut rows, &mut particles, &slots, &map, &table);
        for (s, e) in slots.iter().enumerate() {
            if s == gone {
                assert_eq!(
                    particles.positions[s],
                    Vec3A::splat(-7.0),
                    "a missing particle keeps its state"
                );
            } else {
                assert_eq!(particles.positions[s], Vec3A::splat(e.index_u32() as f32));
            }
        }
        // rows trading places (same length) are noticed too
        table.swap(0, n / 2);
        load(&mut rows, &mut particles, &slots, &map, &table);
        let Columns { x, .. } = columns(&table);
        for (row, e) in table.iter().enumerate() {
            if let Some(s) = slots.iter().position(|p| p == e) {
                assert_eq!(Vec3::from(particles.positions[s]), x[row].0);
            }
        }
        // store writes every mapped row's position and velocity from its slot, and
        // leaves the stranger alone
        particles.positions.iter_mut().for_each(|p| *p *= 2.0);
        for (s, v) in particles.velocities.iter_mut().enumerate() {
            *v = Vec3A::new(s as f32, 1.0, 0.0);
        }
        for (s, q) in particles.orientations.iter_mut().enumerate() {
            *q = Quat::from_rotation_x(s as f32 * 1e-3);
        }
        let at = table.iter().position(|e| *e == stranger).unwrap();
        let Columns { x, v, q, .. } = stored(&rows, &particles, &table, |c| {
            c.x[at] = Position(Vec3::splat(123.0));
            c.v[at] = Velocity(Vec3::splat(9.0));
        });
        for (row, e) in table.iter().enumerate() {
            let (position, velocity, orientation) = match slots.iter().position(|p| p == e) {
                None => (
                    Vec3::splat(123.0),
                    Vec3::splat(9.0),
                    turned(stranger.index_u32() as f32),
                ),
                Some(s) => {
                    let id = e.index_u32() as f32;
                    (
                        Vec3::splat(2.0 * id),
                        Vec3::new(s as f32, 1.0, 0.0),
                        Quat::from_rotation_x(s as f32 * 1e-3),
                    )
                }
            };
            assert_eq!(
                (x[row].0, v[row].0, q[row].0),
                (position, velocity, orientation),
                "row {row}"
            );
        }
    }

    #[test]
    fn a_table_in_the_slots_order_is_copied_run_by_run_and_a_trade_within_a_run_noticed() {
        let mut world = World::new();
        let n = 2 * CHUNK + 5;
        let (mut particles, slots, map) = particles_and_slots(&mut world, n);
        let mut rows = TableRows::default();
        let mut table = slots.clone();
        load(&mut rows, &mut particles, &slots, &map, &table);
        assert_loaded(&particles, &slots);
        let runs = [Some(0), Some(CHUNK as u32), Some(2 * CHUNK as u32)];
        let in_runs = |map: &[u32]| map.chunks(CHUNK).map(run_start).collect::<Vec<_>>();
        assert_eq!(in_runs(&rows.row_of_slot), runs);
        assert_eq!(in_runs(&rows.slot_of_row), runs);
        // stored run by run: every row from its slot, the slot of the same number
        particles.positions.iter_mut().for_each(|p| *p *= 2.0);
        particles.velocities.iter_mut().for_each(|v| *v *= -1.0);
        particles
            .orientations
            .iter_mut()
            .for_each(|q| *q = q.conjugate());
        particles.spins.iter_mut().for_each(|w| *w *= 3.0);
        let c = stored(&rows, &particles, &table, |_| {});
        for s in 0..n {
            let stored = (c.x[s].0, c.v[s].0, c.q[s].0, c.w[s].0);
            let p = &particles;
            let expected = (
                p.positions[s],
                p.velocities[s],
                p.orientations[s],
                p.spins[s],
            );
            let expected = (
                expected.0.into(),
                expected.1.into(),
                expected.2,
                expected.3.into(),
            );
            assert_eq!(stored, expected, "slot {s}");
        }
        // two rows of the middle run trade places: the run is checked, not trusted
        table.swap(CHUNK + 1, CHUNK + 2);
        load(&mut rows, &mut particles, &slots, &map, &table);
        assert_loaded(&particles, &slots);
        assert_eq!(in_runs(&rows.row_of_slot)[1], None);
    }

    #[test]
    fn a_particle_entering_in_a_strangers_place_is_found() {
        let mut world = World::new();
        let (mut particles, slots, map) = particles_and_slots(&mut world, 3);
        let mut rows = TableRows::default();
        // slot 1's particle is elsewhere (another table) when the map is built
        let stranger = world.spawn_empty().id();
        let table = vec![slots[0], stranger, slots[2]];
        load(&mut rows, &mut particles, &slots, &map, &table);
        particles.positions[1] = Vec3A::splat(-1.0);
        // it comes back where the stranger was: same length, mapped rows unmoved
        let table = vec![slots[0], slots[1], slots[2]];
        load(&mut rows, &mut particles, &slots, &map, &table);
        assert_loaded(&particles, &slots);
    }

    #[test]
    fn a_recycled_entity_index_is_not_taken_for_the_old_particle() {
        let mut world = World::new();
        let (mut particles, slots, map) = particles_and_slots(&mut world, 4);
        let mut rows = TableRows::default();
        load(&mut rows, &mut particles, &slots, &map, &slots);
        assert_loaded(&particles, &slots);
        // slot 2's entity is despawned; a new entity reuses its index
        let old = slots[2];
        let reused =
            Entity::from_index_and_generation(old.index(), old.generation().after_versions(1));
        assert_ne!(reused, old);
        let table = vec![slots[0], slots[1], reused, slots[3]];
        particles.positions[2] = Vec3A::splat(-1.0);
        load(&mut rows, &mut particles, &slots, &map, &table);
        assert_eq!(particles.positions[2], Vec3A::splat(-1.0));
        let mut c = columns(&table);
        let stored = StoredColumns {
            positions: &mut c.x,
            velocities: &mut c.v,
            orientations: &mut c.q,
            spins: &mut c.w,
        };
        rows.store(&particles, stored);
        let x = c.x;
        assert_eq!(
            x[2].0,
            Vec3::splat(reused.index_u32() as f32),
            "not written from slot 2"
        );
    }
}
