//! The pieces of a body: connected components of its live particles over the
//! lattice's links, counted fast while the lattice is intact and labelled otherwise.

use super::lattice::{Lattice, NO_PARTICLE, PieceLabels};
use crate::util::union_find::UnionFind;

/// Labels the pieces by a union–find over *runs*: the particles of consecutive cells
/// along a row of the grid, each linked to the next along +x (a particle its cell does
/// not name, a split's other half, is a run of its own). A grid's rows are long and
/// mostly whole, so the sets are few and stay in cache, and the particles are walked in
/// the grid's memory order, in one pass that makes the runs and joins each to the runs
/// its particles link to below (−y, −z), consecutive particles of a row mostly naming
/// the same pair (joined once); the other halves are then joined to every run they link
/// to. The pieces are then numbered in order
/// of their lowest particle, as a search from each unlabelled particle in index order
/// numbers them.
fn label_pieces(lattice: &Lattice) -> PieceLabels {
    let n = lattice.len();
    let nx = (lattice.dims.x as usize).max(1);
    let mut run_of = vec![u32::MAX; n];
    // (a set per run, added as the runs are met)
    let mut sets = UnionFind::new(0);
    // (per direction, the last pair of runs joined: the next particle of a row mostly
    // names it again)
    let mut joined = [(u32::MAX, u32::MAX); 2];
    for row in lattice.grid.chunks_exact(nx) {
        let mut last = NO_PARTICLE;
        for &p in row {
            if p != NO_PARTICLE {
                let links = &lattice.links[p as usize];
                let run = if last != NO_PARTICLE && links[0] == last {
                    run_of[last as usize]
                } else {
                    sets.add()
                };
                run_of[p as usize] = run;
                // −y and −z lead to cells earlier in the grid, whose runs are known; an
                // other half there joins its runs below
                for (joined, q) in joined.iter_mut().zip([links[2], links[4]]) {
                    if q == NO_PARTICLE {
                        continue;
                    }
                    let other = run_of[q as usize];
                    if other != u32::MAX && (run, other) != *joined {
                        sets.union(run, other);
                        *joined = (run, other);
                    }
                }
            }
            last = p;
        }
    }
    // (the grid names live particles only: a removed one leaves its cell)
    let others: Vec<u32> = (lattice.live_particles())
        .filter(|&p| run_of[p as usize] == u32::MAX)
        .collect();
    for &p in &others {
        run_of[p as usize] = sets.add();
    }
    let runs = sets.len() as u32;
    for &p in &others {
        for &q in lattice.links[p as usize]
            .iter()
            .filter(|&&q| q != NO_PARTICLE)
        {
            sets.union(run_of[p as usize], run_of[q as usize]);
        }
    }
    // each run's piece, numbered when its first particle in index order is met
    let root: Vec<u32> = (0..runs).map(|r| sets.find(r)).collect();
    let mut piece_of_root = vec![u32::MAX; runs as usize];
    let mut pieces = 0u32;
    let mut label = run_of;
    for (p, run) in label.iter_mut().enumerate() {
        if !lattice.is_live(p as u32) {
            *run = u32::MAX;
            continue;
        }
        let piece = &mut piece_of_root[root[*run as usize] as usize];
        if *piece == u32::MAX {
            *piece = pieces;
            pieces += 1;
        }
        *run = *piece;
    }
    PieceLabels {
        label,
        count: pieces as usize,
    }
}

impl Lattice {
    /// The body's pieces, labelled. Labelled on the first call after an edit (a pass
    /// over the links) and kept until the next edit, so every reader in a frame —
    /// the cut's count, contacts, the surface — shares one labelling.
    pub fn pieces(&self) -> &PieceLabels {
        self.pieces.get_or_init(|| label_pieces(self))
    }

    /// Number of pieces: connected components of the live particles under the
    /// 6-neighbourhood (the count of [`Lattice::pieces`], without labelling
    /// every particle). Works on runs of occupied cells along x: one pass over the grid,
    /// then a union–find over the runs, joining each run to the overlapping runs of the
    /// row below and of the slice below — a few operations per run instead of a search
    /// step per particle.
    ///
    /// Once edges were severed or particles split ([`Lattice::is_intact`] false), the
    /// grid no longer tells the edges, and the pieces are labelled over the links.
    pub fn piece_count(&self) -> usize {
        if let Some(labelled) = self.pieces.get() {
            return labelled.count;
        }
        if !self.intact {
            return self.pieces().count;
        }
        let (nx, ny) = (self.dims.x as usize, self.dims.y as usize);
        if self.live_count == 0 || nx == 0 {
            return 0;
        }
        // runs of occupied cells per row (`first`, `last` x, inclusive); the grid's
        // padding keeps every run inside its row
        let mut runs: Vec<(u32, u32)> = Vec::new();
        let mut row_start: Vec<u32> = Vec::with_capacity(self.grid.len() / nx + 1);
        for row in self.grid.chunks_exact(nx) {
            row_start.push(runs.len() as u32);
            let mut x = 0;
            while x < nx {
                if row[x] == NO_PARTICLE {
                    x += 1;
                    continue;
                }
                let first = x;
                while x < nx && row[x] != NO_PARTICLE {
                    x += 1;
                }
                runs.push((first as u32, (x - 1) as u32));
            }
        }
        row_start.push(runs.len() as u32);
        let mut sets = UnionFind::new(runs.len());
        let mut pieces = runs.len();
        let range = |r: usize| row_start[r] as usize..row_start[r + 1] as usize;
        for r in 0..row_start.len() - 1 {
            // the row at y − 1 (same slice) and the row at z − 1 (same y)
            let below = [(r % ny != 0).then(|| r - 1), r.checked_sub(ny)];
            for other in below.into_iter().flatten() {
                let (mut i, mut j) = (range(r).start, range(other).start);
                let (end_i, end_j) = (range(r).end, range(other).end);
                while i < end_i && j < end_j {
                    let (a, b) = (runs[i], runs[j]);
                    if a.1 < b.0 {
                        i += 1;
                    } else if b.1 < a.0 {
                        j += 1;
                    } else {
                        if sets.union(i as u32, j as u32) {
                            pieces -= 1;
                        }
                        if a.1 < b.1 {
                            i += 1;
                        } else {
                            j += 1;
                        }
                    }
                }
            }
        }
        pieces
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::IVec3;

    /// The pieces by a search from each unlabelled live particle, in index order: the
    /// reference the union–find is checked against.
    fn searched_pieces(lattice: &Lattice) -> PieceLabels {
        let mut label = vec![u32::MAX; lattice.len()];
        let mut pieces = 0u32;
        for start in lattice.live_particles() {
            if label[start as usize] != u32::MAX {
                continue;
            }
            label[start as usize] = pieces;
            let mut stack = vec![start];
            while let Some(p) = stack.pop() {
                for n in lattice.neighbours(p) {
                    if label[n as usize] == u32::MAX {
                        label[n as usize] = pieces;
                        stack.push(n);
                    }
                }
            }
            pieces += 1;
        }
        PieceLabels {
            label,
            count: pieces as usize,
        }
    }

    #[test]
    fn piece_count_agrees_with_labelling_the_pieces() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let mut counts = std::collections::BTreeSet::new();
        for case in 0..300 {
            // random occupancy of a small box (sparse to dense), then random removals
            let dims = IVec3::new(
                rng.random_range(1..9),
                rng.random_range(1..9),
                rng.random_range(1..9),
            );
            let fill = rng.random_range(0.2..1.0);
            let mut coords = Vec::new();
            for z in 0..dims.z {
                for y in 0..dims.y {
                    for x in 0..dims.x {
                        if rng.random_bool(fill) {
                            coords.push(IVec3::new(x, y, z) - dims / 2);
                        }
                    }
                }
            }
            let mut l = Lattice::from_coords(1.0, coords).unwrap();
            for p in 0..l.len() as u32 {
                if rng.random_bool(0.2) {
                    l.remove(p);
                }
            }
            let labels = label_pieces(&l);
            assert_eq!(labels.label, searched_pieces(&l).label, "case {case}");
            let pieces = labels.count;
            assert_eq!(l.piece_count(), pieces, "case {case}");
            counts.insert(pieces.min(4));
            // and with edges severed at random: labelled over the links
            for (a, b) in l.edges() {
                if rng.random_bool(0.3) {
                    l.sever(a, b);
                }
            }
            let severed = label_pieces(&l);
            assert_eq!(
                severed.label,
                searched_pieces(&l).label,
                "case {case}, severed"
            );
        }
        // empty, one, and several pieces all occurred
        assert_eq!(counts.into_iter().collect::<Vec<_>>(), [0, 1, 2, 3, 4]);
    }

    #[test]
    fn the_kept_labels_follow_every_edit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let coords = (0..5 * 5 * 5)
            .map(|k| IVec3::new(k % 5, k / 5 % 5, k / 25))
            .collect();
        let mut l = Lattice::from_coords(1.0, coords).unwrap();
        let mut severed = Vec::new();
        for step in 0..200 {
            l.pieces();
            let live: Vec<u32> = l.live_particles().collect();
            let p = live[rng.random_range(0..live.len())];
            match step % 4 {
                0 => {
                    l.remove(p);
                }
                1 => {
                    if let Some(q) = l.neighbours(p).next() {
                        l.sever(p, q);
                        severed.push((p, q));
                    }
                }
                2 => {
                    l.split(p, std::array::from_fn(|_| rng.random_bool(0.5)));
                }
                _ => {
                    if let Some((a, b)) = severed.pop() {
                        l.relink(a, b);
                    }
                }
            }
            let fresh = searched_pieces(&l);
            assert_eq!(l.pieces().label, fresh.label, "step {step}");
            assert_eq!(l.piece_count(), fresh.count, "step {step}");
        }
    }
}
