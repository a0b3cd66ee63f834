//! The local update's tests: against a full extraction after every kind of cut, and
//! the crush check's volume terms it carries over, and what a save may hold of them.

use super::*;
use crate::body::crossings::Crossing;
use crate::body::lattice::NEIGHBOUR_OFFSETS;
use crate::surface::extract::{extract, work_out_volume_changes};
use rand::{Rng, SeedableRng};

/// The surface as what does not depend on numbering: per vertex, its rest place,
/// its bindings and the quad corners (quad face, corner) it joins; per quad face,
/// its piece.
fn canonical(t: &SurfaceTopology) -> (Vec<String>, Vec<String>) {
    let mut slots: Vec<Vec<(IVec3, u8, usize)>> = vec![Vec::new(); t.vertex_count()];
    let mut pieces = Vec::new();
    for (q, quad) in t.quads.iter().enumerate() {
        let [a, b, c] = t.triangles[2 * q];
        let d = t.triangles[2 * q + 1][2];
        for (k, v) in [a, b, c, d].into_iter().enumerate() {
            slots[v as usize].push((quad.cell, quad.direction, k));
        }
        assert_eq!(t.triangle_piece[2 * q], t.triangle_piece[2 * q + 1]);
        pieces.push(format!(
            "{:?} {} {}",
            quad.cell,
            quad.direction,
            t.triangle_piece[2 * q]
        ));
    }
    let mut vertices: Vec<String> = (0..t.vertex_count())
        .map(|v| {
            let mut s = slots[v].clone();
            s.sort_by_key(|(c, d, k)| (c.x, c.y, c.z, *d, *k));
            let mut b: Vec<(u32, i32)> = t
                .bindings_of(v)
                .iter()
                .map(|b| (b.particle, (b.weight * 1e4).round() as i32))
                .collect();
            b.sort_unstable();
            format!("{:?} {:?} {:?}", (t.rest[v] * 1e4).round(), b, s)
        })
        .collect();
    vertices.sort();
    pieces.sort();
    (vertices, pieces)
}

#[test]
fn a_local_update_is_the_full_extraction_after_every_kind_of_cut() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(51);
    let mut updates = 0;
    for case in 0..40 {
        let dims = IVec3::new(
            rng.random_range(3..10),
            rng.random_range(3..10),
            rng.random_range(3..10),
        );
        let coords: Vec<IVec3> = (0..dims.x * dims.y * dims.z)
            .map(|k| IVec3::new(k % dims.x, k / dims.x % dims.y, k / dims.x / dims.y))
            .filter(|_| rng.random_bool(0.9))
            .collect();
        let Ok(mut lattice) = Lattice::from_coords(0.1, coords) else {
            continue;
        };
        // split bodies from the start in half the cases: they draw octants
        let split_first = case % 2 == 0;
        if split_first {
            let p = lattice.live_particles().next().unwrap();
            lattice.split(p, [true, false, false, false, false, false]);
        }
        let mut surface = extract(&lattice);
        for step in 0..6 {
            let live: Vec<u32> = lattice.live_particles().collect();
            let mut touched = Vec::new();
            for _ in 0..rng.random_range(1..6) {
                let p = live[rng.random_range(0..live.len())];
                if !lattice.is_live(p) {
                    continue;
                }
                match rng.random_range(0..3) {
                    0 => {
                        lattice.remove(p);
                        touched.push(p);
                    }
                    1 => {
                        if let Some(q) = lattice.neighbours(p).next() {
                            lattice.sever(p, q);
                            lattice.set_crossing(p, q, random_crossing(&mut rng));
                            touched.extend([p, q]);
                        }
                    }
                    _ if split_first => {
                        // the edges on one side of a blade, as the cut plans them
                        let n = glam::Vec3::new(
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                        );
                        let moves: [bool; 6] =
                            std::array::from_fn(|d| NEIGHBOUR_OFFSETS[d].as_vec3().dot(n) > 0.0);
                        if let Some(q) = lattice.split(p, moves) {
                            touched.extend([p, q]);
                        }
                    }
                    _ => {}
                }
            }
            let full = extract(&lattice);
            match update(&lattice, surface.clone(), &touched) {
                Some(local) => {
                    let (a, b) = (canonical(&local), canonical(&full));
                    let only = |x: &[String], y: &[String]| -> Vec<String> {
                        x.iter()
                            .filter(|s| !y.contains(s))
                            .take(3)
                            .cloned()
                            .collect()
                    };
                    assert!(
                        a == b,
                        "case {case} step {step} res {}: local only {:?} / full only {:?}; pieces local only {:?} / full only {:?}",
                        full.resolution,
                        only(&a.0, &b.0),
                        only(&b.0, &a.0),
                        only(&a.1, &b.1),
                        only(&b.1, &a.1)
                    );
                    updates += 1;
                }
                None => assert_ne!(full.resolution, surface.resolution),
            }
            surface = full;
        }
    }
    assert!(updates > 150, "{updates} local updates checked");
}

/// A blade's crossing of an edge, at random: the cut faces there rest on it.
fn random_crossing(rng: &mut impl Rng) -> Crossing {
    let normal = glam::Vec3::from_array(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
    let fraction = rng.random_range(0.1..0.9);
    Crossing {
        fraction,
        normal: normal.normalize(),
    }
}

#[test]
fn the_volume_terms_a_local_update_carries_over_are_those_of_its_places() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(52);
    let mut placed = 0;
    for case in 0..20 {
        let n = rng.random_range(4..9);
        let coords: Vec<IVec3> = (0..n * n * n)
            .map(|k| IVec3::new(k % n, k / n % n, k / n / n))
            .collect();
        let Ok(mut lattice) = Lattice::from_coords(0.1, coords) else {
            continue;
        };
        if case % 2 == 0 {
            lattice.split(0, [true, false, false, false, false, false]);
        }
        let mut surface = extract(&lattice);
        for step in 0..6 {
            // severed links with a blade's crossings: the cut faces rest on them
            let mut touched = Vec::new();
            let live: Vec<u32> = lattice.live_particles().collect();
            for _ in 0..rng.random_range(1..6) {
                let p = live[rng.random_range(0..live.len())];
                let Some(q) = lattice.neighbours(p).next() else {
                    continue;
                };
                lattice.sever(p, q);
                assert!(lattice.set_crossing(p, q, random_crossing(&mut rng)));
                touched.extend([p, q]);
            }
            let local = update(&lattice, surface, &touched).expect("a local update");
            let mut afresh = local.clone();
            afresh.volume_change.clear();
            let scale = lattice.spacing() / local.resolution as f32;
            work_out_volume_changes(&mut afresh, scale);
            assert_eq!(
                local.volume_change, afresh.volume_change,
                "case {case} step {step}"
            );
            placed += local.volume_change.iter().filter(|c| **c != 0.0).count();
            // (the next update carries over this one's terms)
            surface = local;
        }
    }
    assert!(placed > 1000, "{placed} triangles placed on cuts");
}

#[test]
fn a_saved_surface_whose_placements_do_not_match_its_vertices_is_refused() {
    let lattice = Lattice::from_coords(0.1, vec![IVec3::ZERO, IVec3::X]).unwrap();
    let mut surface = extract(&lattice);
    assert_eq!(surface.fault(lattice.len()), None);
    // (an old save kept none: read as the rest places)
    surface.placed.clear();
    assert_eq!(surface.fault(lattice.len()), None);
    surface.placed = vec![glam::Vec3::ZERO; surface.rest.len() - 1];
    assert!(surface.fault(lattice.len()).is_some());
    surface.placed = vec![glam::Vec3::NAN; surface.rest.len()];
    assert!(surface.fault(lattice.len()).is_some());
}

/// A slice through the middle of a box, its surface extracted before: the local update
/// edits the surface's lists where they lie (their room takes the cut faces), so that a
/// cut frame first-touches no copy of them; and it is still the full extraction.
#[test]
fn a_slice_is_spliced_into_the_extracted_lists_where_they_lie() {
    let n = 12;
    let coords = (0..n * n * n).map(|k| IVec3::new(k % n, k / n % n, k / n / n));
    let mut lattice = Lattice::from_coords(0.1, coords.collect()).unwrap();
    let surface = extract(&lattice);
    let at = |t: &SurfaceTopology| {
        [
            t.rest.as_ptr() as usize,
            t.corners.as_ptr() as usize,
            t.binding_start.as_ptr() as usize,
            t.bindings.as_ptr() as usize,
            t.quads.as_ptr() as usize,
            t.triangles.as_ptr() as usize,
            t.volume_change.as_ptr() as usize,
        ]
    };
    let before = at(&surface);
    let mut touched = Vec::new();
    for p in lattice.live_particles().collect::<Vec<_>>() {
        let c = lattice.coord(p) - lattice.coord(0);
        if c.x == n / 2 - 1 {
            let q = lattice.at(lattice.coord(p) + IVec3::X).unwrap();
            lattice.sever(p, q);
            touched.extend([p, q]);
        }
    }
    let local = update(&lattice, surface, &touched).unwrap();
    assert_eq!(at(&local), before);
    assert!(canonical(&local) == canonical(&extract(&lattice)));
}
