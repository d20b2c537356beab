//! The Python SDK (`api/python`) against the real server: starts a server on an ephemeral
//! loopback port and runs the SDK's unittest suite with `MANYHANDS_REQUIRE_SERVER=1`, so the
//! suite cannot skip itself. Needs `python3` (≥ 3.9, standard library only); `.ci/run` installs
//! it on a machine that lacks it. Without python3 the test fails unless
//! `MANYHANDS_SKIP_PYTHON=1` is set.

mod common;
use common::server::start;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_sdk_suite_passes_against_a_live_server() {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let found = std::process::Command::new(&python)
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !found {
        assert!(
            std::env::var("MANYHANDS_SKIP_PYTHON").as_deref() == Ok("1"),
            "{python} not found: install Python ≥ 3.9 (or set MANYHANDS_SKIP_PYTHON=1)"
        );
        return;
    }
    let h = start("python-sdk").await;
    let dir = common::root().join("api").join("python");
    let base = h.base.clone();
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(python)
            .args(["-m", "unittest", "discover", "-v", "-s", "tests"])
            .current_dir(dir)
            .env("MANYHANDS_URL", base)
            .env("MANYHANDS_REQUIRE_SERVER", "1")
            .env_remove("MANYHANDS_TOKEN")
            .output()
    })
    .await
    .expect("join")
    .expect("run python");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "Python SDK tests failed:\n{err}");
    assert!(!err.contains("skipped"), "tests were skipped:\n{err}");
    // Every test of the suite ran (one line "… ok" each).
    let ran = err.lines().filter(|l| l.ends_with(" ok")).count();
    assert!(ran >= 6, "only {ran} Python tests ran:\n{err}");
}

/// `pip install api/python` builds from the source folder without writing into it (no `build/`,
/// no `*.egg-info`): the pyproject build backend is flit_core. Installs into a temporary
/// `--target`, so the machine's Python is left as it was. Needs pip and the package index.
#[test]
fn pip_install_leaves_the_source_folder_clean() {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let has_pip = std::process::Command::new(&python)
        .args(["-m", "pip", "--version"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !has_pip {
        assert!(
            std::env::var("MANYHANDS_SKIP_PYTHON").as_deref() == Ok("1"),
            "{python} -m pip not found: install pip (or set MANYHANDS_SKIP_PYTHON=1)"
        );
        return;
    }
    let src = common::root().join("api").join("python");
    let listing = || -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&src)
            .expect("api/python")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let before = listing();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let target = std::env::temp_dir().join(format!("manyhands-pip-{}-{nanos}", std::process::id()));
    let out = std::process::Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-cache-dir",
            "--target",
        ])
        .arg(&target)
        .arg(&src)
        .output()
        .expect("run pip");
    assert!(
        out.status.success(),
        "pip install api/python failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(target.join("manyhands_client").join("py.typed").is_file());
    let after = listing();
    let _ = std::fs::remove_dir_all(&target);
    assert_eq!(before, after, "pip install wrote into api/python");
    assert!(
        !after
            .iter()
            .any(|n| n == "build" || n.ends_with(".egg-info")),
        "{after:?}"
    );
}
