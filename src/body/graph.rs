//! Graph searches over the particle graph (live lattice edges), restricted to particle
//! subsets: connected components of a cluster, pieces of a body.

use crate::body::lattice::{Lattice, NO_PARTICLE};
use std::cell::RefCell;

/// Index of `p` in the sorted slice `set`, if present.
#[inline]
pub fn position_in(set: &[u32], p: u32) -> Option<usize> {
    set.binary_search(&p).ok()
}

thread_local! {
    /// Per-thread scratch of one slot per lattice particle, `u32::MAX` between uses.
    static SLOTS: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
    /// Per-thread depth-first stack of [`connected_components`], empty between uses.
    static STACK: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
}

/// Runs `f` with a scratch slice of `len` slots, all `u32::MAX`; `f` must give every
/// slot it sets back to `u32::MAX` before it returns, and must not call `with_slots`
/// itself (the scratch is borrowed while `f` runs). Lookups are O(1) where a binary
/// search over the member list would cost a logarithm and a branch miss per step.
pub fn with_slots<R>(len: usize, f: impl FnOnce(&mut [u32]) -> R) -> R {
    SLOTS.with(|slots| {
        let mut slots = slots.borrow_mut();
        if slots.len() < len {
            slots.resize(len, u32::MAX);
        }
        f(&mut slots[..len])
    })
}

/// Maximal connected subgraphs of the live particles in `members` (any order, no
/// duplicates), using lattice edges between members. Each component is sorted; the
/// components are ordered by their smallest particle. Dead particles are dropped.
///
/// Sorted input (every member list of a [`crate::clusters::store::ClusterStore`]) costs
/// no sort: the components are read off the labels in member order.
pub fn connected_components(members: &[u32], lattice: &Lattice) -> Vec<Vec<u32>> {
    // sized up front: a filtered collect would grow the list by reallocation
    let mut set: Vec<u32> = Vec::with_capacity(members.len());
    set.extend(members.iter().copied().filter(|p| lattice.is_live(*p)));
    if !set.is_sorted_by(|a, b| a < b) {
        set.sort_unstable();
        set.dedup();
    }
    let (count, components) = with_slots(lattice.len(), |label| {
        // label: UNSEEN for members not reached yet, the component id once reached;
        // ids are given in order of each component's smallest member
        const UNSEEN: u32 = u32::MAX - 1;
        for &p in &set {
            label[p as usize] = UNSEEN;
        }
        let mut count = 0u32;
        // (a thread's stack is reused: one per call would cost an allocation)
        let mut stack = STACK.with(|s| std::mem::take(&mut *s.borrow_mut()));
        for &start in &set {
            if label[start as usize] != UNSEEN {
                continue;
            }
            label[start as usize] = count;
            stack.push(start);
            while let Some(p) = stack.pop() {
                for n in lattice.links(p) {
                    if n != NO_PARTICLE && label[n as usize] == UNSEEN {
                        label[n as usize] = count;
                        stack.push(n);
                    }
                }
            }
            count += 1;
        }
        STACK.with(|s| *s.borrow_mut() = stack);
        let mut components = Vec::new();
        if count > 1 {
            components = vec![Vec::new(); count as usize];
            for &p in &set {
                components[label[p as usize] as usize].push(p);
            }
        }
        for &p in &set {
            label[p as usize] = u32::MAX;
        }
        (count, components)
    });
    match count {
        0 => Vec::new(),
        1 => vec![set],
        _ => components,
    }
}

/// Whether the live particles of `members` form one connected graph (an empty set is not).
pub fn is_connected(members: &[u32], lattice: &Lattice) -> bool {
    connected_components(members, lattice).len() == 1
}

/// Live particles adjacent to `members` but not in it: the cluster's *adjacent
/// particles*, without duplicates, in discovery order (members in the given
/// order, each one's neighbours in lattice order) — deterministic without a sort.
pub fn adjacent_particles(members: &[u32], lattice: &Lattice) -> Vec<u32> {
    with_slots(lattice.len(), |mark| {
        for &m in members {
            mark[m as usize] = 0;
        }
        // (room for every neighbour cell: the list never grows by reallocation)
        let mut out = Vec::with_capacity(members.len() * 6);
        for &m in members {
            for n in lattice.links(m) {
                if n != NO_PARTICLE && mark[n as usize] == u32::MAX {
                    mark[n as usize] = 1;
                    out.push(n);
                }
            }
        }
        // two plain loops: a chained iterator tests which half it is in at every step
        for &p in members {
            mark[p as usize] = u32::MAX;
        }
        for &p in &out {
            mark[p as usize] = u32::MAX;
        }
        out
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::{IVec3, UVec3};

    #[test]
    fn components_of_a_cut_bar() {
        let mut l = Shape::cuboid(UVec3::new(5, 1, 1)).voxelise(1.0).unwrap();
        let all: Vec<u32> = l.live_particles().collect();
        assert!(is_connected(&all, &l));
        let mid = l.at(IVec3::new(0, 0, 0)).unwrap();
        l.remove(mid);
        let comps = connected_components(&all, &l);
        assert_eq!(comps.len(), 2);
        assert_eq!(comps.iter().map(Vec::len).sum::<usize>(), 4);
        assert_eq!(l.piece_count(), 2);
        let left: Vec<u32> = comps[0].clone();
        assert_eq!(adjacent_particles(&left, &l), Vec::<u32>::new());
    }
}
