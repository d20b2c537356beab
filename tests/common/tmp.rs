//! Folders for a test's files under the target directory cargo uses (`CARGO_TARGET_TMPDIR`,
//! which cargo sets for integration tests: `<target-dir>/tmp`), never in the system's temporary
//! folder or the source tree. Each test process writes under its own `manyhands-run-PID`
//! ([`run_root`]); [`TestDir`] and [`Cleanup`] remove a test's folder when dropped, and the first
//! call of a process removes the run folders of processes that have ended (what a killed or
//! failed run left). A test that panics keeps its folder (named on stderr) for a look;
//! `MANYHANDS_KEEP_TEST_DIRS=1` keeps every one.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

static NEXT: AtomicUsize = AtomicUsize::new(0);

/// The target directory's folder for test files (not removed: caches kept between runs live
/// here, e.g. `test_root().join("test-data")`).
pub fn test_root() -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
}

/// This process's folder under [`test_root`] (created on first use, after removing the run
/// folders of ended processes).
pub fn run_root() -> PathBuf {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        sweep_ended_runs();
        let p = test_root().join(format!("manyhands-run-{}", std::process::id()));
        std::fs::create_dir_all(&p).expect("create the run folder");
        p
    })
    .clone()
}

/// Removes `manyhands-run-PID` folders whose process has ended (Linux: no `/proc/PID`).
fn sweep_ended_runs() {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(rd) = std::fs::read_dir(test_root()) else {
        return;
    };
    for e in rd.flatten() {
        let name = e.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix("manyhands-run-"))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// A fresh folder, removed on drop.
#[derive(Debug)]
pub struct TestDir(PathBuf);

impl TestDir {
    /// `<target-dir>/tmp/manyhands-run-PID/NAME-N` (created empty).
    pub fn new(name: &str) -> TestDir {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let p = run_root().join(format!("{name}-{n}"));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create the test folder");
        TestDir(p)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    pub fn join(&self, p: impl AsRef<Path>) -> PathBuf {
        self.0.join(p)
    }
}

impl AsRef<Path> for TestDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl std::ops::Deref for TestDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        remove_unless_kept(&self.0);
    }
}

/// Removes `dir`, unless `MANYHANDS_KEEP_TEST_DIRS=1` or the test is panicking (then it says
/// where the files are).
fn remove_unless_kept(dir: &Path) {
    if std::env::var("MANYHANDS_KEEP_TEST_DIRS").is_ok_and(|v| v == "1") {
        return;
    }
    if std::thread::panicking() {
        eprintln!("test files kept in {}", dir.display());
        return;
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// Removes a folder made elsewhere when dropped (as [`TestDir`] does its own).
#[derive(Debug)]
pub struct Cleanup(PathBuf);

impl Cleanup {
    pub fn new(p: impl AsRef<Path>) -> Cleanup {
        Cleanup(p.as_ref().to_path_buf())
    }
}

impl Drop for Cleanup {
    fn drop(&mut self) {
        remove_unless_kept(&self.0);
    }
}
