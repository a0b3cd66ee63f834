//! Reconstruction step 1: cut clusters fall into pieces (connected components of their live
//! members); the pieces that add nothing are dropped, the fragments merge into the
//! neighbour cluster that shares most of their particles, and the other pieces stay as
//! clusters.
//!
//! Two departures from the notes' letter, both measured against a fresh clustering of
//! the same cut geometry (`cleave fidelity`), which is what the reconstruction aims at
//! (the body's clusters, and so its stiffness, should stay what they were):
//!
//! - **Not every piece merges.** Merging every piece grows the neighbours by a whole
//!   piece, and the split that follows cuts the union along a new plane: clusters came out
//!   40–65 % larger and 70–85 % longer than a fresh clustering's, and a cantilever with
//!   20 scoops sagged 7–12 % less. A piece of a cut cluster is what a fresh clustering
//!   builds there anyway (the distance-based clusters truncated by the cut), so a piece
//!   stays a cluster unless its rest shape is a point or a line: such a *fragment* cannot
//!   fix a rotation, and it merges (§3.2).
//! - **The neighbour shares the most particles with the fragment** (ties: the smaller
//!   cluster, then at random). §3.2 picks a random cluster of a random adjacent particle;
//!   the cluster that already holds most of the fragment grows least and stays compact.
//!   A fragment that shares no particle with another cluster merges through its first
//!   adjacent particle, as before.
//!
//! And one addition: a piece is **redundant** when each of its particles and each
//! lattice edge between them also lies in another cluster (not itself dropped): it
//! constrains nothing the others do not, and is dropped, smallest first. A fresh
//! clustering has no such leftovers; keeping them gave 10–13 % more memberships per
//! particle than a fresh clustering (and duplicate clusters: the same lone particle
//! once per cut cluster).
//!
//! The work is split by what it reads. The pieces and their neighbours only read the
//! clusters as the cut left them and the lattice, so they are found in parallel; the
//! drops and merge choices depend on the ones before, and draw from the one random
//! stream, piece by piece in order; the merged member lists are unions, computed in
//! parallel; and the store applies every edit at once. A piece that merges away is never
//! written as a cluster of its own.

use super::merge::MergeChooser;
use super::pieces::{CutView, PieceScratch, Pieces};
use crate::body::lattice::Lattice;
use crate::clusters::edits::ClusterEdits;
use crate::clusters::store::ClusterStore;
use rand::Rng;
use rayon::prelude::*;

/// Cut clusters per parallel task.
const CUT_PER_TASK: usize = 64;

/// Merge groups per parallel task.
const GROUPS_PER_TASK: usize = 64;

/// Replaces every cut cluster by its pieces, drops the redundant ones and merges the
/// fragments into neighbour clusters (see the module docs for the rules).
/// Returns the clusters this produced — the neighbour clusters that received a merge and
/// the pieces that remain clusters — ascending, without duplicates.
///
/// A cut cluster stands, as a candidate neighbour, for its piece that holds the
/// particle in question. Everything that draws from `rng` runs in piece order, so the
/// result does not depend on the thread count.
pub fn regroup<S: ClusterStore>(
    store: &mut S,
    lattice: &Lattice,
    cut_clusters: &[u32],
    rng: &mut impl Rng,
) -> Vec<u32> {
    let mut cut: Vec<u32> = cut_clusters.to_vec();
    cut.sort_unstable();
    cut.dedup();
    let view = CutView::new(lattice, store.index(), &cut);
    // 3.1: the pieces of every cut cluster, and their intact neighbours.
    let lists: Vec<&[u32]> = cut.iter().map(|k| store.members(*k)).collect();
    let pieces = find_pieces(&lists, &view);
    // first piece of each cut cluster
    let mut first = Vec::with_capacity(cut.len() + 1);
    first.push(0u32);
    for c in &pieces.counts {
        first.push(first.last().copied().unwrap_or(0) + c);
    }
    // 3.2: every merge, chosen in piece order over the merge forest.
    let chooser = MergeChooser {
        view: &view,
        pieces: &pieces,
        first: &first,
        size_of: &|k| store.members(k).len(),
    };
    let mut forest = chooser.choose(rng);
    // The merged member lists, group by group, then one batch of edits.
    let mut groups: Vec<(u32, u32)> = (0..pieces.pieces.len() as u32)
        .map(|p| (forest.find(p), p))
        .collect();
    groups.sort_unstable();
    let groups: Vec<&[(u32, u32)]> = groups.chunk_by(|a, b| a.0 == b.0).collect();
    let unions = merged_members(&groups, &pieces);
    let owner_of_piece = |p: u32| first.partition_point(|f| *f <= p) - 1;
    let mut edits = ClusterEdits::default();
    let mut produced = Vec::with_capacity(groups.len());
    let mut kept = vec![false; cut.len()];
    // (created clusters are listed by their position among the creations)
    let mut created_positions = Vec::new();
    let lists = unions.iter().flat_map(|(particles, spans)| {
        spans
            .iter()
            .map(move |[s, e]| &particles[*s as usize..*e as usize])
    });
    for (group, members) in groups.iter().zip(lists) {
        let root = group[0].0;
        if forest.is_dropped(root) {
            continue;
        }
        match forest.intact_key(root) {
            Some(k) => {
                edits.extend(k, members);
                produced.push(k);
            }
            None => {
                let c = owner_of_piece(root);
                if first[c] == root {
                    kept[c] = true;
                    edits.replace(cut[c], members);
                    produced.push(cut[c]);
                } else {
                    created_positions.push(produced.len());
                    edits.create(members);
                    // a placeholder until the store names it
                    produced.push(cut[c]);
                }
            }
        }
    }
    for (c, k) in cut.iter().enumerate() {
        if !kept[c] {
            edits.remove(*k);
        }
    }
    let created = store.apply(&edits);
    for (position, k) in created_positions.into_iter().zip(created) {
        produced[position] = k;
    }
    produced.sort_unstable();
    produced.dedup();
    produced
}

/// The pieces of the cut clusters whose member `lists` these are, in order (in
/// parallel, each task's pieces appended in order).
fn find_pieces(lists: &[&[u32]], view: &CutView) -> Pieces {
    let found: Vec<Pieces> = lists
        .par_chunks(CUT_PER_TASK)
        .map_init(PieceScratch::default, |scratch, lists| {
            let mut out = Pieces::default();
            for members in lists {
                scratch.find(members, view, &mut out);
            }
            out
        })
        .collect();
    let mut all = Pieces::default();
    for chunk in found {
        all.append(chunk);
    }
    all
}

/// Each merge group's members — the union of its pieces', sorted when more than one —
/// in parallel: per task, the members in one list and each group's span of it.
fn merged_members(groups: &[&[(u32, u32)]], pieces: &Pieces) -> Vec<(Vec<u32>, Vec<[u32; 2]>)> {
    groups
        .par_chunks(GROUPS_PER_TASK)
        .map(|groups| {
            let (mut particles, mut spans) = (Vec::new(), Vec::with_capacity(groups.len()));
            for group in groups {
                let start = particles.len();
                for (_, p) in *group {
                    particles.extend_from_slice(pieces.members(*p as usize));
                }
                if group.len() > 1 {
                    let len = sort_dedup(&mut particles[start..]);
                    particles.truncate(start + len);
                }
                spans.push([start as u32, particles.len() as u32]);
            }
            (particles, spans)
        })
        .collect()
}

/// Sorts `list` and moves its distinct values to the front; returns how many there are.
fn sort_dedup(list: &mut [u32]) -> usize {
    list.sort_unstable();
    let mut len = 0;
    for r in 0..list.len() {
        if len == 0 || list[r] != list[len - 1] {
            list[len] = list[r];
            len += 1;
        }
    }
    len
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::graph::is_connected;
    use crate::body::shape::Shape;
    use crate::clusters::store::ClusterTable;
    use glam::{IVec3, UVec3};
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn clusters(t: &ClusterTable) -> Vec<Vec<u32>> {
        t.iter().map(|(_, m)| m.to_vec()).collect()
    }

    #[test]
    fn fragments_merge_redundant_pieces_go_and_the_rest_stay() {
        // A 6×1×1 bar, clusters {0,1,2,3} and {3,4,5}; cut particle 1
        let mut l = Shape::cuboid(UVec3::new(6, 1, 1)).voxelise(1.0).unwrap();
        let p: Vec<u32> = (0..6)
            .map(|x| l.at(IVec3::new(x - 3, 0, 0)).unwrap())
            .collect();
        let mut t = ClusterTable::from_clusters(
            6,
            vec![vec![p[0], p[1], p[2], p[3]], vec![p[3], p[4], p[5]]],
        );
        l.remove(p[1]);
        let out = regroup(&mut t, &l, &[0], &mut ChaCha8Rng::seed_from_u64(0));
        // {p0} has no adjacent particle: it stays on its own; the fragment {p2, p3} merges
        // into {p3, p4, p5}, which holds one of its particles
        assert_eq!(clusters(&t), vec![vec![p[0]], vec![p[2], p[3], p[4], p[5]]]);
        assert_eq!(out, vec![0, 1]);

        // the same bar, clusters {0,1,2}, {2,3,4}, {4,5}: the piece {p2} lies in
        // {p2, p3, p4} (redundant) and goes
        let mut l = Shape::cuboid(UVec3::new(6, 1, 1)).voxelise(1.0).unwrap();
        let mut t = ClusterTable::from_clusters(
            6,
            vec![
                vec![p[0], p[1], p[2]],
                vec![p[2], p[3], p[4]],
                vec![p[4], p[5]],
            ],
        );
        l.remove(p[1]);
        let out = regroup(&mut t, &l, &[0], &mut ChaCha8Rng::seed_from_u64(0));
        assert_eq!(
            clusters(&t),
            vec![vec![p[0]], vec![p[2], p[3], p[4]], vec![p[4], p[5]]]
        );
        assert_eq!(out, vec![0]);
        for (_, m) in t.iter() {
            assert!(is_connected(m, &l));
        }
    }

    #[test]
    fn a_piece_that_spans_a_plane_stays_a_cluster() {
        // a 4×3 plate: a 3×3 cluster on the left overlapping a 2×3 one on the right;
        // cutting the left cluster's corner leaves it 8 particles that stay together
        let mut l = Shape::cuboid(UVec3::new(4, 3, 1)).voxelise(1.0).unwrap();
        let column =
            |x: i32| -> Vec<u32> { l.live_particles().filter(|q| l.coord(*q).x == x).collect() };
        let x0 = l.live_particles().map(|q| l.coord(q).x).min().unwrap();
        let mut left: Vec<u32> = (x0..x0 + 3).flat_map(column).collect();
        let mut right: Vec<u32> = (x0 + 2..x0 + 4).flat_map(column).collect();
        left.sort_unstable();
        right.sort_unstable();
        let mut t = ClusterTable::from_clusters(l.len(), vec![left.clone(), right.clone()]);
        let corner = left[0];
        l.remove(corner);
        let out = regroup(&mut t, &l, &[0], &mut ChaCha8Rng::seed_from_u64(0));
        assert_eq!(out, vec![0]);
        assert_eq!(clusters(&t), vec![left[1..].to_vec(), right]);
    }
}
