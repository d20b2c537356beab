//! SIGTERM drains like a service behind a load balancer: `/readyz` answers 503 at once while
//! `/healthz`, `GET` and a running job's event stream keep working and new jobs get 503 +
//! `Retry-After`; the running job finishes within the grace period, then the listener closes and
//! the process exits cleanly.

mod process;
#[path = "common/tmp.rs"]
mod tmp;

use std::time::{Duration, Instant};

use process::spawn;
use reqwest::StatusCode;
use serde_json::{json, Value};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_drains_then_closes() {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let data = tmp::run_root().join(format!("manyhands-drain-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&data).expect("dir");
    let mut p = spawn(&data, &["--shutdown-grace", "4", "--drain", "2"]);
    let base = format!("http://{}", p.addr);
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(20))
        .build()
        .expect("client");
    // A job that runs for 1.5 s (its time limit), then succeeds.
    let r = http
        .post(format!("{base}/v1/plans"))
        .json(&json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 1_000_000_000u64, "time_limit": 1.5}))
        .send()
        .await
        .expect("POST");
    assert_eq!(r.status(), StatusCode::ACCEPTED);
    let id = r.json::<Value>().await.expect("job")["id"]
        .as_str()
        .expect("id")
        .to_string();
    let events = http
        .get(format!("{base}/v1/plans/{id}/events"))
        .send()
        .await
        .expect("SSE");
    assert_eq!(events.status(), StatusCode::OK);
    let sse = tokio::spawn(async move {
        let mut events = events;
        let mut text = String::new();
        while let Some(chunk) = events.chunk().await.expect("SSE chunk") {
            text.push_str(&String::from_utf8_lossy(&chunk));
            if text.contains("event: end") {
                break;
            }
        }
        text
    });
    tokio::time::sleep(Duration::from_millis(200)).await;

    let t0 = Instant::now();
    let pid = p.child.id().to_string();
    let killed = std::process::Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .expect("kill -TERM");
    assert!(killed.success());
    // Draining: not ready, alive, reads work, new jobs are refused with Retry-After.
    let mut ready_503 = None;
    while t0.elapsed() < Duration::from_secs(1) {
        let r = http
            .get(format!("{base}/readyz"))
            .send()
            .await
            .expect("readyz");
        if r.status() == StatusCode::SERVICE_UNAVAILABLE {
            ready_503 = Some(t0.elapsed());
            break;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let ready_503 = ready_503.expect("/readyz answers 503 during the drain");
    let r = http
        .get(format!("{base}/healthz"))
        .send()
        .await
        .expect("healthz");
    assert_eq!(r.status(), StatusCode::OK);
    let r = http
        .get(format!("{base}/v1/plans/{id}"))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), StatusCode::OK);
    assert_eq!(r.json::<Value>().await.expect("job")["state"], "running");
    let r = http
        .post(format!("{base}/v1/plans"))
        .json(&json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 10}))
        .send()
        .await
        .expect("POST while draining");
    assert_eq!(r.status(), StatusCode::SERVICE_UNAVAILABLE);
    assert!(r.headers().contains_key("retry-after"));
    // The running job's stream delivers its end: it finished within the grace period.
    let text = tokio::time::timeout(Duration::from_secs(5), sse)
        .await
        .expect("SSE ends")
        .expect("SSE task");
    let end = text
        .split("event: end")
        .nth(1)
        .and_then(|t| t.lines().find_map(|l| l.strip_prefix("data: ")))
        .expect("end event data");
    let job: Value = serde_json::from_str(end).expect("end job");
    assert_eq!(job["state"], "succeeded", "{job}");
    let ended = t0.elapsed();
    let r = http
        .get(format!("{base}/v1/plans/{id}"))
        .send()
        .await
        .expect("GET after the job ended");
    assert_eq!(r.status(), StatusCode::OK);
    // Then the listener closes and the process exits 0.
    let mut closed = None;
    while t0.elapsed() < Duration::from_secs(8) {
        match http.get(format!("{base}/healthz")).send().await {
            Err(e) if e.is_connect() => {
                closed = Some(t0.elapsed());
                break;
            }
            _ => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
    let closed = closed.expect("the listener closes after the drain");
    let status = p.child.wait().expect("exit");
    eprintln!(
        "SIGTERM: /readyz 503 after {:.1} ms, job ended at {:.0} ms, listener closed at {:.0} ms, exit {status}",
        ready_503.as_secs_f64() * 1e3,
        ended.as_secs_f64() * 1e3,
        closed.as_secs_f64() * 1e3
    );
    assert!(status.success(), "{status}");
    assert!(
        closed >= Duration::from_millis(1900),
        "drain of 2 s: {closed:?}"
    );
    let _ = std::fs::remove_dir_all(&data);
}
