//! Greedy graph colouring of clusters for the Gauss–Seidel mode: two clusters that share
//! a particle never get the same colour, so the clusters of one colour can be projected
//! in parallel, in any order, with the same result.

/// Colours clusters greedily in index order. `cluster_start`/`members` are the CSR
/// cluster → particle lists, `particle_start`/`particle_clusters` the inverse lists.
/// Returns the colour of each cluster.
pub fn colour_clusters(
    cluster_start: &[u32],
    members: &[u32],
    particle_start: &[u32],
    particle_clusters: &[u32],
) -> Vec<u32> {
    let clusters = cluster_start.len().saturating_sub(1);
    let mut colour = vec![u32::MAX; clusters];
    let mut taken: Vec<bool> = Vec::new();
    for k in 0..clusters {
        taken.iter_mut().for_each(|t| *t = false);
        for &m in &members[cluster_start[k] as usize..cluster_start[k + 1] as usize] {
            let m = m as usize;
            for &other in
                &particle_clusters[particle_start[m] as usize..particle_start[m + 1] as usize]
            {
                let c = colour[other as usize];
                if c != u32::MAX {
                    taken[c as usize] = true;
                }
            }
        }
        let c = taken.iter().position(|t| !t).unwrap_or(taken.len()) as u32;
        if c as usize == taken.len() {
            taken.push(false);
        }
        colour[k] = c;
    }
    colour
}

/// [`colour_clusters`] with one bit per colour per particle instead of the inverse lists:
/// a cluster takes the lowest colour that none of its members' earlier clusters has, the
/// same choice. Returns the colours and every particle's colour bits (of `particles`
/// particles), or `None` when some cluster would need a 65th colour.
pub fn colour_clusters_by_bits(
    cluster_start: &[u32],
    members: &[u32],
    particles: usize,
) -> Option<(Vec<u32>, Vec<u64>)> {
    let mut bits = vec![0u64; particles];
    let colours = cluster_start
        .windows(2)
        .map(|range| {
            let members = &members[range[0] as usize..range[1] as usize];
            let taken = members.iter().fold(0, |taken, m| taken | bits[*m as usize]);
            let colour = taken.trailing_ones();
            let bit = 1u64.checked_shl(colour)?; // none from colour 64 on
            for &m in members {
                bits[m as usize] |= bit;
            }
            Some(colour)
        })
        .collect::<Option<Vec<u32>>>()?;
    Some((colours, bits))
}

/// [`colour_clusters`] from the cluster → particle lists alone: builds the inverse lists
/// (over `particles` particles) first.
pub fn colour_clusters_by_lists(
    cluster_start: &[u32],
    members: &[u32],
    particles: usize,
) -> Vec<u32> {
    let mut particle_start = vec![0u32; particles + 1];
    for &m in members {
        particle_start[m as usize + 1] += 1;
    }
    for p in 0..particles {
        particle_start[p + 1] += particle_start[p];
    }
    let mut fill = particle_start.clone();
    let mut particle_clusters = vec![0; members.len()];
    for (k, range) in cluster_start.windows(2).enumerate() {
        for &m in &members[range[0] as usize..range[1] as usize] {
            particle_clusters[fill[m as usize] as usize] = k as u32;
            fill[m as usize] += 1;
        }
    }
    colour_clusters(cluster_start, members, &particle_start, &particle_clusters)
}

/// Groups the clusters whose colour is not `free` by colour. Returns `(order,
/// colour_start)`: cluster indices grouped by colour (ascending inside a colour) and the
/// offsets of each colour's group in `order`.
pub fn order_by_colour(colour_of: &[u32], free: u32) -> (Vec<u32>, Vec<u32>) {
    let used = || colour_of.iter().filter(|c| **c != free);
    let colours = used().map(|c| *c as usize + 1).max().unwrap_or(0);
    let mut start = vec![0u32; colours + 1];
    for &c in used() {
        start[c as usize + 1] += 1;
    }
    for c in 0..colours {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut order = vec![0u32; start[colours] as usize];
    for (k, &c) in colour_of.iter().enumerate() {
        if c != free {
            order[fill[c as usize] as usize] = k as u32;
            fill[c as usize] += 1;
        }
    }
    (order, start)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CSR lists for clusters given as member lists over `n` particles.
    fn csr(clusters: &[Vec<u32>], n: usize) -> [Vec<u32>; 4] {
        let mut cluster_start = vec![0];
        let mut members = vec![];
        let mut of = vec![vec![]; n];
        for (k, c) in clusters.iter().enumerate() {
            members.extend(c);
            cluster_start.push(members.len() as u32);
            for &m in c {
                of[m as usize].push(k as u32);
            }
        }
        let mut particle_start = vec![0];
        let mut particle_clusters = vec![];
        for list in of {
            particle_clusters.extend(list);
            particle_start.push(particle_clusters.len() as u32);
        }
        [cluster_start, members, particle_start, particle_clusters]
    }

    #[test]
    fn colouring_by_bits_makes_the_greedy_choice() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (mut fitted, mut overflowed) = (false, false);
        for case in 0..200 {
            let n = rng.random_range(1..60);
            let clusters: Vec<Vec<u32>> = (0..rng.random_range(0..300))
                .map(|_| {
                    let mut c: Vec<u32> = (0..rng.random_range(1..8))
                        .map(|_| rng.random_range(0..n))
                        .collect();
                    c.sort_unstable();
                    c.dedup();
                    c
                })
                .collect();
            let [cs, m, ps, pc] = csr(&clusters, n as usize);
            let greedy = colour_clusters(&cs, &m, &ps, &pc);
            assert_eq!(colour_clusters_by_lists(&cs, &m, n as usize), greedy);
            match colour_clusters_by_bits(&cs, &m, n as usize) {
                Some((colours, bits)) => {
                    fitted = true;
                    assert_eq!(colours, greedy, "case {case}");
                    for p in 0..n {
                        let expected = clusters
                            .iter()
                            .zip(&colours)
                            .filter(|(c, _)| c.contains(&p))
                            .fold(0u64, |b, (_, colour)| b | 1 << colour);
                        assert_eq!(bits[p as usize], expected, "case {case}, particle {p}");
                    }
                }
                None => {
                    assert!(greedy.iter().any(|c| *c >= 64), "case {case}");
                    overflowed = true;
                }
            }
        }
        // both outcomes occurred
        assert!(fitted && overflowed);
        // 64 clusters sharing a particle fit in 64 colours; a 65th does not
        let crowded: Vec<Vec<u32>> = (0..65).map(|k| vec![0, k + 1]).collect();
        let [cs, m, ..] = csr(&crowded[..64], 66);
        assert!(colour_clusters_by_bits(&cs, &m, 66).is_some());
        let [cs, m, ..] = csr(&crowded, 66);
        assert!(colour_clusters_by_bits(&cs, &m, 66).is_none());
    }

    #[test]
    fn clusters_of_one_colour_share_no_particle() {
        // overlapping windows of 3 along a bar of 20 particles, plus a few long ones
        let mut clusters: Vec<Vec<u32>> = (0..18).map(|i| vec![i, i + 1, i + 2]).collect();
        clusters.push(vec![0, 5, 10, 15]);
        clusters.push(vec![3, 19]);
        let [cs, m, ps, pc] = csr(&clusters, 20);
        let (order, colour_start) = order_by_colour(&colour_clusters(&cs, &m, &ps, &pc), u32::MAX);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..clusters.len() as u32).collect::<Vec<_>>());
        for c in 0..colour_start.len() - 1 {
            let group = &order[colour_start[c] as usize..colour_start[c + 1] as usize];
            let mut used = [false; 20];
            for &k in group {
                for &p in &clusters[k as usize] {
                    assert!(!used[p as usize], "colour {c} shares particle {p}");
                    used[p as usize] = true;
                }
            }
        }
        // windows of 3 need at least 3 colours; greedy should not need many more
        let colours = colour_start.len() - 1;
        assert!((3..=5).contains(&colours), "{colours} colours");
    }
}
