//! A skipped test's `SKIPPED (…): NAME` line is countable however the tests run: with one test
//! thread the harness writes `test NAME ... ` before the test runs and its result after, on the
//! same stream a run's log merges stderr into. This test runs its own binary on one thread with
//! stdout and stderr into one file (as `cargo test 2>&1 | tee log` does) and counts the skip as
//! `.ci/run` and `.ci/fresh-clone` do: lines starting with `SKIPPED (` in the skip log, and in
//! the merged output too.

use std::process::{Command, Stdio};

const PROBE_ENV: &str = "MANYHANDS_SKIP_PROBE";

/// Skips when run by [`a_skip_is_one_whole_line_on_one_test_thread`] (passes at once otherwise).
#[test]
fn skip_probe() {
    if std::env::var_os(PROBE_ENV).is_some() {
        manyhands::skips::report("probe: nothing to run");
    }
}

#[test]
fn a_skip_is_one_whole_line_on_one_test_thread() {
    if std::env::var_os(PROBE_ENV).is_some() {
        return;
    }
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("manyhands-skips-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let out_path = dir.join("out.log");
    let skips = dir.join("skipped.log");
    let out = std::fs::File::create(&out_path).expect("log");
    let status = Command::new(std::env::current_exe().expect("test binary"))
        .args(["skip_probe", "--exact", "--test-threads=1"])
        .env(PROBE_ENV, "1")
        .env(manyhands::skips::SKIP_LOG_ENV, &skips)
        .stdout(Stdio::from(out.try_clone().expect("clone")))
        .stderr(Stdio::from(out))
        .status()
        .expect("run the probe");
    assert!(status.success());
    let merged = std::fs::read_to_string(&out_path).expect("output");
    let logged = std::fs::read_to_string(&skips).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    let count = |text: &str| text.lines().filter(|l| l.starts_with("SKIPPED (")).count();
    assert_eq!(
        logged.lines().collect::<Vec<_>>(),
        ["SKIPPED (probe: nothing to run): skip_probe"],
        "skip log"
    );
    assert_eq!(count(&merged), 1, "merged output:\n{merged}");
    assert!(merged.contains("test result: ok. 1 passed"), "{merged}");
}
