//! Conservative culling is exact (SPEC §6.2): the scenes with contacts and cuts end in
//! the same state bit for bit with culling on and off (`--no-culling`), on one thread and
//! on two.

mod common;
use common::run_with;

#[test]
fn culling_changes_no_result_for_any_thread_count() {
    for scene in ["pile", "stack", "press", "random", "slice"] {
        let (_, reference) = run_with(scene, None, &["--threads", "1", "--no-culling"]);
        for extra in [
            &["--threads", "1"][..],
            &["--threads", "2"],
            &["--threads", "2", "--no-culling"],
        ] {
            let (_, dump) = run_with(scene, None, extra);
            assert!(
                dump == reference,
                "{scene} with {extra:?} differs from --threads 1 --no-culling"
            );
        }
    }
}
