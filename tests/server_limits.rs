//! Time limits, cancel and shutdown reach the first-use builds (reachability grids, grasp lists,
//! roadmaps): a job's time limit counts from its start and includes them, a cancel frees the
//! planner thread at once, SIGINT exits within its grace; a build a job left because of its time
//! limit goes on and later jobs reuse it (`src/server/builds.rs`).

mod common;
mod process;

use std::time::{Duration, Instant};

use reqwest::StatusCode;
use serde_json::{json, Value};

/// `GET base+path` as JSON.
async fn get(http: &reqwest::Client, base: &str, path: &str) -> Value {
    http.get(format!("{base}{path}"))
        .send()
        .await
        .expect("GET")
        .json()
        .await
        .expect("json")
}

/// Submits `body` and waits (bounded) until its progress reports `phase`; the job id.
async fn submit_until_phase(
    http: &reqwest::Client,
    base: &str,
    body: &Value,
    phase: &str,
) -> String {
    let r = http
        .post(format!("{base}/v1/plans"))
        .json(body)
        .send()
        .await
        .expect("POST");
    assert_eq!(r.status(), StatusCode::ACCEPTED);
    let v: Value = r.json().await.expect("json");
    let id = v["id"].as_str().expect("id").to_string();
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let j = get(http, base, &format!("/v1/plans/{id}")).await;
        if j["progress"]["phase"] == phase {
            return id;
        }
        assert!(
            j["state"] == "queued" || j["state"] == "running",
            "the job ended before its {phase} phase: {j}"
        );
        assert!(Instant::now() < deadline, "no {phase} phase: {j}");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// A `multi_robot` job with a 1 s time limit on a fresh data folder (its reachability grids
/// not built yet) ends within 1.5 s, and says what happened with the real elapsed time.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn time_limit_includes_first_use_grid_builds() {
    let h = common::server::start("limits-grid").await;
    let t = Instant::now();
    let (s, v) = h
        .post(
            "/v1/plans?wait=30",
            &json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table", "time_limit": 1}),
        )
        .await;
    let took = t.elapsed();
    eprintln!(
        "multi_robot, time limit 1 s, fresh data folder: {took:?} {}",
        v["error"]
    );
    assert_eq!(s, StatusCode::OK, "{v}");
    assert!(
        took < Duration::from_millis(1500),
        "the job took {took:?}: {v}"
    );
    match v["state"].as_str() {
        Some("succeeded") => {}
        Some("failed") => {
            assert_eq!(v["error"]["code"], "timeout", "{v}");
            let m = v["error"]["message"].as_str().unwrap_or("");
            assert!(m.starts_with("time limit 1 s reached"), "{m}");
            assert!(!m.contains("after 0.000"), "{m}");
            assert!(m.contains("reachability grid"), "{m}");
            assert!(m.contains("first use"), "{m}");
        }
        _ => panic!("{v}"),
    }
    h.server.shutdown().await.expect("shutdown");
}

/// A job cancelled while it waits for a grid build frees its planner thread within 100 ms, and
/// the build no job waits for any more stops.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancel_in_the_grid_phase_frees_the_worker() {
    let h = common::server::start("limits-cancel").await;
    let jobs = h.server.state().jobs.clone();
    let id = submit_until_phase(
        &h.http,
        &h.base,
        &json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table", "time_limit": 60}),
        "reachability grids",
    )
    .await;
    assert_eq!(jobs.running_here(), 1);
    // The phase is announced just before the build starts.
    let t = Instant::now();
    while jobs.builds_running() == 0 {
        assert!(t.elapsed() < Duration::from_secs(2), "no grid build");
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    tokio::time::sleep(Duration::from_millis(100)).await;
    let r = h
        .http
        .delete(format!("{}/v1/plans/{id}", h.base))
        .send()
        .await
        .expect("DELETE");
    let cancelled = Instant::now();
    assert_eq!(r.status(), StatusCode::OK);
    while jobs.running_here() > 0 {
        assert!(
            cancelled.elapsed() < Duration::from_millis(100),
            "the worker is still busy {:?} after the cancel",
            cancelled.elapsed()
        );
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let freed = cancelled.elapsed();
    let j = get(&h.http, &h.base, &format!("/v1/plans/{id}")).await;
    assert_eq!(j["state"], "cancelled", "{j}");
    // No job waits for the build: it stops too (it polls every 256 samples).
    while jobs.builds_running() > 0 {
        assert!(
            cancelled.elapsed() < Duration::from_secs(2),
            "the grid build still runs"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    eprintln!("worker free {freed:?} after the cancel");
    h.server.shutdown().await.expect("shutdown");
}

/// SIGINT with a 1 s grace while a job waits for a grid build: the process exits within the
/// grace and a small margin (the build stops with the job).
#[cfg(unix)]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigint_while_a_grid_builds_exits_within_the_grace() {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let data = std::env::temp_dir().join(format!(
        "manyhands-limits-int-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&data).expect("dir");
    let mut p = process::spawn(&data, &["--shutdown-grace", "1"]);
    let base = format!("http://{}", p.addr);
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(20))
        .build()
        .expect("client");
    submit_until_phase(
        &http,
        &base,
        &json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table", "time_limit": 60}),
        "reachability grids",
    )
    .await;
    let t0 = Instant::now();
    let killed = std::process::Command::new("kill")
        .args(["-INT", &p.child.id().to_string()])
        .status()
        .expect("kill -INT");
    assert!(killed.success());
    let status = loop {
        if let Some(s) = p.child.try_wait().expect("wait") {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_millis(2500),
            "still running {:?} after SIGINT with a 1 s grace",
            t0.elapsed()
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    };
    eprintln!("exited {:?} after SIGINT: {status}", t0.elapsed());
    assert!(status.success(), "{status}");
    let _ = std::fs::remove_dir_all(&data);
}

/// Pick-and-place over HTTP on a fresh data folder (the README's example): it succeeds, or
/// its time limit comes while the grasp lists or the roadmap are built for the first time and
/// the answer says so (never "0.000 ms"); the builds go on, and a later job with a 2 s time
/// limit reuses them (its stats say nothing was built) and succeeds within a tight bound.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pick_place_first_use_then_cached() {
    let h = common::server::start("limits-pick").await;
    let jobs = h.server.state().jobs.clone();
    let req = json!({"kind": "pick_place", "scene": "pick_place", "robot": "justin",
        "object": "statuette", "pick_hand": "right_hand", "place_hand": "left_hand", "seed": 1});
    let t = Instant::now();
    let (s, v) = h.post("/v1/plans?wait=120", &req).await;
    eprintln!(
        "pick_place on a fresh data folder: {:?} {} {} {}",
        t.elapsed(),
        v["state"],
        v["error"],
        v["result"]["offline"]
    );
    assert_eq!(s, StatusCode::OK, "{v}");
    match v["state"].as_str() {
        Some("succeeded") => {
            let off = &v["result"]["offline"];
            assert_eq!(off["pick_list_built"], true, "{off}");
            assert_eq!(off["roadmap_built"], true, "{off}");
        }
        Some("failed") => {
            assert_eq!(v["error"]["code"], "timeout", "{v}");
            let m = v["error"]["message"].as_str().unwrap_or("");
            assert!(m.starts_with("time limit 10 s reached"), "{m}");
            assert!(m.contains("first use"), "{m}");
            assert!(!m.contains("0.000 ms"), "{m}");
        }
        _ => panic!("{v}"),
    }
    // The builds a timed-out job left finish in the background.
    let t = Instant::now();
    while jobs.builds_running() > 0 {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "builds still running"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let mut again = req.clone();
    again["time_limit"] = json!(30);
    let t = Instant::now();
    let (s, v) = h.post("/v1/plans?wait=60", &again).await;
    let took = t.elapsed();
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let off = &v["result"]["offline"];
    for k in ["pick_list_built", "place_list_built", "roadmap_built"] {
        assert_eq!(off[k], false, "{k}: {off}");
    }
    assert!(took < Duration::from_secs(30), "{took:?}");
    eprintln!("pick_place with cached offline data: {took:?}");
    h.server.shutdown().await.expect("shutdown");
}

/// `pick_place` whose time limit comes during planning answers `timeout`, like other kinds.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pick_place_time_limit_is_a_timeout() {
    let h = common::server::start("limits-pick-timeout").await;
    let req = json!({"kind": "pick_place", "scene": "pick_place", "robot": "justin",
        "object": "statuette", "pick_hand": "right_hand", "place_hand": "left_hand", "seed": 1,
        "time_limit": 0.05});
    let (s, v) = h.post("/v1/plans?wait=30", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "failed", "{v}");
    assert_eq!(v["error"]["code"], "timeout", "{v}");
    h.server.shutdown().await.expect("shutdown");
}

/// A chain robot of `links` links (`links - 1` revolute joints `j1`…), each link with
/// `shapes` small spheres: within the upload limits (512 links, 512 joints).
fn chain_urdf(links: usize, shapes: usize) -> String {
    let mut u = String::from("<robot name=\"snake\">\n");
    for i in 0..links {
        u += &format!("<link name=\"l{i}\">");
        for k in 0..shapes {
            u += &format!(
                "<collision><origin xyz=\"0 0 {}\"/><geometry><sphere radius=\"0.004\"/></geometry></collision>",
                0.01 * k as f64
            );
        }
        u += "</link>\n";
    }
    for i in 1..links {
        let axis = if i % 2 == 0 { "0 1 0" } else { "1 0 0" };
        u += &format!(
            "<joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{i}\"/>\
             <origin xyz=\"0 0 0.03\"/><axis xyz=\"{axis}\"/>\
             <limit lower=\"-0.5\" upper=\"0.5\" effort=\"1\" velocity=\"1\"/></joint>\n",
            i - 1
        );
    }
    u + "</robot>\n"
}

/// Uploads robot `name` and scene `name` holding it alone.
async fn upload_chain(h: &common::server::Harness, name: &str, links: usize, shapes: usize) {
    let r = h
        .http
        .put(format!("{}/v1/robots/{name}", h.base))
        .json(&json!({"urdf": chain_urdf(links, shapes)}))
        .send()
        .await
        .expect("PUT robot");
    assert!(r.status().is_success(), "{:?}", r.text().await);
    let scene = json!({"name": name, "description": "a chain robot", "obstacles": [], "objects": [],
        "robots": [{"name": "snake", "model": name,
            "base_pose": {"position": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]},
            "configs": {"start": {}}, "start": "start"}]});
    let r = h
        .http
        .put(format!("{}/v1/scenes/{name}", h.base))
        .json(&scene)
        .send()
        .await
        .expect("PUT scene");
    assert!(r.status().is_success(), "{:?}", r.text().await);
}

/// A flood of checks on a 512-link robot (130 816 shape pairs) runs on the heavy lane or is
/// refused there (503), so IK requests meanwhile answer quickly; a check past the bound is a
/// 422 naming it; jobs on that robot end within their time limit, setup included.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn costly_checks_do_not_starve_cheap_queries() {
    let h = std::sync::Arc::new(common::server::start("limits-lanes").await);
    upload_chain(&h, "snake", 512, 1).await;
    upload_chain(&h, "snake2", 512, 2).await;
    // Past the bound: 1024 shapes → 523 776 pairs.
    let (s, v) = h
        .post("/v1/check", &json!({"scene": "snake2", "robots": []}))
        .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(common::server::field(&v), "scene", "{v}");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("200000"),
        "{v}"
    );
    // The flood: 6 clients checking the 512-link robot for 3 s.
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut flood = Vec::new();
    for _ in 0..6 {
        let (h, stop) = (h.clone(), stop.clone());
        flood.push(tokio::spawn(async move {
            let mut codes = Vec::new();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let (s, _) = h
                    .post("/v1/check", &json!({"scene": "snake", "robots": []}))
                    .await;
                codes.push(s.as_u16());
                if s == StatusCode::SERVICE_UNAVAILABLE {
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
            }
            codes
        }));
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let ik = json!({"robot": "armar", "group": "torso_right_arm",
        "pose": {"position": [0.5, -0.3, 1.1], "rpy": [0.0, 0.0, 0.0]}});
    let mut times = Vec::new();
    for _ in 0..20 {
        let t = Instant::now();
        let (s, v) = h.post("/v1/ik", &ik).await;
        times.push(t.elapsed());
        assert_eq!(s, StatusCode::OK, "{v}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let mut codes = Vec::new();
    for f in flood {
        codes.extend(f.await.expect("flood"));
    }
    times.sort();
    eprintln!(
        "IK under the check flood: median {:?}, max {:?}; check answers {codes:?}",
        times[times.len() / 2],
        times[times.len() - 1]
    );
    assert!(
        codes.iter().all(|&c| c == 200 || c == 503),
        "checks answer 200 or 503: {codes:?}"
    );
    assert!(
        times[times.len() / 2] < Duration::from_millis(100),
        "{times:?}"
    );
    assert!(times[times.len() - 1] < Duration::from_secs(1), "{times:?}");

    // Jobs on that robot end within their time limit, setup included.
    for body in [
        json!({"kind": "collision_sweep", "scene": "snake", "samples": 1_000_000_000u64, "time_limit": 2}),
        json!({"kind": "joint_space", "scene": "snake", "time_limit": 2,
            "robots": [{"name": "snake", "goal": {"j1": 0.4, "j300": -0.4, "j511": 0.4}}]}),
    ] {
        let t = Instant::now();
        let (s, v) = h.post("/v1/plans?wait=60", &body).await;
        let took = t.elapsed();
        eprintln!(
            "{} on the 512-link robot: {took:?} {}",
            body["kind"], v["state"]
        );
        assert_eq!(s, StatusCode::OK, "{v}");
        assert_ne!(v["state"], "running", "{v}");
        assert!(took < Duration::from_secs(6), "{}: {took:?}", body["kind"]);
    }
}
