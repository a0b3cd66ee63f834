//! `cleave fidelity`: the comparison of cut bodies with fresh clusterings of the same
//! geometry (see [`cleave::analysis::fidelity`]), as a table or one JSON object.

use cleave::analysis::cluster_shape::ClusterShape;
use cleave::analysis::fidelity::{FidelityOptions, fidelity as compare};
use cleave::io::cut_scenes::MAX_CUTS;

/// Runs the comparison and prints it.
pub fn fidelity(options: FidelityOptions, json: bool) -> Result<(), String> {
    if !(1..=MAX_CUTS).contains(&options.cuts) {
        return Err(format!(
            "--cuts: {} is out of range (allowed 1 ≤ cuts ≤ {MAX_CUTS})",
            options.cuts
        ));
    }
    let report = compare(options).map_err(|e| e.to_string())?;
    if json {
        println!(
            "{}",
            serde_json::to_string(&report).map_err(|e| e.to_string())?
        );
        return Ok(());
    }
    let b = &report.block;
    println!(
        "32×16×16 block after {} {} cuts (seed {}): {} particles, {} pieces, {} invariant violations",
        b.cuts, report.cut_mode, report.seed, b.particles, b.pieces, b.violations
    );
    println!(
        "{:>26} {:>10} {:>10} {:>8}",
        "", "rebuilt", "fresh", "ratio"
    );
    let row = |name: &str, get: fn(&ClusterShape) -> f64, ratio: f64| {
        println!(
            "{name:>26} {:>10.3} {:>10.3} {ratio:>8.3}",
            get(&b.rebuilt),
            get(&b.fresh)
        );
    };
    row("clusters", |s| s.clusters as f64, b.ratio.clusters);
    row("mean size", |s| s.mean_size, b.ratio.mean_size);
    row(
        "memberships per particle",
        |s| s.memberships_per_particle,
        b.ratio.memberships_per_particle,
    );
    row(
        "mean extent (cells)",
        |s| s.mean_extent,
        b.ratio.mean_extent,
    );
    let c = &report.cantilever;
    println!(
        "cantilever with {} scoops ({} particles), static tip sag in h: intact {:.3}, \
         rebuilt {:.3}, fresh {:.3}, rebuilt/fresh {:.3}",
        c.scoops, c.particles, c.intact_sag_h, c.rebuilt_sag_h, c.fresh_sag_h, c.ratio
    );
    Ok(())
}
