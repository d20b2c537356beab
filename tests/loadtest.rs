//! `manyhands loadtest` against the real server: a short run with IK queries and planning jobs
//! reports throughput, only 2xx answers, and every accepted job in a final state.

mod common;
use common::server::start;
use serde_json::Value;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loadtest_drives_a_live_server_and_accounts_for_every_job() {
    let h = start("loadtest").await;
    let base = h.base.clone();
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
            .args([
                "--json",
                "loadtest",
                "--url",
                &base,
                "--clients",
                "4",
                "--duration",
                "1.5",
                "--plan-fraction",
                "0.05",
                "--threads",
                "1",
            ])
            .output()
    })
    .await
    .expect("join")
    .expect("run loadtest");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "loadtest failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: Value = serde_json::from_str(&stdout).expect("JSON report");
    let ik = r["ik"]["count"].as_u64().expect("ik count");
    assert!(ik > 50, "only {ik} IK answers in 1.5 s");
    assert_eq!(r["errors_5xx"], 0);
    assert_eq!(r["transport_errors"], 0);
    assert_eq!(r["status"]["200"].as_u64(), Some(ik), "{r}");
    let accepted = r["jobs"]["accepted"].as_u64().expect("accepted");
    assert!(accepted > 0, "no job submitted: {r}");
    let finished: u64 = r["jobs"]["final"]
        .as_object()
        .expect("final")
        .values()
        .filter_map(Value::as_u64)
        .sum();
    assert_eq!(finished, accepted, "{r}");
    assert_eq!(r["jobs"]["lost"], 0);
    assert!(r["ik"]["p99_ms"].as_f64().expect("p99") > 0.0);
}

#[test]
fn loadtest_refuses_non_loopback_urls() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args([
            "loadtest",
            "--url",
            "http://example.com:8080",
            "--duration",
            "1",
        ])
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("loopback"));
}
