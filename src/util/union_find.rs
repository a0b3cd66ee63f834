//! Union–find over `0..n` whose every set is rooted at its lowest element, with path
//! halving: joins are cheap, and a pass in index order meets each set's root before any
//! other member (which [`UnionFind::into_parents`] lets a caller number sets by).

/// Disjoint sets of `0..n` (see the module docs).
#[derive(Clone, Debug)]
pub struct UnionFind(Vec<u32>);

impl UnionFind {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Self((0..n as u32).collect())
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// A new singleton, numbered after the others (its own root).
    pub fn add(&mut self) -> u32 {
        let x = self.0.len() as u32;
        self.0.push(x);
        x
    }

    /// The root (lowest element) of `x`'s set.
    #[inline]
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let grand = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = grand;
            x = grand;
        }
        x
    }

    /// Joins the sets of `a` and `b`; whether they were apart.
    #[inline]
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
        ra != rb
    }

    /// Each element's parent: lower than the element unless it is its set's root.
    pub fn into_parents(self) -> Vec<u32> {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_are_rooted_at_their_lowest_element_and_parents_point_down() {
        let mut sets = UnionFind::new(8);
        assert!(sets.union(5, 2));
        assert!(sets.union(7, 5));
        assert!(sets.union(6, 3));
        assert!(!sets.union(2, 7));
        assert!(sets.union(3, 7));
        for x in [2, 3, 5, 6, 7] {
            assert_eq!(sets.find(x), 2);
        }
        assert_eq!(sets.find(4), 4);
        assert_eq!(sets.add(), 8);
        assert!(sets.union(8, 6));
        assert_eq!((sets.find(8), sets.len()), (2, 9));
        let parents = sets.into_parents();
        for (x, &p) in parents.iter().enumerate() {
            assert!(p as usize <= x, "{x} → {p}");
        }
    }
}
