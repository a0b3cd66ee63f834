//! The invariants of a body's clusters, on plain data: every cluster connected, no dead
//! member, every live particle covered, no isolated cluster, no oversized cluster, no
//! cluster inside (or equal to) another; and the particle → clusters index in step with
//! the member lists.

use crate::body::graph::is_connected;
use crate::body::lattice::Lattice;
use crate::clusters::contained::subset;
use petgraph::unionfind::UnionFind;
use std::fmt;

/// One broken invariant.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Violation {
    /// A cluster's live members do not form one connected graph (or it is empty).
    Disconnected {
        /// Cluster id (as given to the checker).
        cluster: u64,
    },
    /// A cluster lists a removed particle.
    DeadMember {
        /// Cluster id.
        cluster: u64,
        /// The removed particle.
        particle: u32,
    },
    /// A body of the oriented model holds a cluster.
    ClusterOfOrientedBody {
        /// The cluster.
        cluster: u64,
    },
    /// A live particle is in no cluster.
    Uncovered {
        /// The particle.
        particle: u32,
    },
    /// Inside one piece, the clusters' overlap graph falls into several components.
    Isolated {
        /// A particle of the piece.
        piece_particle: u32,
        /// How many overlap components the piece has.
        components: usize,
    },
    /// A cluster has more members than allowed.
    Oversized {
        /// Cluster id.
        cluster: u64,
        /// Its size.
        size: usize,
        /// The limit.
        max: usize,
    },
    /// The particle → clusters index does not list exactly the clusters whose members
    /// hold this particle (in ascending order).
    IndexMismatch {
        /// The particle.
        particle: u32,
    },
    /// A cluster's members all belong to another cluster as well (reported once, for
    /// the smaller cluster, or the later of two equal ones).
    Contained {
        /// Cluster id.
        cluster: u64,
        /// A cluster that holds all of its members.
        container: u64,
    },
    /// A body's key table names a cluster whose entity is gone or is not a cluster of
    /// the body (despawned from outside, say).
    MissingCluster {
        /// The cluster key.
        cluster: u64,
    },
    /// A live particle's position is not finite (NaN or infinite), or its entity has
    /// lost its position.
    NonFinite {
        /// The particle.
        particle: u32,
    },
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Violation::Disconnected { cluster } => write!(f, "cluster {cluster} is not connected"),
            Violation::DeadMember { cluster, particle } => {
                write!(f, "cluster {cluster} has removed particle {particle}")
            }
            Violation::Uncovered { particle } => write!(f, "particle {particle} is in no cluster"),
            Violation::ClusterOfOrientedBody { cluster } => {
                write!(
                    f,
                    "cluster {cluster} belongs to a body of the oriented model"
                )
            }
            Violation::Isolated {
                piece_particle,
                components,
            } => write!(
                f,
                "the piece of particle {piece_particle} has {components} unlinked cluster groups"
            ),
            Violation::Oversized { cluster, size, max } => {
                write!(f, "cluster {cluster} has {size} members (max {max})")
            }
            Violation::IndexMismatch { particle } => write!(
                f,
                "the cluster index entry of particle {particle} disagrees with the members"
            ),
            Violation::Contained { cluster, container } => {
                write!(f, "cluster {cluster} lies inside cluster {container}")
            }
            Violation::MissingCluster { cluster } => {
                write!(f, "cluster {cluster} has no cluster entity")
            }
            Violation::NonFinite { particle } => {
                write!(f, "particle {particle} has no finite position")
            }
        }
    }
}

/// Checks one body's clusters (`(id, sorted members)`) against its lattice.
pub fn check_body<'a>(
    lattice: &Lattice,
    clusters: impl IntoIterator<Item = (u64, &'a [u32])>,
    max_cluster_size: usize,
) -> Vec<Violation> {
    let clusters: Vec<(u64, &[u32])> = clusters.into_iter().collect();
    let mut out = contained_clusters(&clusters, lattice.len());
    let mut covered = vec![false; lattice.len()];
    let mut sets = UnionFind::<u32>::new(lattice.len());
    for &(id, members) in &clusters {
        if members.len() > max_cluster_size {
            out.push(Violation::Oversized {
                cluster: id,
                size: members.len(),
                max: max_cluster_size,
            });
        }
        if let Some(&dead) = members.iter().find(|m| !lattice.is_live(**m)) {
            out.push(Violation::DeadMember {
                cluster: id,
                particle: dead,
            });
        }
        if !is_connected(members, lattice) {
            out.push(Violation::Disconnected { cluster: id });
        }
        for &m in members.iter().filter(|m| lattice.is_live(**m)) {
            covered[m as usize] = true;
            sets.union(members[0], m);
        }
    }
    for p in lattice.live_particles() {
        if !covered[p as usize] {
            out.push(Violation::Uncovered { particle: p });
        }
    }
    let (piece, count) = (&lattice.pieces().label, lattice.pieces().count);
    let mut roots: Vec<Vec<u32>> = vec![Vec::new(); count];
    for p in lattice.live_particles().filter(|p| covered[*p as usize]) {
        roots[piece[p as usize] as usize].push(sets.find(p));
    }
    for (i, mut r) in roots.into_iter().enumerate() {
        r.sort_unstable();
        r.dedup();
        if r.len() > 1 {
            let piece_particle = lattice
                .live_particles()
                .find(|p| piece[*p as usize] == i as u32)
                .unwrap_or(0);
            out.push(Violation::Isolated {
                piece_particle,
                components: r.len(),
            });
        }
    }
    out
}

/// [`Violation::Contained`] for each cluster (sorted members) whose members another
/// cluster holds too. Every container of a cluster holds its first member, so only the
/// clusters holding that particle are compared.
fn contained_clusters(clusters: &[(u64, &[u32])], particles: usize) -> Vec<Violation> {
    let mut holding: Vec<Vec<usize>> = vec![Vec::new(); particles];
    for (i, (_, members)) in clusters.iter().enumerate() {
        for &m in *members {
            if let Some(list) = holding.get_mut(m as usize) {
                list.push(i);
            }
        }
    }
    let mut out = Vec::new();
    for (i, &(cluster, members)) in clusters.iter().enumerate() {
        let Some(head) = members.first().and_then(|h| holding.get(*h as usize)) else {
            continue;
        };
        let container = head.iter().find(|&&j| {
            let other = clusters[j].1;
            j != i
                && (other.len() > members.len() || (other.len() == members.len() && j < i))
                && subset(members, other)
        });
        if let Some(&j) = container {
            out.push(Violation::Contained {
                cluster,
                container: clusters[j].0,
            });
        }
    }
    out
}

/// Checks a particle → clusters index, given as each particle's list in particle order
/// (e.g. [`crate::clusters::index::ClusterIndex::iter`]), against the member lists it
/// indexes: entry `p` must list, ascending and once each, the clusters whose members
/// hold `p`.
pub fn check_index<'a, 'i>(
    clusters: impl IntoIterator<Item = (u32, &'a [u32])>,
    index: impl ExactSizeIterator<Item = &'i [u32]>,
) -> Vec<Violation> {
    let mut expected: Vec<Vec<u32>> = vec![Vec::new(); index.len()];
    let mut out = Vec::new();
    for (k, members) in clusters {
        for &m in members {
            match expected.get_mut(m as usize) {
                Some(list) => list.push(k),
                None => out.push(Violation::IndexMismatch { particle: m }),
            }
        }
    }
    for (p, (mut want, have)) in expected.into_iter().zip(index).enumerate() {
        want.sort_unstable();
        if want[..] != have[..] {
            out.push(Violation::IndexMismatch { particle: p as u32 });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use glam::UVec3;

    #[test]
    fn each_violation_is_detected() {
        let mut l = Shape::cuboid(UVec3::new(4, 1, 1)).voxelise(1.0).unwrap();
        let ok: Vec<Vec<u32>> = vec![vec![0, 1, 2], vec![2, 3]];
        assert!(
            check_body(
                &l,
                ok.iter().enumerate().map(|(i, m)| (i as u64, m.as_slice())),
                3
            )
            .is_empty()
        );
        let bad = [vec![0, 1], vec![2, 3]];
        let v = check_body(
            &l,
            bad.iter()
                .enumerate()
                .map(|(i, m)| (i as u64, m.as_slice())),
            3,
        );
        assert!(
            matches!(v[..], [Violation::Isolated { components: 2, .. }]),
            "{v:?}"
        );
        let v = check_body(&l, [(0, &[0u32, 2, 3][..])], 2);
        assert!(v.contains(&Violation::Disconnected { cluster: 0 }));
        assert!(v.contains(&Violation::Oversized {
            cluster: 0,
            size: 3,
            max: 2
        }));
        assert!(v.contains(&Violation::Uncovered { particle: 1 }));
        // inside another, and a duplicate
        let v = check_body(
            &l,
            [(0, &[0u32, 1, 2, 3][..]), (1, &[1, 2]), (2, &[1, 2])],
            4,
        );
        assert_eq!(
            v,
            vec![
                Violation::Contained {
                    cluster: 1,
                    container: 0
                },
                Violation::Contained {
                    cluster: 2,
                    container: 0
                }
            ]
        );
        let v = check_body(&l, [(0, &[0u32, 1, 2][..]), (1, &[2, 3]), (2, &[2, 3])], 3);
        assert_eq!(
            v,
            vec![Violation::Contained {
                cluster: 2,
                container: 1
            }]
        );
        l.remove(3);
        let v = check_body(&l, [(0, &[0u32, 1, 2, 3][..])], 4);
        assert_eq!(
            v,
            vec![Violation::DeadMember {
                cluster: 0,
                particle: 3
            }]
        );
    }

    #[test]
    fn index_mismatches_are_detected() {
        let clusters: [(u32, &[u32]); 2] = [(0, &[0, 1]), (5, &[1, 2])];
        let list = |ks: &'static [u32]| ks;
        let good = [list(&[0]), list(&[0, 5]), list(&[5])];
        assert!(check_index(clusters, good.into_iter()).is_empty());
        // a missing entry, an extra entry, the wrong order, a member beyond the index
        let missing = [list(&[0]), list(&[5]), list(&[5])];
        let extra = [list(&[0, 5]), list(&[0, 5]), list(&[5])];
        let unsorted = [list(&[0]), list(&[5, 0]), list(&[5])];
        for (bad, particle) in [(missing, 1), (extra, 0), (unsorted, 1)] {
            assert_eq!(
                check_index(clusters, bad.into_iter()),
                vec![Violation::IndexMismatch { particle }]
            );
        }
        assert_eq!(
            check_index([(0u32, &[0u32, 3][..])], good[..1].iter().copied()),
            vec![Violation::IndexMismatch { particle: 3 }]
        );
    }
}
