//! Test files stay under the target directory cargo uses and are removed: a server harness's
//! data folder lies under `CARGO_TARGET_TMPDIR` (not the system's temporary folder, not the
//! source tree unless the target directory is there) and is gone once the harness is dropped;
//! a run folder left by an ended process is removed by the next run. (One test in this binary:
//! the sweep runs at the process's first use of the run folder.)

mod common;

use std::path::{Path, PathBuf};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn test_files_stay_under_the_target_dir_and_are_removed() {
    let target_tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    // A run folder of a process that has ended (pid above Linux's pid_max).
    let stale = target_tmp.join("manyhands-run-4194999");
    std::fs::create_dir_all(stale.join("left-over")).expect("stale");
    let h = common::server::start("dirs").await;
    let data = h.dir.to_path_buf();
    assert!(data.starts_with(&target_tmp), "{}", data.display());
    assert!(
        !data.starts_with(std::env::temp_dir()) || target_tmp.starts_with(std::env::temp_dir())
    );
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    if !target_tmp.starts_with(manifest) {
        assert!(!data.starts_with(manifest), "{}", data.display());
    }
    if Path::new("/proc/self").exists() {
        assert!(!stale.exists(), "the ended run's folder was not removed");
    }
    // The server wrote its store there; dropping the harness removes it.
    assert!(std::fs::read_dir(&data).expect("data").next().is_some());
    h.server.shutdown().await.expect("shutdown");
    assert!(data.exists());
    let common::server::Harness { server, dir, .. } = common::server::start("dirs-2").await;
    server.shutdown().await.expect("shutdown");
    let data2 = dir.to_path_buf();
    assert!(data2.exists());
    drop(dir);
    assert!(!data2.exists(), "{} left behind", data2.display());
}
