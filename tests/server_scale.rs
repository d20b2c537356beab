//! The job store is the record, not memory, in both modes (embedded and PostgreSQL):
//! `GET /v1/plans` pages over 10 000 records quickly, a restart reads no result into memory,
//! and 50 jobs with 20 MB results leave the server's memory within 100 MB of idle.

mod job_store;
mod pg;
mod process;
#[path = "common/tmp.rs"]
mod tmp;

use std::sync::Arc;
use std::time::{Duration, Instant};

use manyhands::server::api::JobState;
use manyhands::server::store::embedded::EmbeddedStore;
use manyhands::server::store::postgres::{PgOptions, PgStore};
use manyhands::server::store::{JobStore, Outcome};
use manyhands::server::{Config, Server};
use serde_json::value::RawValue;
use serde_json::{json, Value};

fn temp_dir(name: &str) -> std::path::PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let d = tmp::run_root().join(format!(
        "manyhands-scale-{name}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

const RECORDS: usize = 10_000;

/// Fills `store` with `RECORDS` finished jobs of two kinds (a small result each).
async fn fill(store: Arc<dyn JobStore>) {
    let t0 = Instant::now();
    let base = job_store::now_ms() - RECORDS as u64;
    let mut tasks = Vec::new();
    for lane in 0..8 {
        let store = store.clone();
        tasks.push(tokio::spawn(async move {
            for i in (lane..RECORDS).step_by(8) {
                let kind = if i % 2 == 0 {
                    "joint_space"
                } else {
                    "collision_sweep"
                };
                let id = format!("j{i:016x}");
                let nj = job_store::new_job(&id, kind, base + i as u64, 0, 1);
                store.enqueue(&nj, usize::MAX).await.expect("enqueue");
                let result =
                    RawValue::from_string(format!("{{\"n\":{i},\"x\":[0.1,0.2]}}")).expect("raw");
                let o = Outcome {
                    state: JobState::Succeeded,
                    result: Some(result),
                    error: None,
                    progress: None,
                    finished_ms: job_store::now_ms(),
                };
                assert!(store.finish(&id, None, &o).await.expect("finish"));
            }
        }));
    }
    for t in tasks {
        t.await.expect("fill task");
    }
    eprintln!(
        "{RECORDS} records written in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
}

/// The first page's answer time (median of 5) through a server on `cfg`, and that the pages
/// cover every record exactly once.
async fn first_page_ms(cfg: Config) -> f64 {
    let server = Server::start(cfg).await.expect("server");
    let base = format!("http://{}", server.addr());
    let http = reqwest::Client::new();
    let mut times = Vec::new();
    for _ in 0..5 {
        let t0 = Instant::now();
        let r = http
            .get(format!("{base}/v1/plans?limit=100"))
            .send()
            .await
            .expect("GET");
        assert_eq!(r.status(), reqwest::StatusCode::OK);
        let v: Value = r.json().await.expect("json");
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        assert_eq!(v["jobs"].as_array().map(|a| a.len()), Some(100));
        assert!(v["next_cursor"].is_string());
    }
    // Filtered and walked to the end: every record once.
    let mut seen = 0;
    let mut cursor = String::new();
    loop {
        let r: Value = http
            .get(format!(
                "{base}/v1/plans?limit=1000&kind=joint_space&state=succeeded{cursor}"
            ))
            .send()
            .await
            .expect("GET")
            .json()
            .await
            .expect("json");
        let jobs = r["jobs"].as_array().expect("jobs");
        assert!(jobs.iter().all(|j| j["kind"] == "joint_space"));
        seen += jobs.len();
        match r["next_cursor"].as_str() {
            Some(c) => cursor = format!("&cursor={c}"),
            None => break,
        }
    }
    assert_eq!(seen, RECORDS / 2);
    server.shutdown().await.expect("shutdown");
    times.sort_by(f64::total_cmp);
    times[2]
}

fn config(dir: &std::path::Path) -> Config {
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.to_path_buf());
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.workers = 1;
    cfg.query_threads = 1;
    cfg.drain = Duration::ZERO;
    cfg
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_pages_10000_records_fast_embedded() {
    let dir = temp_dir("list");
    let store = EmbeddedStore::open(&dir.join("jobs.redb")).expect("open");
    let store: Arc<dyn JobStore> = Arc::new(store);
    fill(store.clone()).await;
    store.close().await;
    drop(store);
    let ms = first_page_ms(config(&dir)).await;
    eprintln!("embedded: first page of 100 over {RECORDS} records in {ms:.2} ms (median of 5)");
    assert!(ms <= 50.0, "{ms} ms");
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_pages_10000_records_fast_postgres() {
    let Some(cluster) = pg::PgCluster::start("list_pages_10000_records_fast_postgres") else {
        return;
    };
    let store = PgStore::connect(&cluster.url(), PgOptions::default())
        .await
        .expect("connect");
    let store: Arc<dyn JobStore> = Arc::new(store);
    fill(store.clone()).await;
    store.close().await;
    drop(store);
    let dir = temp_dir("listpg");
    let mut cfg = config(&dir);
    cfg.store = Some(cluster.url());
    let ms = first_page_ms(cfg).await;
    eprintln!("postgres: first page of 100 over {RECORDS} records in {ms:.2} ms (median of 5)");
    assert!(ms <= 50.0, "{ms} ms");
    let _ = std::fs::remove_dir_all(dir);
}

/// Resident memory of a process, in MiB.
fn rss_mib(pid: u32) -> f64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map(|kb| kb / 1024.0)
        .unwrap_or(0.0)
}

/// A joint-space plan whose trajectory, sampled every millisecond at 1/400 of the robot's
/// speed, makes a result of about 20 MB.
fn big(seed: u64) -> Value {
    json!({"kind": "joint_space", "scene": "empty", "time_limit": 20, "seed": seed,
           "sample_period": 0.001, "velocity_scaling": 0.0025,
           "robots": [{"name": "armar", "group": "right_arm",
                       "goal": {"right_elbow": -1.0, "right_shoulder_1": -0.4}}]})
}

/// 50 jobs with ~20 MB results through the real binary: afterwards its memory is within
/// 100 MB of what it was idle; restarted on the same store, it reads no result at start.
async fn memory_stays_flat(extra: &[&str], name: &str) {
    let dir = temp_dir(name);
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(120))
        .build()
        .expect("client");
    let p = process::spawn(&dir, extra);
    let pid = p.child.id();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let idle = rss_mib(pid);
    let mut ids = Vec::new();
    for seed in 0..50 {
        let r = http
            .post(format!("http://{}/v1/plans", p.addr))
            .json(&big(seed))
            .send()
            .await
            .expect("POST");
        assert_eq!(r.status(), reqwest::StatusCode::ACCEPTED);
        let v: Value = r.json().await.expect("json");
        ids.push(v["id"].as_str().expect("id").to_string());
    }
    let mut peak = idle;
    let mut bytes = 0u64;
    for id in &ids {
        loop {
            let r = http
                .get(format!("http://{}/v1/plans/{id}?wait=2", p.addr))
                .send()
                .await
                .expect("GET");
            peak = peak.max(rss_mib(pid));
            let text = r.text().await.expect("body");
            let v: Value = serde_json::from_str(&text).expect("json");
            if v["state"] == "succeeded" {
                bytes += text.len() as u64;
                break;
            }
            assert!(v["state"] == "running" || v["state"] == "queued", "{v}");
        }
    }
    // Reading the results back goes through memory too; let the threads go idle.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let after = rss_mib(pid);
    eprintln!(
        "{name}: idle {idle:.0} MiB, peak {peak:.0} MiB, after 50 jobs ({:.0} MB of results) {after:.0} MiB",
        bytes as f64 / 1e6
    );
    assert!(bytes > 50 * 15_000_000, "results of {bytes} bytes");
    assert!(
        after - idle <= 100.0,
        "idle {idle:.0} MiB, after {after:.0} MiB"
    );
    drop(p);
    // A restart reads no result: its memory is as at the first start.
    let p = process::spawn(&dir, extra);
    tokio::time::sleep(Duration::from_millis(500)).await;
    let restarted = rss_mib(p.child.id());
    eprintln!("{name}: restarted with them stored: {restarted:.0} MiB");
    assert!(
        restarted - idle <= 100.0,
        "idle {idle:.0} MiB, restarted {restarted:.0} MiB"
    );
    let r = http
        .get(format!("http://{}/v1/plans/{}", p.addr, ids[0]))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), reqwest::StatusCode::OK);
    drop(p);
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn memory_stays_flat_with_large_results_embedded() {
    memory_stays_flat(&[], "memory-embedded").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn memory_stays_flat_with_large_results_postgres() {
    let Some(cluster) = pg::PgCluster::start("memory_stays_flat_with_large_results_postgres")
    else {
        return;
    };
    let url = cluster.url();
    memory_stays_flat(&["--store", &url], "memory-postgres").await;
}
