//! Two `manyhands serve` replicas on one real PostgreSQL (started by the test as an
//! unprivileged user, see `tests/pg`): one queue, leases and fencing, events and cancel across
//! replicas, shared uploads, a replica killed with SIGKILL, a replica stalled with SIGSTOP past
//! its lease, and PostgreSQL itself stopped and started again under load.

mod pg;
mod process;
#[path = "common/tmp.rs"]
mod tmp;

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use process::{spawn, Proc};
use reqwest::StatusCode;
use serde_json::{json, Value};

fn temp_dir(name: &str) -> PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let d = tmp::run_root().join(format!(
        "manyhands-cluster-{name}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// A replica named `name` on the store `url`, with a lease of `lease` seconds.
fn replica(url: &str, name: &str, lease: &str, dir: &std::path::Path) -> Proc {
    let data = dir.join(name);
    std::fs::create_dir_all(&data).expect("data dir");
    spawn(
        &data,
        &[
            "--store",
            url,
            "--replica-id",
            name,
            "--lease-seconds",
            lease,
            "--max-queue",
            "1000",
            "--drain",
            "0",
            "--shutdown-grace",
            "1",
        ],
    )
}

/// Two replicas `a` and `b` on a fresh PostgreSQL, with a lease of `lease` seconds, and a
/// client. `None` (after a SKIPPED line) without PostgreSQL. Dropped: the replicas stop, then
/// the database, and the folder goes.
struct Cell {
    a: Proc,
    b: Proc,
    c: Client,
    pgc: pg::PgCluster,
    dir: PathBuf,
}

impl Cell {
    fn start(test: &str, lease: &str) -> Option<Cell> {
        let pgc = pg::PgCluster::start(test)?;
        let dir = temp_dir(test);
        let url = pgc.url();
        Some(Cell {
            a: replica(&url, "a", lease, &dir),
            b: replica(&url, "b", lease, &dir),
            c: Client::new(),
            pgc,
            dir,
        })
    }
}

impl Drop for Cell {
    fn drop(&mut self) {
        let _ = self.a.child.kill();
        let _ = self.b.child.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

struct Client {
    http: reqwest::Client,
}

impl Client {
    fn new() -> Client {
        Client {
            http: reqwest::Client::builder()
                .timeout(Duration::from_secs(60))
                .build()
                .expect("client"),
        }
    }

    async fn call(
        &self,
        m: reqwest::Method,
        p: &Proc,
        path: &str,
        body: Option<&Value>,
    ) -> (StatusCode, Value) {
        let mut r = self.http.request(m, format!("http://{}{path}", p.addr));
        if let Some(b) = body {
            r = r.json(b);
        }
        match r.send().await {
            Ok(r) => {
                let s = r.status();
                (s, r.json().await.unwrap_or(Value::Null))
            }
            Err(e) => panic!("{path}: {e}"),
        }
    }

    async fn post(&self, p: &Proc, path: &str, body: &Value) -> (StatusCode, Value) {
        self.call(reqwest::Method::POST, p, path, Some(body)).await
    }

    async fn get(&self, p: &Proc, path: &str) -> (StatusCode, Value) {
        self.call(reqwest::Method::GET, p, path, None).await
    }

    async fn delete(&self, p: &Proc, path: &str) -> (StatusCode, Value) {
        self.call(reqwest::Method::DELETE, p, path, None).await
    }

    async fn ready(&self, p: &Proc) -> Option<StatusCode> {
        self.http
            .get(format!("http://{}/readyz", p.addr))
            .timeout(Duration::from_secs(2))
            .send()
            .await
            .ok()
            .map(|r| r.status())
    }

    /// Polls `/readyz` until it answers `want`; fails after `within`.
    async fn wait_ready(&self, p: &Proc, want: StatusCode, within: Duration) {
        let t0 = Instant::now();
        while self.ready(p).await != Some(want) {
            assert!(
                t0.elapsed() < within,
                "/readyz not {want} within {within:?}"
            );
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }

    /// The job's event stream (from the start) until `end`: (event name, data) pairs.
    async fn events(
        &self,
        p: &Proc,
        id: &str,
        last_event_id: Option<u64>,
    ) -> Vec<(String, u64, Value)> {
        let mut r = self
            .http
            .get(format!("http://{}/v1/plans/{id}/events", p.addr))
            .timeout(Duration::from_secs(30));
        if let Some(l) = last_event_id {
            r = r.header("Last-Event-ID", l.to_string());
        }
        let text = r.send().await.expect("events").text().await.expect("text");
        let mut out = Vec::new();
        for block in text.split("\n\n") {
            let (mut name, mut id, mut data) = (String::new(), 0u64, String::new());
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("event:") {
                    name = v.trim().to_string();
                } else if let Some(v) = line.strip_prefix("id:") {
                    id = v.trim().parse().unwrap_or(0);
                } else if let Some(v) = line.strip_prefix("data:") {
                    data += v.trim_start();
                }
            }
            if !name.is_empty() {
                out.push((name, id, serde_json::from_str(&data).unwrap_or(Value::Null)));
            }
        }
        out
    }
}

fn sweep(samples: u64, seed: u64, time_limit: f64, attempts: u32) -> Value {
    json!({"kind": "collision_sweep", "scene": "kitchen", "samples": samples, "seed": seed,
           "time_limit": time_limit, "max_attempts": attempts})
}

fn plan(seed: u64, attempts: u32) -> Value {
    json!({"kind": "joint_space", "scene": "empty", "time_limit": 10, "seed": seed,
           "max_attempts": attempts,
           "robots": [{"name": "armar", "group": "right_arm",
                       "goal": {"right_elbow": -1.0, "right_shoulder_1": -0.4}}]})
}

/// Submits long jobs through `via` until one runs on replica `name` (any idle thread of either
/// replica may claim a job); cancels the others. The id of the one on `name`.
async fn long_job_on(c: &Client, via: &Proc, other: &Proc, name: &str, attempts: u32) -> String {
    for i in 0..20 {
        let (s, v) = c
            .post(via, "/v1/plans", &sweep(1_000_000_000, i, 30.0, attempts))
            .await;
        assert_eq!(s, StatusCode::ACCEPTED, "{v}");
        let id = v["id"].as_str().expect("id").to_string();
        let t0 = Instant::now();
        let mut owner = Value::Null;
        while t0.elapsed() < Duration::from_secs(5) {
            let (_, v) = c.get(other, &format!("/v1/plans/{id}")).await;
            if v["state"] == "running" {
                owner = v["replica"].clone();
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        if owner == name {
            return id;
        }
        let (_, v) = c.delete(via, &format!("/v1/plans/{id}")).await;
        assert!(final_state(v["state"].as_str().unwrap_or("")), "{v}");
    }
    panic!("replica {name} never ran one of the jobs");
}

fn final_state(s: &str) -> bool {
    matches!(s, "succeeded" | "failed" | "cancelled" | "interrupted")
}

/// 500 jobs of two kinds sent round-robin to two replicas; one replica is killed with SIGKILL
/// while jobs run. Every accepted job ends exactly once, none is run to completion twice, and
/// what was acknowledged (final answers read before the kill) is what the survivor serves.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_replicas_share_one_queue_and_survive_a_kill() {
    let Some(mut cell) = Cell::start("two_replicas_share_one_queue_and_survive_a_kill", "2") else {
        return;
    };
    let Cell { a, b, c, .. } = &mut cell;

    // An upload through one replica is usable through the other.
    let (s, scene) = c.get(a, "/v1/scenes/kitchen").await;
    assert_eq!(s, StatusCode::OK);
    let mut up = scene.clone();
    up["name"] = json!("kitchen_copy");
    let (s, v) = c
        .call(
            reqwest::Method::PUT,
            a,
            "/v1/scenes/kitchen_copy",
            Some(&up),
        )
        .await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    let (s, v) = c
        .post(
            b,
            "/v1/plans?wait=30",
            &json!({"kind": "collision_sweep", "scene": "kitchen_copy",
            "samples": 100, "time_limit": 5}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let (s, _) = c.get(b, "/v1/scenes/kitchen_copy").await;
    assert_eq!(s, StatusCode::OK);
    // A mesh uploaded through one replica is usable at once by a scene uploaded through the
    // other (a copy of the pick-and-place scene, whose statuette is that mesh).
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mesh = std::fs::read(root.join("scenes/meshes/statuette.obj")).expect("statuette");
    let r = c
        .http
        .put(format!("http://{}/v1/meshes/statuette_copy.obj", a.addr))
        .header("content-type", "application/octet-stream")
        .body(mesh)
        .send()
        .await
        .expect("PUT mesh");
    assert_eq!(r.status(), StatusCode::CREATED);
    let mut pp: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("scenes/pick_place.json")).expect("pick_place"),
    )
    .expect("json");
    pp["name"] = json!("pick_place_copy");
    for o in pp["objects"].as_array_mut().expect("objects") {
        for g in o["shapes"].as_array_mut().expect("shapes") {
            if g["path"] == "meshes/statuette.obj" {
                g["path"] = json!("meshes/statuette_copy.obj");
            }
        }
    }
    let (s, v) = c
        .call(
            reqwest::Method::PUT,
            b,
            "/v1/scenes/pick_place_copy",
            Some(&pp),
        )
        .await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    let (s, v) = c.get(b, "/v1/meshes").await;
    assert_eq!(s, StatusCode::OK);
    assert!(
        v.as_array()
            .is_some_and(|l| l.iter().any(|m| m["name"] == "statuette_copy.obj")),
        "{v}"
    );
    let r = c
        .http
        .get(format!(
            "http://{}/v1/scenes/pick_place_copy/meshes/objects/0/0",
            b.addr
        ))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), StatusCode::OK);
    let obj = r.text().await.expect("obj");
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 1312);

    const JOBS: usize = 500;
    const KILL_AT: usize = 200;
    let mut accepted: Vec<(String, u32)> = Vec::new();
    let mut acknowledged: BTreeMap<String, Value> = BTreeMap::new();
    let mut on_a: Vec<(String, u32)> = Vec::new();
    for i in 0..JOBS {
        let attempts = if i % 2 == 0 { 2 } else { 1 };
        let body = if i % 3 == 0 {
            plan(i as u64, attempts)
        } else {
            sweep(300 + i as u64, i as u64, 10.0, attempts)
        };
        let target = if i >= KILL_AT || i % 2 == 1 { &b } else { &a };
        let (s, v) = c.post(target, "/v1/plans", &body).await;
        assert_eq!(s, StatusCode::ACCEPTED, "{v}");
        accepted.push((v["id"].as_str().expect("id").to_string(), attempts));
        if i + 1 == KILL_AT {
            // Eight long jobs keep all four planner threads busy, so A runs two of them when
            // it dies: one may run again (two attempts), one may not.
            let mut long = Vec::new();
            for k in 0..8u32 {
                let attempts = if k % 2 == 0 { 2 } else { 1 };
                let (s, v) = c
                    .post(
                        a,
                        "/v1/plans",
                        &sweep(1_000_000_000, k as u64, 2.0, attempts),
                    )
                    .await;
                assert_eq!(s, StatusCode::ACCEPTED, "{v}");
                let id = v["id"].as_str().expect("id").to_string();
                accepted.push((id.clone(), attempts));
                long.push((id, attempts));
            }
            let t0 = Instant::now();
            loop {
                on_a.clear();
                for (id, attempts) in &long {
                    let (_, v) = c.get(b, &format!("/v1/plans/{id}")).await;
                    if v["state"] == "running" && v["replica"] == "a" {
                        on_a.push((id.clone(), *attempts));
                    }
                }
                if on_a.len() == 2 {
                    break;
                }
                assert!(t0.elapsed() < Duration::from_secs(20), "A runs {on_a:?}");
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            // What the clients were told before the kill: the final answers read through A.
            for (id, _) in accepted.iter().take(60) {
                let (s, v) = c.get(a, &format!("/v1/plans/{id}")).await;
                assert_eq!(s, StatusCode::OK);
                if final_state(v["state"].as_str().unwrap_or("")) {
                    acknowledged.insert(id.clone(), v);
                }
            }
            a.child.kill().expect("kill -9");
            a.child.wait().expect("reap");
        }
    }
    // Everything ends (A's leases run out after 2 s; B takes over).
    let deadline = Instant::now() + Duration::from_secs(240);
    let mut finals: BTreeMap<String, Value> = BTreeMap::new();
    while finals.len() < accepted.len() {
        assert!(
            Instant::now() < deadline,
            "{} of {} jobs final",
            finals.len(),
            accepted.len()
        );
        for (id, _) in &accepted {
            if finals.contains_key(id) {
                continue;
            }
            let (s, v) = c.get(b, &format!("/v1/plans/{id}")).await;
            assert_eq!(s, StatusCode::OK, "{id}: {v}");
            if final_state(v["state"].as_str().unwrap_or("")) {
                finals.insert(id.clone(), v);
            }
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let mut states: BTreeMap<String, usize> = BTreeMap::new();
    for (id, attempts) in &accepted {
        let v = &finals[id];
        *states
            .entry(v["state"].as_str().unwrap_or("").to_string())
            .or_insert(0) += 1;
        // Never more attempts than allowed; interrupted only when none was left.
        let started = v["attempt"].as_u64().unwrap_or(0);
        assert!(started <= *attempts as u64, "{v}");
        if v["state"] == "interrupted" {
            assert_eq!(started, *attempts as u64, "{v}");
        }
    }
    // The jobs A ran when it died: run again by B where allowed, else interrupted.
    for (id, attempts) in &on_a {
        let v = &finals[id];
        if *attempts == 2 {
            assert_eq!(v["state"], "succeeded", "{v}");
            assert_eq!(v["attempt"], 2, "{v}");
            assert_eq!(v["replica"], "b", "{v}");
        } else {
            assert_eq!(v["state"], "interrupted", "{v}");
            assert_eq!(v["replica"], "a", "{v}");
        }
    }
    assert_eq!(states.get("failed"), None, "{states:?}");
    assert!(
        states.get("succeeded").copied().unwrap_or(0) >= JOBS - 8,
        "{states:?}"
    );
    // Acknowledged answers are served unchanged by the survivor.
    for (id, v) in &acknowledged {
        assert_eq!(&finals[id], v, "{id} changed after the kill");
    }
    // Each job's record of events: one `end`, last; at most max_attempts starts; read through B.
    for (id, attempts) in accepted.iter().step_by(25) {
        let ev = c.events(b, id, Some(0)).await;
        let ends = ev.iter().filter(|e| e.0 == "end").count();
        assert_eq!(ends, 1, "{id}: {ev:?}");
        assert_eq!(ev.last().map(|e| e.0.as_str()), Some("end"));
        let starts = ev
            .iter()
            .filter(|e| e.0 == "state" && e.2["state"] == "running")
            .count();
        assert!(starts as u32 <= *attempts, "{id}: {starts} starts");
        assert_eq!(ev.last().map(|e| &e.2), Some(&finals[id]));
        let seqs: Vec<u64> = ev.iter().map(|e| e.1).collect();
        assert_eq!(seqs, (1..=seqs.len() as u64).collect::<Vec<_>>(), "{id}");
    }
    // The list pages over everything, newest first, from either replica.
    let mut seen = BTreeSet::new();
    let mut cursor: Option<String> = None;
    loop {
        let path = match &cursor {
            Some(c) => format!("/v1/plans?limit=97&cursor={c}"),
            None => "/v1/plans?limit=97".to_string(),
        };
        let (s, v) = c.get(b, &path).await;
        assert_eq!(s, StatusCode::OK, "{v}");
        for j in v["jobs"].as_array().expect("jobs") {
            assert!(seen.insert(j["id"].as_str().expect("id").to_string()));
        }
        match v["next_cursor"].as_str() {
            Some(n) => cursor = Some(n.to_string()),
            None => break,
        }
    }
    assert_eq!(seen.len(), accepted.len() + 1);
    eprintln!(
        "two replicas, {} jobs, one killed while running {on_a:?}: {states:?}",
        accepted.len()
    );
}

/// A replica stopped with SIGSTOP past its lease loses its job to the other replica; once
/// resumed its late writes are refused, and a cancel through the replica that does not run the
/// job ends it within 100 ms.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_replica_is_fenced_and_cancel_reaches_across() {
    let Some(mut cell) = Cell::start("a_stalled_replica_is_fenced_and_cancel_reaches_across", "1")
    else {
        return;
    };
    let Cell { a, b, c, .. } = &mut cell;
    // A long job with a second attempt allowed, run by A.
    let id = long_job_on(c, a, b, "a", 2).await;
    let pid = a.child.id().to_string();
    let sig = |s: &str| {
        let ok = std::process::Command::new("kill")
            .args([s, &pid])
            .status()
            .expect("kill")
            .success();
        assert!(ok, "kill {s}");
    };
    sig("-STOP");
    // B reaps the lease (1 s) and runs the second attempt.
    let t0 = Instant::now();
    let mut v = Value::Null;
    while t0.elapsed() < Duration::from_secs(10) {
        v = c.get(b, &format!("/v1/plans/{id}")).await.1;
        if v["replica"] == "b" && v["state"] == "running" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(v["replica"], "b", "{v}");
    assert_eq!(v["attempt"], 2, "{v}");
    sig("-CONT");
    // A wakes up: its lease is lost, its writes are refused; the record stays B's.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let (_, v) = c.get(a, &format!("/v1/plans/{id}")).await;
    assert_eq!(v["replica"], "b", "{v}");
    assert_eq!(v["attempt"], 2, "{v}");
    assert_eq!(v["state"], "running", "{v}");
    // Cancel through A, which does not run the job: final within 100 ms.
    let t0 = Instant::now();
    let (s, v) = c.delete(a, &format!("/v1/plans/{id}")).await;
    let took = t0.elapsed();
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["state"], "cancelled", "{v}");
    assert!(took < Duration::from_millis(100), "cancel took {took:?}");
    // B's planner thread is freed: a short job through B runs at once.
    let (s, v) = c.post(b, "/v1/plans?wait=20", &sweep(200, 1, 5.0, 1)).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let ev = c.events(b, &id, Some(0)).await;
    assert_eq!(ev.iter().filter(|e| e.0 == "end").count(), 1, "{ev:?}");
    let runs: Vec<&Value> = ev
        .iter()
        .filter(|e| e.0 == "state" && e.2["state"] == "running")
        .map(|e| &e.2["replica"])
        .collect();
    assert_eq!(runs, [&json!("a"), &json!("b")], "{ev:?}");
    // No progress of A's after B took over.
    let b_start = ev
        .iter()
        .position(|e| e.0 == "state" && e.2["replica"] == "b")
        .expect("b's start");
    assert!(ev[b_start..]
        .iter()
        .filter(|e| e.0 == "progress")
        .all(|e| e.2["state"] == "running"));
}

/// PostgreSQL stopped for 5 s under load: both replicas report not ready meanwhile, recover
/// without a restart, and lose no accepted job.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replicas_ride_out_a_database_restart() {
    let Some(mut cell) = Cell::start("replicas_ride_out_a_database_restart", "10") else {
        return;
    };
    let Cell { a, b, c, pgc, .. } = &mut cell;
    let mut accepted = Vec::new();
    for i in 0..40u64 {
        let p = if i % 2 == 0 { &a } else { &b };
        let (s, v) = c.post(p, "/v1/plans", &sweep(20_000, i, 10.0, 1)).await;
        assert_eq!(s, StatusCode::ACCEPTED, "{v}");
        accepted.push(v["id"].as_str().expect("id").to_string());
    }
    pgc.stop();
    let down = Instant::now();
    // Both report not ready within a few seconds; a submission is refused with 503.
    for p in [&a, &b] {
        c.wait_ready(p, StatusCode::SERVICE_UNAVAILABLE, Duration::from_secs(5))
            .await;
    }
    let (s, v) = c.post(a, "/v1/plans", &sweep(100, 1, 5.0, 1)).await;
    assert_eq!(s, StatusCode::SERVICE_UNAVAILABLE, "{v}");
    let rest = Duration::from_secs(5).saturating_sub(down.elapsed());
    tokio::time::sleep(rest).await;
    pgc.start_again();
    for p in [&a, &b] {
        c.wait_ready(p, StatusCode::OK, Duration::from_secs(20))
            .await;
    }
    for i in 0..10u64 {
        let p = if i % 2 == 0 { &a } else { &b };
        let (s, v) = c.post(p, "/v1/plans", &sweep(500, i, 10.0, 1)).await;
        assert_eq!(s, StatusCode::ACCEPTED, "{v}");
        accepted.push(v["id"].as_str().expect("id").to_string());
    }
    let deadline = Instant::now() + Duration::from_secs(120);
    for id in &accepted {
        loop {
            let (s, v) = c.get(a, &format!("/v1/plans/{id}?wait=5")).await;
            assert_eq!(s, StatusCode::OK, "{id} lost: {v}");
            if final_state(v["state"].as_str().unwrap_or("")) {
                assert_eq!(v["state"], "succeeded", "{v}");
                break;
            }
            assert!(Instant::now() < deadline, "{id} not final: {v}");
        }
    }
}

/// The expensive caches are shared: a grasp list built by the replica that ran the first job is
/// fetched from the store by the other replica, never built again (and the same holds for
/// reachability grids and roadmaps, which go through the same tier).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn caches_are_built_once_per_cluster() {
    let Some(mut cell) = Cell::start("caches_are_built_once_per_cluster", "5") else {
        return;
    };
    let Cell { a, b, c, dir, .. } = &mut cell;
    let req = json!({"kind": "grasp_list", "robot": "justin", "hand": "left_hand",
        "mesh": "statuette", "params": {"positions": 27, "mu": 1.0}});
    // Whichever replica runs it builds the list once…
    let (s, first) = c.post(a, "/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{first}");
    assert_eq!(first["state"], "succeeded", "{first}");
    assert_eq!(first["result"]["built"], true, "{first}");
    let builder = first["replica"].as_str().expect("replica").to_string();
    // …and the other replica, whose own cache folder is empty, finds it in the store.
    let other = if builder == "a" { "b" } else { "a" };
    assert!(
        !dir.join(other).join("grasps").exists()
            || std::fs::read_dir(dir.join(other).join("grasps"))
                .map(|d| d.count() == 0)
                .unwrap_or(true),
        "the other replica has no local copy yet"
    );
    // Stop the builder's planner threads from taking it: make it busy with long jobs.
    let busy = if builder == "a" { &a } else { &b };
    let mut long = Vec::new();
    for i in 0..2 {
        let (s, v) = c
            .post(busy, "/v1/plans", &sweep(1_000_000_000, i, 20.0, 1))
            .await;
        assert_eq!(s, StatusCode::ACCEPTED);
        long.push(v["id"].as_str().expect("id").to_string());
    }
    let t0 = Instant::now();
    loop {
        let mut on_builder = 0;
        for id in &long {
            let (_, v) = c.get(busy, &format!("/v1/plans/{id}")).await;
            if v["state"] == "running" && v["replica"] == builder.as_str() {
                on_builder += 1;
            }
        }
        if on_builder == 2 {
            break;
        }
        // The other replica took one: the builder is not yet full; add another.
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the builder never got busy"
        );
        let (_, v) = c
            .post(busy, "/v1/plans", &sweep(1_000_000_000, 9, 20.0, 1))
            .await;
        long.push(v["id"].as_str().expect("id").to_string());
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // Long jobs the other replica took are cancelled: it has a free thread, the builder none.
    for id in &long {
        let (_, v) = c.get(busy, &format!("/v1/plans/{id}")).await;
        if v["replica"] != builder.as_str() {
            let _ = c.delete(busy, &format!("/v1/plans/{id}")).await;
        }
    }
    let (s, second) = c.post(busy, "/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{second}");
    assert_eq!(second["state"], "succeeded", "{second}");
    assert_eq!(second["replica"], other, "{second}");
    assert_eq!(
        second["result"]["built"], false,
        "fetched, not rebuilt: {second}"
    );
    assert_eq!(second["result"]["id"], first["result"]["id"]);
    for id in &long {
        let _ = c.delete(busy, &format!("/v1/plans/{id}")).await;
    }
}

/// A replica shutting down (SIGTERM, as in a rolling update) gives the job it runs back to the
/// queue: the other replica runs it at once, and the attempt given back does not count.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_shutting_down_hands_its_job_over() {
    let Some(mut cell) = Cell::start("a_replica_shutting_down_hands_its_job_over", "5") else {
        return;
    };
    let Cell { a, b, c, .. } = &mut cell;
    let id = long_job_on(c, a, b, "a", 1).await;
    let ok = std::process::Command::new("kill")
        .args(["-TERM", &a.child.id().to_string()])
        .status()
        .expect("kill")
        .success();
    assert!(ok);
    let t0 = Instant::now();
    let mut v = Value::Null;
    while t0.elapsed() < Duration::from_secs(10) {
        v = c.get(b, &format!("/v1/plans/{id}")).await.1;
        if v["replica"] == "b" && v["state"] == "running" {
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert_eq!(v["replica"], "b", "{v}");
    assert_eq!(v["state"], "running", "{v}");
    assert_eq!(v["attempt"], 2, "{v}");
    assert_eq!(v["max_attempts"], 2, "{v}");
    let status = a.child.wait().expect("a exits");
    assert!(status.success(), "{status:?}");
    eprintln!("handed over in {:.2} s", t0.elapsed().as_secs_f64());
    let (_, v) = c.delete(b, &format!("/v1/plans/{id}")).await;
    assert_eq!(v["state"], "cancelled", "{v}");
}
