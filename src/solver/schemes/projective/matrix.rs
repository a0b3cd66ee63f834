//! Projective dynamics' global matrix: `A = M/dt² + Σₖ κₖ Eₖ + Σ_terms w AᵀA`, the
//! lower triangle of a sparse symmetric positive definite matrix.
//!
//! A cluster's energy `κ/2 Σᵢ wᵢ |xᵢ − c − R rᵢ|²` depends on its members' centre
//! `c = Σ wᵢ xᵢ / Σ wᵢ`; written in the members alone its Hessian is the dense block
//! `κ (W − w wᵀ/Σw)`, every member coupled to every other. Here the centre is an
//! unknown of its own instead (one row per cluster, after the particles' rows): the
//! energy is then a star — each member coupled to its clusters' centres only,
//! `κ wᵢ` on the member's diagonal, `−κ wᵢ` between member and centre, `κ Σw` on the
//! centre's diagonal — and minimising it over `c` gives back the same energy, so the
//! particles' solution is the same. A cluster of 27 members adds 28 entries instead of
//! 378, and the factor fills in far less: the particles, each in a few clusters, are
//! eliminated first and leave a matrix of the centres, one per cluster.

use crate::solver::clusters::term::ClusterTerm;
use crate::solver::registry::Terms;
use crate::solver::term::{NO_DENSE, Substep, Unknowns};
use faer::sparse::Triplet;

/// The global matrix's lower triangle and what it was built from.
pub(super) struct Assembly {
    pub(super) row_of: Vec<u32>,
    pub(super) particle_of: Vec<u32>,
    /// Rows of the matrix: the free particles' first, then one per cluster centre.
    pub(super) rows: usize,
    pub(super) entries: Vec<Triplet<usize, usize, f64>>,
    /// Per particle: the sum of its clusters' stiffnesses.
    pub(super) stiffness_sum: Vec<f64>,
}

/// The global matrix (lower triangle, duplicates to be summed) for the clusters, the
/// terms' projective forms and the masses `1/inv_mass`, at the substep's time step.
pub(super) fn assemble(
    clusters: &ClusterTerm,
    inv_mass: &[f32],
    terms: &Terms,
    step: &Substep,
) -> Assembly {
    let n = inv_mass.len();
    let inv_dt2 = 1.0 / (step.dt as f64 * step.dt as f64);
    let mass = |i: usize| 1.0 / inv_mass[i] as f64;
    let mut row_of = vec![NO_DENSE; n];
    let mut particle_of = Vec::new();
    for (i, &w) in inv_mass.iter().enumerate() {
        if w > 0.0 {
            row_of[i] = particle_of.len() as u32;
            particle_of.push(i as u32);
        }
    }
    let mut entries: Vec<Triplet<usize, usize, f64>> = particle_of
        .iter()
        .enumerate()
        .map(|(row, &i)| Triplet::new(row, row, mass(i as usize) * inv_dt2))
        .collect();
    let mut stiffness_sum = vec![0.0f64; n];
    let unknowns = Unknowns {
        row_of: &row_of,
        inv_mass,
    };
    // each cluster couples its members to its centre, a row of its own (module docs)
    let mut centre_rows = particle_of.len();
    for (k, members) in clusters.clusters() {
        if members.iter().all(|&m| row_of[m as usize] == NO_DENSE) {
            continue;
        }
        let kappa = unknowns.weight(clusters.compliance[k], members, step.dt);
        let centre = centre_rows;
        centre_rows += 1;
        let mut total = 0.0;
        for &m in members {
            stiffness_sum[m as usize] += kappa;
            let w = clusters.weight(m) as f64;
            total += w;
            let row = row_of[m as usize];
            if row != NO_DENSE {
                let row = row as usize;
                entries.push(Triplet::new(row, row, kappa * w));
                entries.push(Triplet::new(centre, row, -kappa * w));
            }
        }
        entries.push(Triplet::new(centre, centre, kappa * total));
    }
    let mut term_entries = Vec::new();
    for term in terms.iter() {
        if let Some(form) = term.projective() {
            form.add_hessian(step, &unknowns, &mut term_entries);
        }
    }
    entries.extend(
        term_entries
            .into_iter()
            .map(|(row, col, value)| Triplet::new(row, col, value)),
    );
    Assembly {
        row_of,
        particle_of,
        rows: centre_rows,
        entries,
        stiffness_sum,
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::body::shape::Shape;
    use crate::config::{Material, SolverMode};
    use crate::cut::tool::Pose;
    use crate::math::sparse_cholesky::SparseCholesky;
    use crate::solver::clusters::term::ClusterSpec;
    use crate::solver::term::{BodyTopology, ParticleKey, Topology};
    use crate::solver::terms::attachments::{Attachment, Attachments};
    use crate::solver::terms::edges::Edges;
    use crate::solver::testing::{TEST_DT, step};
    use faer::Conj;
    use faer::Mat;
    use faer::linalg::solvers::SolveCore;
    use glam::{UVec3, Vec3};

    /// A 4×3×3 lattice block (dense index = lattice index) with 2×2×2 clusters at every
    /// cell, compliant; particle 0 held still.
    pub(in crate::solver::schemes::projective) fn block()
    -> (crate::body::lattice::Lattice, ClusterTerm, Vec<f32>) {
        let lattice = Shape::cuboid(UVec3::new(4, 3, 3))
            .voxelise(0.1)
            .expect("a block");
        let rest: Vec<Vec3> = (0..lattice.len() as u32)
            .map(|i| lattice.rest_position(i))
            .collect();
        let mut clusters = vec![];
        for i in 0..lattice.len() as u32 {
            let c = lattice.coord(i);
            let cell: Option<Vec<u32>> = (0..8)
                .map(|b| lattice.at(c + glam::IVec3::new(b & 1, (b >> 1) & 1, b >> 2)))
                .collect();
            clusters.extend(cell);
        }
        let specs = clusters.iter().map(|m| ClusterSpec {
            members: m,
            compliance: 1e-3,
            rotation: glam::Quat::IDENTITY,
            plastic: None,
        });
        let term = ClusterTerm::new(&rest, specs, SolverMode::Projective);
        let mut inv_mass = vec![1.0; rest.len()];
        inv_mass[0] = 0.0;
        (lattice, term, inv_mass)
    }

    /// `A⁻¹ B` by the sparse factor, for the three columns of `rhs`.
    fn sparse_solve(factor: &SparseCholesky, rhs: &Mat<f64>) -> Mat<f64> {
        let mut rows: Vec<[f64; 3]> = (0..rhs.nrows())
            .map(|i| [0, 1, 2].map(|j| rhs[(i, j)]))
            .collect();
        factor.solve_in_place(&mut rows);
        Mat::from_fn(rhs.nrows(), 3, |i, j| rows[i][j])
    }

    /// The full matrix of the lower-triangle entries, summed.
    pub(in crate::solver::schemes::projective) fn dense(
        rows: usize,
        entries: &[Triplet<usize, usize, f64>],
    ) -> Mat<f64> {
        let mut a = Mat::<f64>::zeros(rows, rows);
        for e in entries {
            a[(e.row, e.col)] += e.val;
            if e.row != e.col {
                a[(e.col, e.row)] += e.val;
            }
        }
        a
    }

    #[test]
    fn the_global_matrix_is_symmetric_positive_definite_and_its_factor_solves_it() {
        let (_, clusters, inv_mass) = block();
        let a = assemble(&clusters, &inv_mass, &Terms::default(), &step(1));
        let free = a.particle_of.len();
        assert_eq!(free, inv_mass.len() - 1, "the held particle is no unknown");
        assert_eq!(
            a.rows,
            free + clusters.clusters().count(),
            "a centre per cluster"
        );
        let matrix = dense(a.rows, &a.entries);
        // positive definite: a dense Cholesky succeeds with a positive diagonal
        let llt = matrix.llt(faer::Side::Lower).expect("positive definite");
        assert!((0..a.rows).all(|i| llt.L()[(i, i)] > 0.0));
        let factor = SparseCholesky::new(a.rows, &a.entries, u64::MAX).expect("a factor");
        let rhs = Mat::<f64>::from_fn(a.rows, 3, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
        let sparse = sparse_solve(&factor, &rhs);
        let residual = (&matrix * &sparse - &rhs).norm_max();
        assert!(residual < 1e-9 * rhs.norm_max(), "{residual}");
        // eliminating the centres leaves each cluster's energy on its members alone:
        // M/dt² + Σₖ κₖ (Wₖ − wₖ wₖᵀ/Σwₖ), the members' weights summed over all members
        let inv_dt2 = 1.0 / (TEST_DT as f64 * TEST_DT as f64);
        let mut members_only = Mat::<f64>::zeros(free, free);
        for (row, &i) in a.particle_of.iter().enumerate() {
            members_only[(row, row)] += inv_dt2 / inv_mass[i as usize] as f64;
        }
        for (k, members) in clusters.clusters() {
            let kappa = 1.0 / clusters.compliance[k] as f64;
            let total: f64 = members.iter().map(|&m| clusters.weight(m) as f64).sum();
            for &p in members {
                for &q in members {
                    let (rp, rq) = (a.row_of[p as usize], a.row_of[q as usize]);
                    if rp == NO_DENSE || rq == NO_DENSE {
                        continue;
                    }
                    let (wp, wq) = (clusters.weight(p) as f64, clusters.weight(q) as f64);
                    let diagonal = if p == q { wp } else { 0.0 };
                    members_only[(rp as usize, rq as usize)] +=
                        kappa * (diagonal - wp * wq / total);
                }
            }
        }
        let (xx, xc, cc) = (
            matrix.submatrix(0, 0, free, free),
            matrix.submatrix(0, free, free, a.rows - free),
            matrix.submatrix(free, free, a.rows - free, a.rows - free),
        );
        let mut cc_inverse_cx = xc.transpose().to_owned();
        cc.llt(faer::Side::Lower)
            .expect("positive definite")
            .solve_in_place_with_conj(Conj::No, cc_inverse_cx.as_mut());
        let schur = xx - xc * &cc_inverse_cx;
        let difference = (&schur - &members_only).norm_max();
        assert!(difference < 1e-9 * members_only.norm_max(), "{difference}");
    }

    #[test]
    fn the_matrix_holds_the_attachments_and_edges_as_their_own_forms_give_them() {
        let (lattice, clusters, inv_mass) = block();
        let dense_map: Vec<u32> = (0..lattice.len() as u32).collect();
        let material = Material {
            edge_compliance: Some(2e-5),
            ..Material::default()
        };
        let body = BodyTopology {
            id: 7,
            lattice: &lattice,
            dense: &dense_map,
            material: &material,
            groups: &Default::default(),
            pieces: 1,
            changed: true,
        };
        let topology = Topology {
            bodies: &[body],
            relaid: true,
        };
        let mut terms = Terms::builtin();
        terms.topology(&topology);
        // a soft attachment of the far end (x = 1), one of compliance 1e-3 m/N
        let far: Vec<u32> = (0..lattice.len() as u32)
            .filter(|&i| lattice.coord(i).x == 1)
            .collect();
        let attachment = Attachment {
            particles: far
                .iter()
                .map(|&local| ParticleKey { body: 7, local })
                .collect(),
            offsets: far.iter().map(|&i| lattice.rest_position(i)).collect(),
            compliance: 1e-3,
            from: Pose::at(Vec3::ZERO),
            to: Pose::at(Vec3::ZERO),
            velocity: None,
        };
        let attachments = terms.get_mut::<Attachments>().expect("built in");
        attachments.set(vec![attachment], &topology);
        let edges = terms.get::<Edges>().expect("built in");
        assert_eq!(edges.len(), 3 * 3 * 3 + 4 * 2 * 3 + 4 * 3 * 2);
        // the dense matrix from scratch: masses, clusters (as the cluster term alone
        // gives them), and each term's constraints by their definitions
        let without = assemble(&clusters, &inv_mass, &Terms::default(), &step(1));
        let rows = without.rows;
        let mut expected = dense(rows, &without.entries);
        let row = |i: u32| without.row_of[i as usize];
        for (a, b, rest, compliance) in edges.iter() {
            assert!((rest - 0.1).abs() < 1e-6 && (compliance - 2e-4).abs() < 1e-9);
            let w = 1.0 / compliance as f64;
            for (i, j, sign) in [(a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)] {
                if row(i) != NO_DENSE && row(j) != NO_DENSE {
                    expected[(row(i) as usize, row(j) as usize)] += sign * w;
                }
            }
        }
        for &i in &far {
            expected[(row(i) as usize, row(i) as usize)] += 1.0 / 1e-3f32 as f64;
        }
        let with = assemble(&clusters, &inv_mass, &terms, &step(1));
        let matrix = dense(rows, &with.entries);
        let difference = (&matrix - &expected).norm_max();
        assert!(difference < 1e-9 * expected.norm_max(), "{difference}");
        // and the sparse factor solves it as a dense solve does
        let factor = SparseCholesky::new(rows, &with.entries, u64::MAX).expect("a factor");
        let rhs = Mat::<f64>::from_fn(rows, 3, |i, j| ((i * 5 + j) % 7) as f64 - 3.0);
        let sparse = sparse_solve(&factor, &rhs);
        let mut reference = rhs.clone();
        expected
            .llt(faer::Side::Lower)
            .expect("positive definite")
            .solve_in_place_with_conj(Conj::No, reference.as_mut());
        let error = (&sparse - &reference).norm_max();
        assert!(error < 1e-9 * reference.norm_max(), "{error}");
    }
}
