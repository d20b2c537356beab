//! A result acknowledged as `succeeded` survives a crash: the real `manyhands serve` binary is
//! killed with SIGKILL right after it answered `succeeded`, restarted on the same data folder,
//! and must serve the very same job, byte for byte.

mod process;
#[path = "common/tmp.rs"]
mod tmp;

use std::time::Duration;

use process::spawn;
use serde_json::{json, Value};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_succeeded_answer_survives_kill_9_byte_identical() {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let data = tmp::run_root().join(format!(
        "manyhands-durability-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&data).expect("dir");
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .expect("client");
    const ROUNDS: usize = 60;
    let mut acknowledged = Vec::new();
    for round in 0..ROUNDS {
        let mut p = spawn(&data, &[]);
        // A short sweep: its result has floats with all 17 digits (fractions, milliseconds).
        let body = json!({"kind": "collision_sweep", "scene": "kitchen",
                          "samples": 3000 + round as u64, "seed": round as u64, "time_limit": 20});
        let r = http
            .post(format!("http://{}/v1/plans?wait=30", p.addr))
            .json(&body)
            .send()
            .await
            .expect("POST");
        assert_eq!(r.status(), reqwest::StatusCode::OK);
        let bytes = r.bytes().await.expect("body");
        // SIGKILL at once: no shutdown, no flush.
        p.child.kill().expect("kill -9");
        p.child.wait().expect("reap");
        let job: Value = serde_json::from_slice(&bytes).expect("job JSON");
        assert_eq!(job["state"], "succeeded", "{job}");
        acknowledged.push((job["id"].as_str().expect("id").to_string(), bytes));
    }
    // One restart reads every acknowledged job back.
    let p = spawn(&data, &[]);
    let (mut found, mut succeeded, mut identical) = (0, 0, 0);
    for (id, served) in &acknowledged {
        let r = http
            .get(format!("http://{}/v1/plans/{id}", p.addr))
            .send()
            .await
            .expect("GET");
        if r.status() != reqwest::StatusCode::OK {
            continue;
        }
        found += 1;
        let again = r.bytes().await.expect("body");
        let job: Value = serde_json::from_slice(&again).expect("job JSON");
        if job["state"] == "succeeded" {
            succeeded += 1;
        }
        if again == *served {
            identical += 1;
        } else if identical + 1 == found {
            eprintln!(
                "job {id} differs after the restart:\n served {}\n stored {}",
                String::from_utf8_lossy(served),
                String::from_utf8_lossy(&again)
            );
        }
    }
    drop(p);
    eprintln!(
        "kill -9 rounds: {ROUNDS}, succeeded answers: {}, found after restart: {found}, \
         still succeeded: {succeeded}, byte-identical: {identical}",
        acknowledged.len()
    );
    assert_eq!(found, ROUNDS, "acknowledged jobs missing after kill -9");
    assert_eq!(succeeded, ROUNDS, "acknowledged results lost by kill -9");
    assert_eq!(identical, ROUNDS, "jobs changed by the restart");
    let _ = std::fs::remove_dir_all(&data);
}
