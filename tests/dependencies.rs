//! The README states how many crates the bare library pulls in; this keeps the
//! statement true (and shows when a change adds dependencies).

use std::process::Command;

#[test]
fn the_readme_states_the_bare_librarys_dependency_count() {
    let manifest = env!("CARGO_MANIFEST_DIR");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "tree",
            "-e",
            "normal",
            "--prefix",
            "none",
            "--no-dedupe",
            "--offline",
        ])
        .current_dir(manifest)
        .output()
        .expect("run cargo tree");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut lines: Vec<&str> = std::str::from_utf8(&out.stdout)
        .expect("utf-8")
        .lines()
        .filter(|l| !l.trim().is_empty())
        .collect();
    lines.sort_unstable();
    lines.dedup();
    let readme = std::fs::read_to_string(format!("{manifest}/README.md")).expect("README");
    let stated = readme
        .split("pull in no command-line or picture crates: ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse::<usize>().ok())
        .expect("the README states a count");
    assert_eq!(lines.len(), stated, "update the README's crate count");
}
