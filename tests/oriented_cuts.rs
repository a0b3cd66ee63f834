//! Cuts through bodies of the oriented model (`--model oriented`): `slice`, `dice` and
//! `random` in every cut mode leave state dumps that pass the test-side checker (each
//! particle's group its live neighbourhood, rigid parts connected, pieces apart), and a
//! run is the same bit for bit on one thread and on two.
//!
//! The runs take 20 iterations per substep instead of the scenes' 10: the groups reach
//! only their neighbours, so a large block of rigid groups stiffens with iterations, and
//! at 10 the slice's block droops at the partial cut enough for its last row to slip out
//! of the blade's removal zone (one piece, in remove mode).

mod common;

use common::*;

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
