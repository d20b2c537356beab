//! The contract run: Schemathesis (PyPI, the version of [`SCHEMATHESIS`]) generates requests
//! from `api/openapi.json` for every operation and checks the server's answers against it: no
//! 5xx, every status and response body as the spec documents, every schema-valid request
//! accepted or refused for a documented reason (auth, missing resource, conflict, overload:
//! 401, 404, 409, 429, 503), every schema-invalid request refused. The server runs in-process
//! on a loopback port with a token (so Schemathesis also checks that auth is not ignored);
//! the run is bounded (few examples per operation, a fixed seed, a time budget) to fit CI.
//!
//! Without Schemathesis installed, prints `SKIPPED (no schemathesis: …)` and returns, unless
//! `MANYHANDS_REQUIRE_SCHEMATHESIS=1` (set by `.ci/run`, which installs it), where it fails.

use std::io::Write;
use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use manyhands::server::{Config, Server};

/// The pinned Schemathesis (`.ci/run` installs this one).
const SCHEMATHESIS: &str = "schemathesis==4.32.5";
const REQUIRE_ENV: &str = "MANYHANDS_REQUIRE_SCHEMATHESIS";
/// Test cases per operation and phase: small, to keep the run within CI's budget.
const MAX_EXAMPLES: u32 = 12;
/// Time budget of the whole run, seconds (the run ends early when every phase is done).
const MAX_SECONDS: u32 = 90;

fn python() -> String {
    std::env::var("PYTHON").unwrap_or_else(|_| "python3".into())
}

/// The installed Schemathesis version, or why it cannot run.
fn installed() -> Result<String, String> {
    let out = Command::new(python())
        .args([
            "-c",
            "import importlib.metadata as m; print(m.version('schemathesis'))",
        ])
        .output()
        .map_err(|e| format!("cannot run {}: {e}", python()))?;
    if !out.status.success() {
        return Err("schemathesis is not installed".into());
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn schemathesis_finds_nothing() {
    let version = match installed() {
        Ok(v) => v,
        Err(why) => {
            let line = format!(
                "SKIPPED (no schemathesis: pip install {SCHEMATHESIS}): schemathesis_finds_nothing"
            );
            let required = std::env::var(REQUIRE_ENV).is_ok_and(|v| v == "1");
            assert!(!required, "{REQUIRE_ENV}=1 but {why}: {line}");
            // Past the harness's capture, as one whole line, so that a run can count it.
            let _ = std::io::stdout()
                .lock()
                .write_all(format!("{line}\n").as_bytes());
            return;
        }
    };
    let pinned = SCHEMATHESIS.trim_start_matches("schemathesis==");
    if version != pinned {
        eprintln!("schemathesis {version} installed, {pinned} pinned: running anyway");
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!(
        "manyhands-schemathesis-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("dir");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let token = "schemathesis-contract-token";
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.join("data"));
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.token = Some(token.into());
    cfg.workers = 1;
    cfg.query_threads = 2;
    // Jobs that a generated request happens to start end fast; a `wait` ends with them.
    cfg.max_plan_seconds = 1.0;
    cfg.max_queue = 8;
    cfg.shutdown_grace = Duration::from_millis(300);
    cfg.drain = Duration::ZERO;
    let server = Server::start(cfg).await.expect("server");
    let base = format!("http://{}", server.addr());
    let spec = dir.join("openapi.json");
    std::fs::write(&spec, manyhands::server::openapi::openapi_json()).expect("spec");
    // Schema-valid requests may be refused only for the reasons the spec names besides their
    // content: auth, a missing resource, a conflict with the server's state, overload.
    // Four exceptions, each documented in the spec: an uploaded robot or scene is a document
    // (URDF, SRDF, scene JSON) whose validity no schema states, a base-placement map is
    // bounded by its number of platform poses, (2⌈radius / cell⌉ + 1)² × yaw_bins, a product
    // of three fields, and grasp contacts must be geometrically sound (non-zero normals,
    // wrenches within range); and a request's joint values, group or named state must fit the
    // robot model it names (how many joints, which groups are chains, which states the SRDF
    // defines), which a schema of the request cannot state.
    std::fs::write(
        dir.join("schemathesis.toml"),
        r#"[checks.positive_data_acceptance]
expected-statuses = ["2xx", "401", "404", "409", "429", "503"]

[[operations]]
include-path-regex = "^/v1/(robots|scenes)/\\{name\\}$"
include-method = "PUT"
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "404", "409", "422", "429", "503"]

[[operations]]
include-path = "/v1/ik/base-placement"
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "404", "409", "422", "429", "503"]

[[operations]]
include-path-regex = "^/v1/(fk|ik|trajectories)$"
include-method = "POST"
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "404", "409", "422", "429", "503"]

[[operations]]
include-path = "/v1/grasp-quality"
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "404", "409", "422", "429", "503"]
"#,
    )
    .expect("config");
    let report = dir.join("report.xml");
    let args: Vec<String> = vec![
        "run".into(),
        spec.display().to_string(),
        "--url".into(),
        base.clone(),
        "--header".into(),
        format!("Authorization: Bearer {token}"),
        "--checks".into(),
        [
            "not_a_server_error",
            "status_code_conformance",
            "content_type_conformance",
            "response_headers_conformance",
            "response_schema_conformance",
            "negative_data_rejection",
            "positive_data_acceptance",
            "ignored_auth",
        ]
        .join(","),
        "--phases".into(),
        "examples,coverage,fuzzing".into(),
        "--max-examples".into(),
        MAX_EXAMPLES.to_string(),
        // Deterministic generation: the same cases every run (no seed, no example database).
        "--generation-deterministic".into(),
        "--no-shrink".into(),
        // One worker: Hypothesis' strategy descriptions are not thread-safe on every Python.
        "--workers".into(),
        "1".into(),
        "--max-time".into(),
        MAX_SECONDS.to_string(),
        "--request-timeout".into(),
        "20".into(),
        "--continue-on-failure".into(),
        "--no-color".into(),
        "--report".into(),
        "junit".into(),
        "--report-junit-path".into(),
        report.display().to_string(),
        "--warnings".into(),
        "off".into(),
    ];
    let py = python();
    let cwd = dir.clone();
    let out = tokio::task::spawn_blocking(move || {
        Command::new(py)
            .arg("-c")
            .arg("import sys; from schemathesis.cli import schemathesis; sys.argv[0] = 'schemathesis'; schemathesis()")
            .args(&args)
            .current_dir(cwd)
            .env("NO_COLOR", "1")
            .output()
    })
    .await
    .expect("join")
    .expect("run schemathesis");
    server.shutdown().await.expect("shutdown");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "schemathesis found problems (exit {:?}):\n{stdout}\n{stderr}",
        out.status.code()
    );
    // A run that tested nothing is no evidence.
    assert!(
        stdout.contains("passed") && !stdout.contains("No operations"),
        "{stdout}\n{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
