//! The oriented model from the command line: bad fields in scene files are one error
//! line naming the file's line and column and the field, exit code 2; cuts through
//! bodies of the oriented model (`--model oriented`): `slice`, `dice` and `random` in
//! every cut mode leave state dumps that pass the test-side checker (each
//! particle's group its live neighbourhood, rigid parts connected, pieces apart), and a
//! run is the same bit for bit on one thread and on two.
//!
//! The runs take 20 iterations per substep instead of the scenes' 10: the groups reach
//! only their neighbours, so a large block of rigid groups stiffens with iterations, and
//! at 10 the slice's block droops at the partial cut enough for its last row to slip out
//! of the blade's removal zone (one piece, in remove mode).

mod common;

use common::*;

/// The minimal scene file with `material` as its body's material and `extra` fields.
fn oriented_file(material: &str, extra: &str) -> String {
    GOOD.replace(
        "spacing: 0.1, position: (0.0, 0.5, 0.0))",
        &format!("spacing: 0.1, position: (0.0, 0.5, 0.0), material: ({material}){extra})"),
    )
}

#[test]
fn bad_oriented_fields_are_one_error_line_naming_the_place() {
    let far = "(region: (min: (5.0, 5.0, 5.0), max: (6.0, 6.0, 6.0)), compliance: 0.0)";
    let cases = [
        (
            "model.ron",
            oriented_file(r#"model: "springs""#, ""),
            vec!["unknown model `springs`", "oriented"],
        ),
        (
            "radii.ron",
            oriented_file(
                r#"model: "oriented", particle_radii: Some((0.05, 0.0, 0.05))"#,
                "",
            ),
            vec!["particle_radii"],
        ),
        (
            "nan.ron",
            oriented_file(
                r#"model: "oriented", particle_radii: Some((0.05, NaN, 0.05))"#,
                "",
            ),
            vec!["particle_radii"],
        ),
        (
            "creep.ron",
            oriented_file(r#"model: "oriented", creep: 1.5"#, ""),
            vec!["creep", "0 ≤ creep ≤ 1"],
        ),
        (
            "yield.ron",
            oriented_file(r#"model: "oriented", yield_strain: -0.1"#, ""),
            vec!["yield_strain"],
        ),
        (
            "group.ron",
            oriented_file(r#"model: "oriented""#, &format!(", groups: [{far}]")),
            vec!["body.groups[0].region", "at least one"],
        ),
        (
            "region.ron",
            oriented_file("", &format!(", stiffness_regions: [{far}]")),
            vec!["body.stiffness_regions[0].region", "at least one"],
        ),
        (
            "clusters.ron",
            oriented_file(
                "",
                ", groups: [(region: (min: (-9.0, -9.0, -9.0), max: (9.0, 9.0, 9.0)), compliance: 0.0)]",
            ),
            vec!["body.groups", "oriented"],
        ),
    ];
    for (name, text, expected) in cases {
        let (code, err) = run_file(name, &text);
        eprintln!("{name}: {}", err.trim_end());
        assert_eq!(code, Some(2), "{name}: {err}");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{name}: not one line: {err}"
        );
        // file:line:col
        assert!(err.contains(&format!("{name}:")), "{name}: {err}");
        assert!(
            err.split(&format!("{name}:"))
                .nth(1)
                .is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_digit())),
            "{name}: no line: {err}"
        );
        for e in expected {
            assert!(err.contains(e), "{name}: `{e}` missing from: {err}");
        }
    }
}

#[test]
fn oriented_cuts_keep_the_dump_legal_in_every_mode() {
    for scene in ["slice", "dice", "random"] {
        for mode in ["remove", "sever", "split"] {
            let args = [
                "--model",
                "oriented",
                "--iterations",
                "20",
                "--cut-mode",
                mode,
            ];
            let (s, dump) = run_with(scene, None, &args);
            let found = check_dump(&dump);
            let (gap, _) = dump_gaps(&dump);
            let h = f(&dump["bodies"][0]["spacing"]);
            eprintln!("{scene} {mode}: {found} pieces, {} h apart", gap / h);
            assert!(found >= 2, "{scene} {mode}: the cuts part the body");
            // (the halves of a split particle rest at least SPLIT_GAP = 0.1 h apart across
            // the blade: split pieces may lie that close)
            let apart = if mode == "split" { 0.1 } else { 0.8 };
            assert!(
                gap / h >= apart,
                "{scene} {mode}: pieces {} h apart",
                gap / h
            );
            assert_eq!(s["invariant_violations"], 0, "{scene} {mode}");
        }
    }
}

#[test]
fn an_oriented_run_is_the_same_on_one_thread_and_two() {
    let dumps: Vec<String> = [1, 2]
        .iter()
        .map(|t| {
            let threads = t.to_string();
            let args = [
                "--model",
                "oriented",
                "--cut-mode",
                "split",
                "--threads",
                &threads,
            ];
            let (_, dump) = run_with("random", Some(120), &args);
            dump.to_string()
        })
        .collect();
    assert!(dumps[0] == dumps[1], "the dumps differ");
}
