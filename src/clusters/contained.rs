//! No cluster may equal another or lie inside it. A fresh clustering has no such
//! clusters, and after a cut they would only add memberships (stiffness) that constrain
//! nothing new. A contained cluster's particles and lattice edges all lie in its
//! container, so removing it keeps every particle covered, every edge covered and every
//! other cluster as it was.

use crate::body::graph::with_slots;
use crate::clusters::edits::ClusterEdits;
use crate::clusters::store::ClusterStore;

/// Whether cluster `inner` (members `a`) counts as inside cluster `outer` (members `b`,
/// a superset of `a`): strictly smaller, or equal with the larger key. This orders the
/// clusters strictly, so removing every cluster inside another leaves, for each removed
/// one, a container that stays.
fn yields_to(inner: u32, a: &[u32], outer: u32, b: &[u32]) -> bool {
    a.len() < b.len() || (a.len() == b.len() && inner > outer)
}

/// Removes every cluster that lies inside another (equal ones: all but the smallest key)
/// among the clusters in `keys` and the clusters inside them. `particles` is the
/// body's particle count. Returns the removed keys, ascending.
///
/// Every container of `k` holds `k`'s first member, so one index lookup finds them; and
/// every cluster inside `k` has its first member in `k`, so the clusters whose first
/// member is a member of `k` are each looked at once.
pub fn remove_contained<S: ClusterStore>(
    store: &mut S,
    particles: usize,
    keys: &[u32],
) -> Vec<u32> {
    let mut removed = Vec::new();
    with_slots(particles, |in_k| {
        for &k in keys {
            let members = store.members(k);
            let Some(&head) = members.first() else {
                continue;
            };
            for &m in members {
                in_k[m as usize] = 0;
            }
            let inside =
                |j: u32, in_k: &[u32]| store.members(j).iter().all(|p| in_k[*p as usize] == 0);
            // containers of k: clusters holding its first member, at least as large
            let contained = store.clusters_of(head).iter().any(|&j| {
                let b = store.members(j);
                j != k && yields_to(k, members, j, b) && subset(members, b)
            });
            if contained {
                removed.push(k);
            }
            // clusters inside k, each found from its first member
            for &m in members {
                for &j in store.clusters_of(m) {
                    let b = store.members(j);
                    if j != k
                        && b.first() == Some(&m)
                        && yields_to(j, b, k, members)
                        && inside(j, in_k)
                    {
                        removed.push(j);
                    }
                }
            }
            for &m in members {
                in_k[m as usize] = u32::MAX;
            }
        }
    });
    removed.sort_unstable();
    removed.dedup();
    if !removed.is_empty() {
        let mut edits = ClusterEdits::default();
        for &k in &removed {
            edits.remove(k);
        }
        store.apply(&edits);
    }
    removed
}

/// Whether the ascending list `a` is a subset of the ascending list `b`.
pub fn subset(a: &[u32], b: &[u32]) -> bool {
    let mut rest = b;
    a.iter().all(|x| match rest.binary_search(x) {
        Ok(i) => {
            rest = &rest[i + 1..];
            true
        }
        Err(_) => false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clusters::store::ClusterTable;

    #[test]
    fn contained_and_duplicate_clusters_go_and_their_containers_stay() {
        let mut t = ClusterTable::from_clusters(
            10,
            vec![
                vec![0, 1, 2, 3],
                vec![1, 2],
                vec![2, 3, 4],
                vec![2, 3, 4],
                vec![5, 6],
                vec![6, 7, 8],
                vec![6],
            ],
        );
        // looking from cluster 0 only
        assert_eq!(remove_contained(&mut t, 10, &[0]), vec![1]);
        // from everything: the duplicate with the larger key and {6}
        let all: Vec<u32> = t.iter().map(|(k, _)| k).collect();
        assert_eq!(remove_contained(&mut t, 10, &all), vec![3, 6]);
        let left: Vec<Vec<u32>> = t.iter().map(|(_, m)| m.to_vec()).collect();
        assert_eq!(
            left,
            vec![vec![0, 1, 2, 3], vec![2, 3, 4], vec![5, 6], vec![6, 7, 8]]
        );
        assert!(subset(&[1, 3], &[0, 1, 2, 3]) && !subset(&[1, 4], &[0, 1, 2, 3]));
        assert!(subset(&[], &[1]) && !subset(&[1], &[]));
    }
}
