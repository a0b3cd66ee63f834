//! The cells the contact search of [`super::contact_pairs`] and [`super::contact_list`]
//! walks: contact particles sorted by the cell their point lies in, and the occupied
//! cells, each marked with the one group its particles share when no two of them can
//! pair.
//!
//! **Sorted cells.** Each particle gets the key of its cell (cubes of one side, the key
//! linear in the cell coordinates, x fastest) and the particles are sorted by key, so
//! the cells around a cell are runs of consecutive keys: nine rows of three cells, or,
//! to meet each pair of cells once, its forward half (x + 1 in its own row, three cells
//! in each of the four rows after it). Cells visited in key order find those runs with
//! one cursor per run that only moves forward: no hashing, no search, cost linear in
//! particles.
//!
//! **Cells that cannot pair.** Most particles of a contact search sit among particles
//! of their own piece, and a piece without self-contact never pairs with itself. A
//! particle's *kin* is its group when that group has no self-contact, else [`NO_KIN`];
//! a cell's kin is the kin all its particles share, else [`NO_KIN`]. A particle and a
//! cell of its own kin, or two cells of one kin, hold no pair, and are passed over
//! without reading a particle: inside a body the search costs per cell, not per pair of
//! particles. Which pairs are found does not change, only which are never looked at.

use crate::util::radix::sort_by_key_radix;
use glam::Vec3A;
use rayon::prelude::*;
use std::ops::Range;

/// Offset that makes cell coordinates non-negative in a key (21 bits per axis).
const CELL_BIAS: i64 = 1 << 20;

/// The kin of a particle whose group has self-contact, and of a cell whose particles do
/// not all share one kin: it may pair with anything.
pub(super) const NO_KIN: u32 = u32::MAX;

/// One occupied cell.
#[derive(Clone, Copy, Debug)]
struct Cell {
    /// Its key.
    key: u64,
    /// Its first entry in the sorted particles.
    start: u32,
    /// The kin its particles share, or [`NO_KIN`].
    kin: u32,
}

/// Contact particles sorted by the cell their point lies in, and the occupied cells.
#[derive(Clone, Debug, Default)]
pub(super) struct CellGrid {
    inv_cell: f32,
    /// `(cell key, particle)`, ascending; particles at non-finite points are left out.
    sorted: Vec<(u64, u32)>,
    /// Each particle's kin (by contact index).
    kin: Vec<u32>,
    /// The occupied cells, ascending by key.
    cells: Vec<Cell>,
}

impl CellGrid {
    /// The particles at `points` (by index), of kin `kin`, in cells of side `cell`.
    pub(super) fn new(points: &[Vec3A], kin: Vec<u32>, cell: f32) -> Self {
        let mut grid = Self {
            inv_cell: 1.0 / cell,
            kin,
            ..Self::default()
        };
        grid.sorted = points
            .par_iter()
            .enumerate()
            .map(|(k, x)| (grid.key(*x), k as u32))
            .filter(|(key, _)| *key != u64::MAX)
            .collect();
        // in particle order, so a stable sort by cell leaves each cell's particles
        // ascending
        sort_by_key_radix(&mut grid.sorted);
        grid.index_cells();
        grid
    }

    /// The key of the cell `x` lies in (`u64::MAX` for a non-finite `x`).
    fn key(&self, x: Vec3A) -> u64 {
        if !x.is_finite() {
            return u64::MAX;
        }
        let c = (x * self.inv_cell).floor();
        let axis = |v: f32| (v as i64 + CELL_BIAS).clamp(1, 2 * CELL_BIAS - 2) as u64;
        axis(c.x) | axis(c.y) << 21 | axis(c.z) << 42
    }

    /// Lists the occupied cells of the sorted particles, with their kin.
    fn index_cells(&mut self) {
        self.cells.clear();
        for (entry, &(key, k)) in self.sorted.iter().enumerate() {
            let kin = self.kin[k as usize];
            match self.cells.last_mut() {
                Some(cell) if cell.key == key => {
                    if cell.kin != kin {
                        cell.kin = NO_KIN;
                    }
                }
                _ => self.cells.push(Cell {
                    key,
                    start: entry as u32,
                    kin,
                }),
            }
        }
    }

    /// The sorted particles, `(cell key, particle)`.
    pub(super) fn sorted(&self) -> &[(u64, u32)] {
        &self.sorted
    }

    /// The entries of cell `c` in the sorted particles.
    fn entries(&self, c: usize) -> Range<usize> {
        let end = self
            .cells
            .get(c + 1)
            .map_or(self.sorted.len(), |next| next.start as usize);
        self.cells[c].start as usize..end
    }

    /// Moves the particles flagged in `moved` to the cells of their `points` now, and
    /// returns their entries in cell order.
    pub(super) fn update(
        &mut self,
        moved: &[u32],
        flagged: &[bool],
        points: &[Vec3A],
    ) -> Vec<(u64, u32)> {
        let mut fresh: Vec<(u64, u32)> = moved
            .iter()
            .map(|&k| (self.key(points[k as usize]), k))
            .filter(|(key, _)| *key != u64::MAX)
            .collect();
        fresh.sort_unstable();
        let kept = self.sorted.iter().filter(|(_, k)| !flagged[*k as usize]);
        let mut merged = Vec::with_capacity(self.sorted.len());
        let mut next = fresh.iter().copied().peekable();
        for entry in kept {
            while let Some(f) = next.next_if(|f| f < entry) {
                merged.push(f);
            }
            merged.push(*entry);
        }
        merged.extend(next);
        self.sorted = merged;
        self.index_cells();
        fresh
    }

    /// Calls `f(k, j)` for each entry `(key, k)` of `entries` (in cell order, as
    /// [`Self::update`] returns them) and every particle `j` in the cell `key` and its
    /// 26 neighbours, except those of `k`'s own kin. The nine rows of three cells
    /// around consecutive entries start at keys that only grow, so each row is followed
    /// by one cursor that only moves forward: no search per entry.
    pub(super) fn around_each(&self, entries: &[(u64, u32)], mut f: impl FnMut(u32, u32)) {
        let Some(&(first, _)) = entries.first() else {
            return;
        };
        let rows: [i64; 9] = std::array::from_fn(|r| {
            let (dy, dz) = (r as i64 % 3 - 1, r as i64 / 3 - 1);
            (dy << 21) + (dz << 42) - 1
        });
        let cells = &self.cells;
        let mut cursors =
            rows.map(|row| cells.partition_point(|c| c.key < (first as i64 + row) as u64));
        for &(key, k) in entries {
            let kin = self.kin[k as usize];
            for (cursor, row) in cursors.iter_mut().zip(rows) {
                let lo = (key as i64 + row) as u64;
                while *cursor < cells.len() && cells[*cursor].key < lo {
                    *cursor += 1;
                }
                let mut c = *cursor;
                while c < cells.len() && cells[c].key <= lo + 2 {
                    if kin == NO_KIN {
                        for &(_, j) in &self.sorted[self.entries(c)] {
                            f(k, j);
                        }
                    } else if cells[c].kin != kin {
                        for &(_, j) in &self.sorted[self.entries(c)] {
                            if self.kin[j as usize] != kin {
                                f(k, j);
                            }
                        }
                    }
                    c += 1;
                }
            }
        }
    }

    /// Splits the cells into runs of consecutive cells holding about `per_task`
    /// particles each: the boundaries, as cell indices from 0 to the number of cells.
    pub(super) fn tasks(&self, per_task: usize) -> Vec<usize> {
        let mut starts = vec![0];
        let mut next = per_task;
        for (c, cell) in self.cells.iter().enumerate() {
            if cell.start as usize >= next {
                starts.push(c);
                next = cell.start as usize + per_task;
            }
        }
        starts.push(self.cells.len());
        starts
    }

    /// Calls `f(a, b)` with the entries of each cell `a` of `cells` (a run of cell
    /// indices) and of each cell `b` that may hold a pair with it: first the cell
    /// itself (`b == a`, unless the cell has a kin), then those of its forward half of
    /// neighbours whose kin is not the cell's. Each pair of cells is met once over all
    /// cells.
    pub(super) fn forward_blocks(
        &self,
        cells: Range<usize>,
        mut f: impl FnMut(Range<usize>, Range<usize>),
    ) {
        if cells.is_empty() {
            return;
        }
        // x + 1 in the cell's own row, and x − 1 … x + 1 in the four rows after it:
        // (offset of the run's first key, cells in the run)
        let forward: [(u64, u64); 5] = [
            (1, 1),
            ((1 << 21) - 1, 3),
            ((1 << 42) - (1 << 21) - 1, 3),
            ((1 << 42) - 1, 3),
            ((1 << 42) + (1 << 21) - 1, 3),
        ];
        let all = &self.cells;
        let first = all[cells.start].key;
        let mut cursors = forward.map(|(o, _)| all.partition_point(|c| c.key < first + o));
        for c in cells {
            let (key, kin) = (all[c].key, all[c].kin);
            let mine = self.entries(c);
            if kin == NO_KIN {
                f(mine.clone(), mine.clone());
            }
            for (cursor, (offset, span)) in cursors.iter_mut().zip(forward) {
                let lo = key + offset;
                while *cursor < all.len() && all[*cursor].key < lo {
                    *cursor += 1;
                }
                let mut d = *cursor;
                while d < all.len() && all[d].key < lo + span {
                    if kin == NO_KIN || all[d].kin != kin {
                        f(mine.clone(), self.entries(d));
                    }
                    d += 1;
                }
            }
        }
    }
}
