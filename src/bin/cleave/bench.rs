//! `cleave bench`: the report of [`cleave::analysis::bench`] as a table or as JSON lines.

use cleave::analysis::bench::{
    BenchRow, CONVERGED_RESIDUAL, ConvergenceOptions, EdgeRow, bench_edges, bench_size, convergence,
};
use cleave::analysis::bench_pile::{PileRow, bench_crowd, bench_pile};
use cleave::analysis::bench_surface::bench_surface;
use cleave::config::SimConfig;

/// The contact rows: the `pile` scene at this spacing, then a crowd at the same spacing
/// (or neither).
#[derive(Clone, Copy, Debug)]
pub struct PileOptions {
    /// Lattice spacing of the pile's and the crowd's bodies; `None`: no contact row.
    pub spacing: Option<f32>,
    /// Bodies in the crowd; `None`: no crowd row.
    pub crowd: Option<usize>,
    /// Frames to step.
    pub frames: u32,
}

/// The most bodies the crowd row takes (sixteen layers of four).
const MAX_CROWD: usize = 64;

/// Benchmarks every size (ascending, so peak memory belongs to the current size), then
/// edge constraints on the largest size (unless `no_edges`), then the pile and the crowd
/// with and without contacts.
pub fn bench(
    sizes: &[u32],
    steps: usize,
    config: SimConfig,
    json: bool,
    pile: PileOptions,
    no_edges: bool,
) -> Result<(), String> {
    let sizes = checked_sizes(sizes, steps, &pile, &config)?;
    if !json {
        print_size_header(&config, steps);
    }
    for &n in &sizes {
        let row = bench_size(n, steps, &config).map_err(|e| e.to_string())?;
        if json {
            print_json(&row)?;
        } else {
            print_size_row(&row);
        }
    }
    if let (false, Some(&n)) = (no_edges, sizes.last()) {
        let row = bench_edges(n, steps, &config).map_err(|e| e.to_string())?;
        if json {
            print_json(&row)?;
        } else {
            print_edge_row(&row);
        }
    }
    if let Some(spacing) = pile.spacing {
        let mut rows = vec![bench_pile(spacing, pile.frames, &config).map_err(|e| e.to_string())?];
        if let Some(bodies) = pile.crowd {
            rows.push(
                bench_crowd(spacing, bodies, pile.frames, &config).map_err(|e| e.to_string())?,
            );
        }
        for row in &rows {
            if json {
                print_json(row)?;
            } else {
                print_pile_row(row);
            }
        }
    }
    Ok(())
}

/// The sizes asked for, ascending and each once; an error for a size past what the
/// memory budget allows, a pile spacing or crowd out of range or no timed step.
fn checked_sizes(
    sizes: &[u32],
    steps: usize,
    pile: &PileOptions,
    config: &SimConfig,
) -> Result<Vec<u32>, String> {
    if let Some(h) = pile.spacing
        && !(h.is_finite() && (0.02..=0.5).contains(&h))
    {
        return Err(format!(
            "--pile-spacing: {h} is out of range (allowed 0.02 ≤ spacing ≤ 0.5)"
        ));
    }
    if let Some(bodies) = pile.crowd
        && !(1..=MAX_CROWD).contains(&bodies)
    {
        return Err(format!(
            "--crowd-bodies: {bodies} is out of range (allowed 1 ≤ bodies ≤ {MAX_CROWD})"
        ));
    }
    if steps == 0 {
        return Err("--steps must be at least 1".into());
    }
    // the largest box one body's memory budget allows
    let budget =
        config.memory_budget_gb as f64 * 1e9 / cleave::body::shape::BYTES_PER_PARTICLE as f64;
    let largest = (budget.cbrt().floor() as u32).clamp(2, 256);
    if let Some(bad) = sizes.iter().find(|n| !(2..=largest).contains(*n)) {
        return Err(format!(
            "--sizes: {bad} is out of range (allowed 2 ≤ size ≤ {largest}: a {largest}³ box is the largest the memory budget of {} GB allows)",
            config.memory_budget_gb
        ));
    }
    let mut sizes = sizes.to_vec();
    sizes.sort_unstable();
    sizes.dedup();
    Ok(sizes)
}

/// The size table's title and column names.
fn print_size_header(config: &SimConfig, steps: usize) {
    println!(
        "cleave bench: {}, {} substeps × {} iterations, {} timed steps, {} thread(s), {} lanes",
        config.solver,
        config.substeps,
        config.iterations,
        steps,
        rayon::current_num_threads(),
        cleave::math::simd::backend()
    );
    println!(
        "{:>5} {:>9} {:>8} {:>11} {:>10} {:>9} {:>10} {:>9} {:>7} {:>8} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>11} {:>10} {:>9}",
        "size",
        "particles",
        "clusters",
        "memberships",
        "ms/step",
        "ns/m-it",
        "bare ms",
        "bare ns",
        "ratio",
        "B/part",
        "cut ms",
        "cut frame",
        "sever ms",
        "sev frame",
        "split ms",
        "spl frame",
        "recluster",
        "relayout",
        "rebuild"
    );
}

/// One size's row, and its step's time by part.
fn print_size_row(row: &BenchRow) {
    println!(
        "{:>5} {:>9} {:>8} {:>11} {:>10.3} {:>9.3} {:>10.3} {:>9.3} {:>7.3} {:>8.0} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>9.3} {:>11.3} {:>9.3}{} {:>9.3}",
        row.size,
        row.particles,
        row.clusters,
        row.memberships,
        row.ms_per_step,
        row.ns_per_membership_iteration,
        row.bare_ms_per_step,
        row.bare_ns_per_membership_iteration,
        row.engine_over_bare,
        row.bytes_per_particle,
        row.cut_event_ms,
        row.cut_frame_ms,
        row.sever_event_ms,
        row.sever_frame_ms,
        row.split_event_ms,
        row.split_frame_ms,
        row.recluster_ms,
        row.relayout_ms,
        if row.relayout_patched { "p" } else { "r" },
        row.rebuild_ms
    );
    let kinds: Vec<String> = row
        .kinds
        .iter()
        .map(|k| format!("{} {:.3}", k.name, k.ms_per_step))
        .collect();
    println!("      ms/step by part: {}", kinds.join(", "));
}

/// The edge constraints' row.
fn print_edge_row(row: &EdgeRow) {
    println!(
        "edges: {}³ box, {} edge constraints; {:.3} ms/step, edges {:.3} ms/step, \
         {:.2} ns per edge-iteration",
        row.size, row.edges, row.ms_per_step, row.edge_ms_per_step, row.ns_per_edge_iteration
    );
}

/// A contact row (the pile's or the crowd's).
fn print_pile_row(row: &PileRow) {
    println!(
        "{} (contacts): {} bodies, {} particles at h = {}, {} taking part, {} pairs; \
         {:.3} ms/step with contacts ({:.1} ns per particle-step), {:.3} without: ×{:.2}; contacts {:.2} ns per particle-iteration; \
         in the step: contacts {:.3} ms (finding pairs {:.3}, projections {:.3}), +{:.0} % on the rest; a far blade's detection {:.3} ms ({:.2} % of the step)",
        row.row,
        row.bodies,
        row.particles,
        row.spacing,
        row.contact_particles,
        row.contact_pairs,
        row.ms_per_step,
        row.ns_per_particle_step,
        row.ms_per_step_without_contacts,
        row.contacts_over_without,
        row.contact_ns_per_particle_iteration,
        row.contact_ms_per_step,
        row.contact_find_ms_per_step,
        row.contact_projection_ms_per_step,
        100.0 * row.contact_share,
        row.far_tool_detect_ms_per_step,
        100.0 * row.far_tool_detect_share
    );
}

/// `cleave bench --surface`: a surface row per size (see
/// [`cleave::analysis::bench_surface`]).
pub fn bench_surfaces(
    sizes: &[u32],
    steps: usize,
    config: &SimConfig,
    json: bool,
) -> Result<(), String> {
    if let Some(bad) = sizes.iter().find(|n| !(2..=128).contains(*n)) {
        return Err(format!(
            "--sizes: {bad} is out of range with --surface (allowed 2 ≤ size ≤ 128)"
        ));
    }
    if !json {
        println!(
            "cleave bench --surface: {} timed runs each, {} thread(s)",
            steps.max(1),
            rayon::current_num_threads()
        );
        println!(
            "{:>5} {:>9} {:>9} {:>9} {:>10} {:>10} {:>11} {:>11} {:>11} {:>9}",
            "size",
            "particles",
            "vertices",
            "triangles",
            "frame ms",
            "resting ms",
            "extract ms",
            "sliced ms",
            "sliced tris",
            "local ms"
        );
    }
    for &n in sizes {
        let row = bench_surface(n, steps, config).map_err(|e| e.to_string())?;
        if json {
            print_json(&row)?;
        } else {
            println!(
                "{:>5} {:>9} {:>9} {:>9} {:>10.3} {:>10.3} {:>11.3} {:>11.3} {:>11} {:>9.3}",
                row.size,
                row.particles,
                row.vertices,
                row.triangles,
                row.frame_ms,
                row.resting_frame_ms,
                row.extract_ms,
                row.sliced_extract_ms,
                row.sliced_triangles,
                row.local_update_ms
            );
        }
    }
    Ok(())
}

/// `cleave bench --model oriented`: each size's box in both models, in one run.
pub fn bench_models(
    sizes: &[u32],
    steps: usize,
    config: &SimConfig,
    json: bool,
) -> Result<(), String> {
    if !json {
        println!(
            "cleave bench --model oriented: {}, {} substeps × {} iterations, {} timed steps, {} thread(s)",
            config.solver,
            config.substeps,
            config.iterations,
            steps.max(1),
            rayon::current_num_threads()
        );
    }
    for &n in sizes {
        let r = cleave::analysis::bench_oriented::bench_models(n, steps, config)
            .map_err(|e| e.to_string())?;
        if json {
            print_json(&r)?;
            continue;
        }
        for m in [&r.clusters, &r.oriented] {
            println!(
                "  {n}³ {:<8}: {:>9} memberships, {:.1} ms/step, elastic part {:.1} ms/step = {:.2} ns per membership-iteration",
                m.model,
                m.memberships,
                m.ms_per_step,
                m.elastic_ms_per_step,
                m.ns_per_membership_iteration
            );
        }
        println!(
            "  {n}³ oriented/clusters per membership-iteration: {:.2}×",
            r.oriented_over_clusters
        );
    }
    Ok(())
}

/// `cleave bench --deform`: the figures of
/// [`cleave::analysis::bench_deform::bench_deform`], one run.
pub fn bench_deform(steps: usize, json: bool) -> Result<(), String> {
    let r = cleave::analysis::bench_deform::bench_deform(steps).map_err(|e| e.to_string())?;
    if json {
        return print_json(&r);
    }
    println!(
        "cleave bench --deform: {} timed runs each, {} thread(s)",
        steps.max(1),
        r.threads
    );
    println!(
        "  W precompute, 10 point handles:   16³ {:.1} ms, 32³ {:.1} ms",
        r.weights_16_ms, r.weights_32_ms
    );
    println!(
        "  V = V̄ + WΔH at 64³, 20 handles:  {:.2} ms (W interpolated from 32³ in {:.0} ms)",
        r.pose_64_ms, r.weights_64_ms
    );
    println!(
        "  full ARAP at 32³:                 {:.1} ms per iteration",
        r.arap_32_iteration_ms
    );
    println!(
        "  reduced ARAP at 64³:              {:.2} ms per frame ({} iterations, {} columns, {} groups; precompute {:.0} ms)",
        r.reduced_arap_frame_ms,
        r.reduced_iterations,
        r.reduced_columns,
        r.reduced_arap_groups,
        r.reduced_arap_precompute_ms
    );
    println!(
        "  reduced projective dynamics, 64³: {:.2} ms per frame ({} iterations, {} of {} clusters; precompute {:.0} ms)",
        r.reduced_dynamics_frame_ms,
        r.reduced_iterations,
        r.reduced_dynamics_cubature,
        r.reduced_dynamics_clusters,
        r.reduced_dynamics_precompute_ms
    );
    Ok(())
}

/// `cleave bench --cutting`: a row per workload (see
/// [`cleave::analysis::bench_cutting`]).
pub fn bench_cutting(dice: Option<u32>, json: bool) -> Result<(), String> {
    use cleave::analysis::bench_cutting::{CuttingOptions, CuttingRow, bench_cutting};
    if !json {
        println!(
            "cleave bench --cutting: whole frames (Simulation::step, surfaces on), {} thread(s); ms",
            rayon::current_num_threads()
        );
        println!(
            "{:<14} {:>6} {:>7} | {:>6} {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} | {:>6} {:>6} {:>6} {:>6} {:>6} | {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} | {:>6} {:>6} {:>6} | {:>6}",
            "workload",
            "parts",
            "plain",
            "median",
            "p95",
            "max",
            "max>1",
            "cut n",
            "median",
            "max",
            "detect",
            "cut",
            "rebuild",
            "layout",
            "surf",
            "subst",
            "work/s",
            "p95/pl",
            "max/pl",
            "cut/pl",
            "cmax/pl",
            "surf fr",
            "p95/pl",
            "max/pl",
            "cut/pl",
            "mem+"
        );
        println!(
            "(then: the same ratios for the frames less their cut work, the floor the pieces' physics sets; mem+: MB the cut frames took at their peak)"
        );
    }
    let mut failed = None;
    let mut print = |row: &CuttingRow| {
        if json {
            if let Err(e) = print_json(row) {
                failed = Some(e);
            }
            return;
        }
        let (s, floor) = (&row.cut_stages, &row.without_cut_work);
        println!(
            "{:<14} {:>6} {:>7.2} | {:>6.2} {:>6.2} {:>6.2} {:>6.2} | {:>6} {:>6.2} {:>6.2} | {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>6.2} | {:>6.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.3} | {:>6.2} {:>6.2} {:>6.2} | {:>6}",
            format!("{} {}", row.workload, row.mode),
            row.particles,
            row.plain.median_ms,
            row.all.median_ms,
            row.all.p95_ms,
            row.all.max_ms,
            row.all.max_after_first_ms,
            row.cut.frames,
            row.cut.median_ms,
            row.cut.max_ms,
            s.detect_ms,
            s.cut_ms,
            s.rebuild_ms,
            s.layout_ms,
            s.surface_ms,
            row.substeps_ms,
            row.cut_work_over_substeps,
            row.as_run.p95_over_plain,
            row.as_run.slowest_over_plain,
            row.as_run.cut_median_over_plain,
            row.as_run.cut_slowest_over_plain,
            row.surface_frame_ms,
            floor.p95_over_plain,
            floor.slowest_over_plain,
            floor.cut_median_over_plain,
            row.cut_peak_extra_mb
                .map_or("-".to_string(), |mb| format!("{mb:.0}")),
        );
    };
    let options = match dice {
        Some(n) => CuttingOptions {
            cuts: false,
            block: false,
            slice: false,
            dice: Some(n),
        },
        None => CuttingOptions::default(),
    };
    bench_cutting(options, &mut print).map_err(|e| e.to_string())?;
    failed.map_or(Ok(()), Err)
}

/// Prints `row` as one line of JSON.
fn print_json(row: &impl serde::Serialize) -> Result<(), String> {
    println!("{}", serde_json::to_string(row).map_err(|e| e.to_string())?);
    Ok(())
}

/// `cleave bench --convergence`: one row per solver (see [`convergence`]).
pub fn bench_convergence(options: ConvergenceOptions, json: bool) -> Result<(), String> {
    if !(2..=64).contains(&options.box_size) {
        return Err(format!(
            "--convergence-size: {} is out of range (allowed 2 ≤ size ≤ 64)",
            options.box_size
        ));
    }
    if !(options.budget_seconds.is_finite() && (0.1..=3600.0).contains(&options.budget_seconds)) {
        return Err(format!(
            "--budget: {} is out of range (allowed 0.1 ≤ seconds ≤ 3600)",
            options.budget_seconds
        ));
    }
    let rows = convergence(options).map_err(|e| e.to_string())?;
    if !json {
        println!(
            "convergence of static solves, material `cantilever`, {} thread(s), each to a \
             {CONVERGED_RESIDUAL:e} relative residual (net force on the particles): (a) \
             twisted {n}³ box; (b) `cantilever` from straight, to {target:.2e} (no \
             lower than twice its converged solution's, f32's floor)",
            rayon::current_num_threads(),
            n = options.box_size,
            target = rows.first().map_or(0.0, |r| r.cantilever_target_residual),
        );
        println!(
            "{:>13} {:>10} {:>11} {:>10} {:>8} {:>10} {:>11} {:>10} {:>8} {:>9}",
            "solver",
            "(a) ms",
            "iterations",
            "residual",
            "error h",
            "(b) ms",
            "iterations",
            "residual",
            "sag h",
            "static h"
        );
    }
    let cell = |v: Option<f64>| v.map_or("—".to_string(), |v| format!("{v:.1}"));
    let count = |v: Option<u32>| v.map_or("—".to_string(), |v| v.to_string());
    for row in &rows {
        if json {
            print_json(row)?;
        } else {
            println!(
                "{:>13} {:>10} {:>11} {:>10.2e} {:>8.4} {:>10} {:>11} {:>10.2e} {:>8.3} {:>9.3}",
                row.solver,
                cell(row.twisted_box_ms),
                count(row.twisted_box_iterations),
                row.twisted_box_final_residual,
                row.twisted_box_final_error_h,
                cell(row.cantilever_ms),
                count(row.cantilever_iterations),
                row.cantilever_final_residual,
                row.cantilever_final_sag_h,
                row.cantilever_static_sag_h
            );
        }
    }
    Ok(())
}
