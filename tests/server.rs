//! Integration tests of `manyhands serve`: the real server in-process on an ephemeral loopback
//! port, exercised over HTTP with reqwest. Every test starts its own server and data directory.

#[path = "common/tmp.rs"]
mod tmp;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use manyhands::server::api::{Job, JobState};
use manyhands::server::store::embedded::EmbeddedStore;
use manyhands::server::store::{JobStore, NewJob};
use manyhands::server::{Config, Server};
use reqwest::StatusCode;
use serde_json::{json, Value};

struct Harness {
    server: Option<Server>,
    base: String,
    http: reqwest::Client,
    dir: PathBuf,
}

fn temp_dir(name: &str) -> PathBuf {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let d = tmp::run_root().join(format!(
        "manyhands-server-{name}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn config(dir: &std::path::Path) -> Config {
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.to_path_buf());
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.workers = 2;
    cfg.query_threads = 2;
    cfg.shutdown_grace = Duration::from_millis(200);
    cfg
}

impl Harness {
    async fn start(name: &str, tweak: impl FnOnce(&mut Config)) -> Harness {
        let dir = temp_dir(name);
        Harness::start_in(dir, tweak).await
    }

    async fn start_in(dir: PathBuf, tweak: impl FnOnce(&mut Config)) -> Harness {
        let mut cfg = config(&dir);
        tweak(&mut cfg);
        let server = Server::start(cfg).await.expect("server starts");
        let base = format!("http://{}", server.addr());
        Harness {
            server: Some(server),
            base,
            http: reqwest::Client::builder()
                .timeout(Duration::from_secs(30))
                .build()
                .expect("client"),
            dir,
        }
    }

    fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    async fn get(&self, path: &str) -> (StatusCode, Value) {
        let r = self.http.get(self.url(path)).send().await.expect("GET");
        let s = r.status();
        (s, r.json().await.unwrap_or(Value::Null))
    }

    async fn send(&self, method: reqwest::Method, path: &str, body: &Value) -> (StatusCode, Value) {
        let r = self
            .http
            .request(method, self.url(path))
            .json(body)
            .send()
            .await
            .expect("request");
        let s = r.status();
        (s, r.json().await.unwrap_or(Value::Null))
    }

    async fn post(&self, path: &str, body: &Value) -> (StatusCode, Value) {
        self.send(reqwest::Method::POST, path, body).await
    }

    async fn put(&self, path: &str, body: &Value) -> (StatusCode, Value) {
        self.send(reqwest::Method::PUT, path, body).await
    }

    async fn delete(&self, path: &str) -> (StatusCode, Value) {
        let r = self
            .http
            .delete(self.url(path))
            .send()
            .await
            .expect("DELETE");
        let s = r.status();
        (s, r.json().await.unwrap_or(Value::Null))
    }

    async fn raw(
        &self,
        path: &str,
        content_type: &str,
        body: Vec<u8>,
    ) -> Result<(StatusCode, Value), reqwest::Error> {
        let r = self
            .http
            .post(self.url(path))
            .header("content-type", content_type)
            .body(body)
            .send()
            .await?;
        let s = r.status();
        Ok((s, r.json().await.unwrap_or(Value::Null)))
    }

    async fn healthy(&self) {
        let (s, v) = self.get("/healthz").await;
        assert_eq!(s, StatusCode::OK);
        assert_eq!(v["status"], "ok");
    }

    async fn stop(mut self) -> PathBuf {
        if let Some(s) = self.server.take() {
            s.shutdown().await.expect("clean shutdown");
        }
        self.dir.clone()
    }
}

fn field(v: &Value) -> &str {
    v["error"]["field"].as_str().unwrap_or("")
}

fn code(v: &Value) -> &str {
    v["error"]["code"].as_str().unwrap_or("")
}

const MINI_URDF: &str = r#"<robot name="mini">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="1" effort="1"/></joint>
</robot>"#;

const MINI_SRDF: &str = r#"<robot name="mini"><group name="all"><joint name="j1"/></group>
  <group_state name="home" group="all"><joint name="j1" value="0.2"/></group_state>
  <disable_collisions link1="base" link2="arm" reason="Adjacent"/></robot>"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn resources_queries_and_operations() {
    let h = Harness::start("resources", |_| {}).await;
    h.healthy().await;
    assert_eq!(h.get("/readyz").await.0, StatusCode::OK);

    // Robots.
    let (s, v) = h.get("/v1/robots").await;
    assert_eq!(s, StatusCode::OK);
    let names: Vec<&str> = v
        .as_array()
        .expect("list")
        .iter()
        .filter_map(|r| r["name"].as_str())
        .collect();
    assert!(
        names.contains(&"armar") && names.contains(&"justin"),
        "{names:?}"
    );
    let (s, v) = h.get("/v1/robots/armar").await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["dof"], 20);
    assert_eq!(v["source"], "builtin");
    let (s, v) = h.get("/v1/robots/nope").await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert_eq!(code(&v), "not_found");

    let (s, v) = h
        .put(
            "/v1/robots/mini",
            &json!({"urdf": MINI_URDF, "srdf": MINI_SRDF}),
        )
        .await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert_eq!(v["dof"], 1);
    let (s, _) = h
        .put(
            "/v1/robots/mini",
            &json!({"urdf": MINI_URDF, "srdf": MINI_SRDF}),
        )
        .await;
    assert_eq!(s, StatusCode::OK);
    assert!(h.dir.join("robots/mini.urdf").is_file());
    // A broken URDF names the element.
    let bad = MINI_URDF.replace(r#"lower="-1.5""#, r#"lower="abc""#);
    let (s, v) = h.put("/v1/robots/mini2", &json!({"urdf": bad})).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(field(&v).starts_with("urdf."), "{v}");
    let bad = MINI_SRDF.replace(r#"<joint name="j1"/>"#, r#"<joint name="j9"/>"#);
    let (s, v) = h
        .put("/v1/robots/mini2", &json!({"urdf": MINI_URDF, "srdf": bad}))
        .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(field(&v).starts_with("srdf."), "{v}");
    let mesh = MINI_URDF.replace(
        r#"<box size="0.2 0.2 0.2"/>"#,
        r#"<mesh filename="/etc/passwd"/>"#,
    );
    let (s, v) = h.put("/v1/robots/mini3", &json!({"urdf": mesh})).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    let (s, v) = h.put("/v1/robots/armar", &json!({"urdf": MINI_URDF})).await;
    assert_eq!(s, StatusCode::CONFLICT, "{v}");
    let (s, v) = h
        .put("/v1/robots/..%2Fevil", &json!({"urdf": MINI_URDF}))
        .await;
    assert!(s.is_client_error(), "{s} {v}");

    // Scenes.
    let (s, v) = h.get("/v1/scenes").await;
    assert_eq!(s, StatusCode::OK);
    assert!(v
        .as_array()
        .expect("list")
        .iter()
        .any(|s| s["name"] == "kitchen"));
    let (s, mut scene) = h.get("/v1/scenes/empty").await;
    assert_eq!(s, StatusCode::OK);
    scene["name"] = json!("mine");
    let (s, v) = h.put("/v1/scenes/mine", &scene).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert!(h.dir.join("scenes/mine.json").is_file());
    let mut bad = scene.clone();
    bad["robots"][0]["configs"]["start"] = json!({"right_elbow": 4.2});
    let (s, v) = h.put("/v1/scenes/mine", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "robots[0].configs.start.right_elbow", "{v}");
    let mut bad = scene.clone();
    bad["robots"][0]["model"] = json!("ghost");
    let (s, v) = h.put("/v1/scenes/mine", &bad).await;
    assert_eq!(s, StatusCode::NOT_FOUND, "{v}");
    assert_eq!(field(&v), "robots[0].model");
    let mut bad = scene.clone();
    bad["obstacles"] = json!([{"name": "o", "pose": {"position": "up"}, "shapes": []}]);
    let (s, v) = h.put("/v1/scenes/mine", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "obstacles[0].pose.position", "{v}");
    let (s, _) = h.put("/v1/scenes/kitchen", &scene).await;
    assert!(s.is_client_error());

    // FK.
    let (s, v) = h
        .post(
            "/v1/fk",
            &json!({"robot": "armar", "config": {"right_elbow": -1.2}, "links": ["right_tcp"]}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["links"][0]["link"], "right_tcp");
    assert_eq!(
        v["links"][0]["pose"]["position"]
            .as_array()
            .map(|a| a.len()),
        Some(3)
    );
    let (s, v) = h
        .post(
            "/v1/fk",
            &json!({"robot": "armar", "config": {"right_elbow": 4.2}}),
        )
        .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(field(&v), "config.right_elbow");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("outside limit"),
        "{v}"
    );
    let (s, v) = h.post("/v1/fk", &json!({"robot": "ghost"})).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert_eq!(field(&v), "robot");
    let (s, v) = h.post("/v1/fk", &json!({"robot": "mini"})).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["config"][0], 0.2);

    // IK: analytic enumeration and numeric.
    // The target: where FK puts the hand at a known configuration.
    let (_, fk) = h
        .post("/v1/fk", &json!({"robot": "armar", "config": {"right_elbow": -1.2, "right_shoulder_1": -0.3}, "links": ["right_tcp"]}))
        .await;
    let pose = &fk["links"][0]["pose"];
    let ik = json!({"robot": "armar", "group": "right_arm",
        "pose": {"position": pose["position"], "quat_xyzw": pose["quat_xyzw"]}, "max_solutions": 3});
    let (s, v) = h.post("/v1/ik", &ik).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["solver"], "analytic");
    assert!(v["solutions_found"].as_u64().unwrap_or(0) > 0, "{v}");
    assert_eq!(v["solutions"].as_array().map(|a| a.len()), Some(3));
    let mut num = ik.clone();
    num["solver"] = json!("numeric");
    let (s, v) = h.post("/v1/ik", &num).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["solver"], "numeric");
    let mut bad = ik.clone();
    bad["group"] = json!("both_arms");
    let (s, v) = h.post("/v1/ik", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(field(&v), "group");
    let mut bad = ik.clone();
    bad["pose"] = json!({"rpy": [0, 0, 0], "quat_xyzw": [0, 0, 0, 1]});
    let (s, v) = h.post("/v1/ik", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert!(field(&v).starts_with("pose"), "{v}");

    // Collision check.
    let (s, v) = h.post("/v1/check", &json!({"scene": "kitchen"})).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["collision"], false, "{v}");
    let (s, v) = h
        .post("/v1/check", &json!({"scene": "kitchen", "robots": [{"name": "armar", "config": {"right_shoulder_1": -1.5, "right_elbow": -0.2}}]}))
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert!(v["collision"].is_boolean());
    let (s, v) = h.post("/v1/check", &json!({"scene": "kitchen", "robots": [{"name": "armar", "config": {"right_elbow": 4.2}}]})).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(field(&v), "robots[0].config.right_elbow");
    let (s, v) = h.post("/v1/check", &json!({"scene": "nowhere"})).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    assert_eq!(field(&v), "scene");

    // Deleting: a robot used by a scene is refused; scene first, then robot.
    let mut ms = scene.clone();
    ms["name"] = json!("minis");
    ms["robots"] = json!([{"name": "m", "model": "mini"}]);
    ms["obstacles"] = json!([]);
    ms["objects"] = json!([]);
    let (s, v) = h.put("/v1/scenes/minis", &ms).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert_eq!(h.delete("/v1/robots/mini").await.0, StatusCode::CONFLICT);
    assert_eq!(h.delete("/v1/scenes/minis").await.0, StatusCode::NO_CONTENT);
    assert_eq!(h.delete("/v1/robots/mini").await.0, StatusCode::NO_CONTENT);
    assert_eq!(h.get("/v1/robots/mini").await.0, StatusCode::NOT_FOUND);
    assert_eq!(h.delete("/v1/robots/armar").await.0, StatusCode::CONFLICT);
    assert_eq!(h.delete("/v1/scenes/mine").await.0, StatusCode::NO_CONTENT);
    assert_eq!(h.delete("/v1/scenes/mine").await.0, StatusCode::NOT_FOUND);

    // Metrics and spec.
    let text = h
        .http
        .get(h.url("/metrics"))
        .send()
        .await
        .expect("metrics")
        .text()
        .await
        .expect("text");
    assert!(
        text.contains(
            "manyhands_http_requests_total{method=\"POST\",route=\"/v1/ik\",status=\"200\"}"
        ),
        "{text}"
    );
    assert!(text.contains("manyhands_http_request_duration_seconds_bucket"));
    assert!(text.contains("manyhands_jobs_queue_depth 0"));
    let (s, v) = h.get("/openapi.json").await;
    assert_eq!(s, StatusCode::OK);
    assert!(v["openapi"].as_str().unwrap_or("").starts_with("3.1"));
    assert_eq!(h.get("/v1/nothing").await.0, StatusCode::NOT_FOUND);
    assert_eq!(h.delete("/v1/fk").await.0, StatusCode::METHOD_NOT_ALLOWED);
    h.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_bodies_are_4xx_and_the_server_stays_healthy() {
    let h = Harness::start("hostile", |_| {}).await;
    let json_ct = "application/json";
    let cases: Vec<(&str, Vec<u8>, u16)> = vec![
        (
            "wrong type",
            br#"{"robot": 5, "group": "right_arm", "pose": {}}"#.to_vec(),
            422,
        ),
        ("malformed", br#"{"robot": "armar", "#.to_vec(), 400),
        (
            "NaN literal",
            br#"{"robot": "armar", "group": "right_arm", "pose": {"position": [NaN, 0, 0]}}"#
                .to_vec(),
            400,
        ),
        (
            "infinite number",
            br#"{"robot": "armar", "group": "right_arm", "pose": {"position": [1e999, 0, 0]}}"#
                .to_vec(),
            400,
        ),
        (
            "unknown field",
            br#"{"robot": "armar", "group": "right_arm", "pose": {}, "extra": 1}"#.to_vec(),
            422,
        ),
        (
            "nested unknown field",
            br#"{"robot": "armar", "group": "right_arm", "pose": {"posit": [0,0,0]}}"#.to_vec(),
            422,
        ),
        ("array body", b"[1, 2, 3]".to_vec(), 422),
        ("empty body", Vec::new(), 400),
        (
            "trailing garbage",
            br#"{"robot": "armar", "group": "right_arm", "pose": {}} xx"#.to_vec(),
            400,
        ),
        (
            "deeply nested",
            ("[".repeat(100_000) + &"]".repeat(100_000)).into_bytes(),
            400,
        ),
        (
            "huge psi steps",
            br#"{"robot": "armar", "group": "right_arm", "pose": {}, "psi_steps": 4000000000}"#
                .to_vec(),
            422,
        ),
        (
            "negative count",
            br#"{"robot": "armar", "group": "right_arm", "pose": {}, "max_solutions": -1}"#
                .to_vec(),
            422,
        ),
    ];
    for (what, body, want) in cases {
        let (s, v) = h.raw("/v1/ik", json_ct, body).await.expect(what);
        assert_eq!(s.as_u16(), want, "{what}: {v}");
        assert!(v["error"]["code"].is_string(), "{what}: {v}");
    }
    let (s, v) = h
        .raw("/v1/ik", json_ct, br#"{"robot": 5}"#.to_vec())
        .await
        .expect("type");
    assert_eq!((s.as_u16(), field(&v)), (422, "robot"), "{v}");
    let (s, v) = h
        .raw(
            "/v1/ik",
            json_ct,
            br#"{"robot": "armar", "group": "right_arm", "pose": {"position": [0, "x", 0]}}"#
                .to_vec(),
        )
        .await
        .expect("type");
    assert_eq!((s.as_u16(), field(&v)), (422, "pose.position[1]"), "{v}");
    let (s, _) = h
        .raw("/v1/ik", "text/plain", b"{}".to_vec())
        .await
        .expect("content type");
    assert_eq!(s, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    // 10 MB body: 413 (or the connection is closed while the client still sends).
    let big = format!("{{\"robot\": \"{}\"}}", "a".repeat(10 * 1024 * 1024));
    match h.raw("/v1/ik", json_ct, big.into_bytes()).await {
        Ok((s, v)) => {
            assert_eq!(s, StatusCode::PAYLOAD_TOO_LARGE, "{v}");
            assert_eq!(code(&v), "body_too_large");
        }
        Err(e) => assert!(!e.is_timeout(), "{e}"),
    }
    let (s, v) = h
        .raw("/v1/plans", json_ct, br#"{"kind": "warp_drive"}"#.to_vec())
        .await
        .expect("kind");
    assert_eq!((s.as_u16(), field(&v)), (422, "kind"), "{v}");
    let (s, v) = h
        .raw(
            "/v1/plans?wait=abc",
            json_ct,
            br#"{"kind": "collision_sweep"}"#.to_vec(),
        )
        .await
        .expect("wait");
    assert_eq!(s, StatusCode::BAD_REQUEST, "{v}");
    // Still healthy and answering.
    h.healthy().await;
    let (s, _) = h
        .post("/v1/ik", &json!({"robot": "armar", "group": "right_arm", "pose": {"position": [0.4512, -0.2613, 1.0767], "rpy": [-2.7037, -1.4125, 1.0834]}}))
        .await;
    assert_eq!(s, StatusCode::OK);
    let text = h
        .http
        .get(h.url("/metrics"))
        .send()
        .await
        .expect("metrics")
        .text()
        .await
        .expect("text");
    assert!(!text.contains("status=\"500\""), "{text}");
    h.stop().await;
}

async fn wait_state(
    h: &Harness,
    id: &str,
    pred: impl Fn(JobState) -> bool,
    within: Duration,
) -> Job {
    let t0 = Instant::now();
    loop {
        let (s, v) = h.get(&format!("/v1/plans/{id}")).await;
        assert_eq!(s, StatusCode::OK, "{v}");
        let job: Job = serde_json::from_value(v).expect("job");
        if pred(job.state) || t0.elapsed() > within {
            return job;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

fn sweep(samples: u64, time_limit: f64) -> Value {
    json!({"kind": "collision_sweep", "scene": "kitchen", "samples": samples, "time_limit": time_limit})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plans_wait_events_and_cancel() {
    let h = Harness::start("plans", |_| {}).await;
    // A joint-space plan answered in one call.
    let plan = json!({"kind": "joint_space", "scene": "empty", "time_limit": 20,
        "robots": [{"name": "armar", "group": "right_arm", "goal": {"right_elbow": -1.0, "right_shoulder_1": -0.4}}]});
    let (s, v) = h.post("/v1/plans?wait=30", &plan).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let path = v["result"]["path"].as_array().expect("path");
    assert!(path.len() >= 2);
    assert_eq!(v["result"]["joints"].as_array().map(|a| a.len()), Some(7));
    assert_eq!(v["result"]["collision_model"], "fast", "{v}");
    // VAMP-style RRT-Connect settings; certification asked but armar is not made of spheres.
    let mut tuned = plan.clone();
    tuned["dynamic_domain"] = json!(4.0);
    tuned["balance"] = json!(true);
    tuned["certify"] = json!(0.04);
    let (s, v) = h.post("/v1/plans?wait=30", &tuned).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    assert_eq!(v["result"]["certified"], false, "{v}");
    // The Halton sampler: the same search for every seed (no shortcutting to tell them apart).
    let mut halton = tuned.clone();
    halton["sampler"] = json!("halton");
    halton["simplify"] = json!(false);
    let mut paths = Vec::new();
    for seed in [1, 2] {
        halton["seed"] = json!(seed);
        let (s, v) = h.post("/v1/plans?wait=30", &halton).await;
        assert_eq!(s, StatusCode::OK, "{v}");
        assert_eq!(v["state"], "succeeded", "{v}");
        paths.push(v["result"]["path"].clone());
    }
    assert_eq!(paths[0], paths[1]);
    // More joints than the Halton sequence has bases: refused before planning, naming it.
    let (s, mut four) = h.get("/v1/scenes/handoff").await;
    assert_eq!(s, StatusCode::OK, "{four}");
    four["name"] = json!("four_armars");
    let robots = four["robots"].as_array().cloned().expect("robots");
    let mut all = Vec::new();
    for copy in 0..2 {
        for r in &robots {
            let mut r = r.clone();
            r["name"] = json!(format!("{}_{copy}", r["name"].as_str().expect("name")));
            r["base_pose"]["position"][1] =
                json!(r["base_pose"]["position"][1].as_f64().unwrap_or(0.0) + 4.0 * copy as f64);
            all.push(r);
        }
    }
    four["robots"] = json!(all);
    let (s, v) = h.put("/v1/scenes/four_armars", &four).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    let names: Vec<Value> = all.iter().map(|r| r["name"].clone()).collect();
    assert_eq!(names.len(), 4);
    let wide = json!({"kind": "joint_space", "scene": "four_armars", "sampler": "halton",
        "robots": names.iter().map(|n| json!({"name": n, "goal": {"right_elbow": -1.0}})).collect::<Vec<_>>()});
    let (s, v) = h.post("/v1/plans", &wide).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "sampler", "{v}");
    for (key, value) in [
        ("certify", json!(2.0)),
        ("dynamic_domain", json!(-1.0)),
        ("sampler", json!("sobol")),
    ] {
        let mut bad = plan.clone();
        bad[key] = value;
        let (s, v) = h.post("/v1/plans", &bad).await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
        assert_eq!(field(&v), key, "{v}");
    }

    // 202 + Location, then GET with wait.
    let r = h
        .http
        .post(h.url("/v1/plans"))
        .json(&sweep(3000, 5.0))
        .send()
        .await
        .expect("post");
    assert_eq!(r.status(), StatusCode::ACCEPTED);
    let loc = r
        .headers()
        .get("location")
        .and_then(|l| l.to_str().ok())
        .expect("Location")
        .to_string();
    let (s, v) = h.get(&format!("{loc}?wait=20")).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["state"], "succeeded", "{v}");
    assert_eq!(v["result"]["samples"], 3000);
    // Counts add up; the most frequent colliding pairs are named bodies, most frequent first.
    let (free, colliding) = (
        v["result"]["free"].as_u64().unwrap_or(0),
        v["result"]["colliding"].as_u64().unwrap_or(0),
    );
    assert!(free + colliding == 3000 && colliding > 0, "{v}");
    let top = v["result"]["top_pairs"].as_array().expect("top_pairs");
    let counts: Vec<u64> = top.iter().filter_map(|p| p["count"].as_u64()).collect();
    assert!(!top.is_empty() && counts.len() == top.len(), "{v}");
    assert!(counts.windows(2).all(|w| w[0] >= w[1]) && counts.iter().sum::<u64>() <= colliding);
    for p in top {
        assert!(
            p["a"].as_str().is_some_and(|a| !a.is_empty())
                && p["b"].as_str().is_some_and(|b| !b.is_empty()),
            "{p}"
        );
    }
    let (_, list) = h.get("/v1/plans").await;
    assert!(list["jobs"].as_array().map(|a| a.len()).unwrap_or(0) >= 2);

    // Field paths in plan requests.
    let mut bad = plan.clone();
    bad["robots"][0]["goal"] = json!({"right_elbow": 4.2});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(field(&v), "robots[0].goal.right_elbow", "{v}");
    let mut bad = plan.clone();
    bad["robots"][0]["goal"] = json!({"right_elbow": "bent"});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    assert_eq!(field(&v), "robots[0].goal.right_elbow", "{v}");
    let mut bad = plan.clone();
    bad["time_limit"] = json!(-1);
    assert_eq!(field(&h.post("/v1/plans", &bad).await.1), "time_limit");
    let mut bad = plan.clone();
    bad["scene"] = json!("atlantis");
    assert_eq!(h.post("/v1/plans", &bad).await.0, StatusCode::NOT_FOUND);

    // Server-Sent Events: state, progress, end.
    let (s, v) = h.post("/v1/plans", &sweep(1_000_000_000, 0.6)).await;
    assert_eq!(s, StatusCode::ACCEPTED);
    let id = v["id"].as_str().expect("id").to_string();
    let mut resp = h
        .http
        .get(h.url(&format!("/v1/plans/{id}/events")))
        .send()
        .await
        .expect("events");
    assert_eq!(resp.status(), StatusCode::OK);
    assert!(resp.headers()["content-type"]
        .to_str()
        .unwrap_or("")
        .starts_with("text/event-stream"));
    let mut text = String::new();
    while let Some(chunk) = tokio::time::timeout(Duration::from_secs(10), resp.chunk())
        .await
        .expect("event in time")
        .expect("chunk")
    {
        text.push_str(&String::from_utf8_lossy(&chunk));
        if text.contains("event: end") {
            break;
        }
    }
    assert!(text.contains("event: state"), "{text}");
    assert!(text.contains("event: progress"), "{text}");
    assert!(text.contains("event: end"), "{text}");
    let end = text
        .split("event: end\ndata: ")
        .nth(1)
        .and_then(|s| s.lines().next())
        .expect("end data");
    let job: Job = serde_json::from_str(end).expect("job json");
    assert_eq!(job.state, JobState::Succeeded);
    assert_eq!(
        job.result
            .as_ref()
            .map(|r| r["truncated_by_time_limit"].clone()),
        Some(json!(true))
    );

    // Cancel a running job: it stops promptly.
    let (_, v) = h.post("/v1/plans", &sweep(1_000_000_000, 30.0)).await;
    let id = v["id"].as_str().expect("id").to_string();
    let job = wait_state(&h, &id, |s| s == JobState::Running, Duration::from_secs(5)).await;
    assert_eq!(job.state, JobState::Running);
    tokio::time::sleep(Duration::from_millis(150)).await;
    let t0 = Instant::now();
    let (s, v) = h.delete(&format!("/v1/plans/{id}")).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["state"], "cancelled", "{v}");
    assert!(
        t0.elapsed() < Duration::from_millis(500),
        "{:?}",
        t0.elapsed()
    );
    assert!(v["progress"]["samples"].as_u64().unwrap_or(0) > 0, "{v}");
    // Cancelling again changes nothing; unknown ids are 404.
    assert_eq!(
        h.delete(&format!("/v1/plans/{id}")).await.1["state"],
        "cancelled"
    );
    assert_eq!(h.delete("/v1/plans/j0").await.0, StatusCode::NOT_FOUND);
    assert_eq!(h.get("/v1/plans/j0/events").await.0, StatusCode::NOT_FOUND);
    h.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn full_queue_answers_429_and_accepted_jobs_finish() {
    let h = Harness::start("queue", |c| {
        c.workers = 1;
        c.max_queue = 3;
    })
    .await;
    let mut accepted = Vec::new();
    let mut refused = 0;
    for _ in 0..8 {
        let r = h
            .http
            .post(h.url("/v1/plans"))
            .json(&sweep(1_000_000_000, 0.3))
            .send()
            .await
            .expect("post");
        match r.status() {
            StatusCode::ACCEPTED => {
                let v: Value = r.json().await.expect("json");
                accepted.push(v["id"].as_str().expect("id").to_string());
            }
            StatusCode::TOO_MANY_REQUESTS => {
                assert!(r.headers().get("retry-after").is_some());
                let v: Value = r.json().await.expect("json");
                assert_eq!(code(&v), "queue_full");
                refused += 1;
            }
            s => panic!("unexpected {s}"),
        }
    }
    assert!(refused >= 1, "queue never full");
    assert!(
        accepted.len() >= 3 && accepted.len() <= 5,
        "{}",
        accepted.len()
    );
    let text = h
        .http
        .get(h.url("/metrics"))
        .send()
        .await
        .expect("metrics")
        .text()
        .await
        .expect("text");
    assert!(text.contains("manyhands_jobs_queue_depth"), "{text}");
    for id in &accepted {
        let (s, v) = h.get(&format!("/v1/plans/{id}?wait=20")).await;
        assert_eq!(s, StatusCode::OK);
        assert_eq!(v["state"], "succeeded", "{v}");
    }
    h.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn restart_keeps_results_and_runs_jobs_it_stopped() {
    let h = Harness::start("restart", |c| c.workers = 1).await;
    let (s, done) = h.post("/v1/plans?wait=20", &sweep(500, 5.0)).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(done["state"], "succeeded");
    let done_id = done["id"].as_str().expect("id").to_string();
    let (_, v) = h.post("/v1/plans", &sweep(1_000_000_000, 60.0)).await;
    let running = v["id"].as_str().expect("id").to_string();
    let (_, v) = h.post("/v1/plans", &sweep(1_000_000_000, 60.0)).await;
    let queued = v["id"].as_str().expect("id").to_string();
    wait_state(
        &h,
        &running,
        |s| s == JobState::Running,
        Duration::from_secs(5),
    )
    .await;
    let t0 = Instant::now();
    let dir = h.stop().await;
    assert!(
        t0.elapsed() < Duration::from_secs(5),
        "shutdown took {:?}",
        t0.elapsed()
    );

    // A crash leaves a record "running": simulate one in the store (a job claimed by a process
    // that died).
    let store = EmbeddedStore::open(&dir.join("jobs.redb")).expect("store");
    let mut crashed: Job = serde_json::from_value(done.clone()).expect("job");
    crashed.id = "jcrashed".into();
    crashed.state = JobState::Queued;
    crashed.result = None;
    crashed.finished_ms = None;
    crashed.created_ms = 1;
    let new = NewJob {
        job: crashed,
        priority: 1000,
        max_attempts: 1,
    };
    store.enqueue(&new, 100).await.expect("enqueue");
    let c = store
        .claim("a-process-that-died", Duration::from_secs(3600))
        .await
        .expect("claim")
        .expect("the crashed job");
    assert_eq!(c.fence.id, "jcrashed");
    drop(store);

    let h = Harness::start_in(dir, |c| c.workers = 1).await;
    let (s, v) = h.get(&format!("/v1/plans/{done_id}")).await;
    assert_eq!(s, StatusCode::OK);
    assert_eq!(v["state"], "succeeded");
    assert_eq!(v["result"]["samples"], 500);
    // Stopped by the shutdown while it ran: given back to the queue, one more attempt allowed
    // for it; accepted and still queued at the shutdown: still queued. Both run after the
    // restart (the one given back first: it is older).
    let (_, v) = h.get(&format!("/v1/plans/{running}")).await;
    assert!(
        v["state"] == "queued" || v["state"] == "running",
        "a job stopped by the shutdown runs again: {v}"
    );
    assert_eq!(v["max_attempts"], 2, "{v}");
    let (_, v) = h.get(&format!("/v1/plans/{queued}")).await;
    assert!(
        v["state"] == "queued" || v["state"] == "running",
        "a queued job survives a restart: {v}"
    );
    for id in [&running, &queued] {
        let (s, v) = h.delete(&format!("/v1/plans/{id}")).await;
        assert_eq!(s, StatusCode::OK);
        assert_eq!(v["state"], "cancelled", "{v}");
    }
    // Left running by a process that died: its lease is reaped at start.
    let (_, v) = h.get("/v1/plans/jcrashed").await;
    assert_eq!(v["state"], "interrupted", "{v}");
    assert_eq!(code(&v), "interrupted");
    let dir = h.stop().await;
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn token_auth_and_retention() {
    let h = Harness::start("auth", |c| {
        c.token = Some("s3cret".into());
        c.retention = Duration::from_millis(300);
    })
    .await;
    h.healthy().await;
    let (s, v) = h.get("/v1/robots").await;
    assert_eq!(s, StatusCode::UNAUTHORIZED);
    assert_eq!(code(&v), "unauthorized");
    let r = h
        .http
        .get(h.url("/v1/robots"))
        .bearer_auth("s3cret")
        .send()
        .await
        .expect("get");
    assert_eq!(r.status(), StatusCode::OK);
    let r = h
        .http
        .get(h.url("/v1/robots"))
        .bearer_auth("wrong")
        .send()
        .await
        .expect("get");
    assert_eq!(r.status(), StatusCode::UNAUTHORIZED);
    // Retention: a finished job disappears after the retention period.
    let r = h
        .http
        .post(h.url("/v1/plans?wait=10"))
        .bearer_auth("s3cret")
        .json(&sweep(100, 5.0))
        .send()
        .await
        .expect("post");
    assert_eq!(r.status(), StatusCode::OK);
    let id = r.json::<Value>().await.expect("json")["id"]
        .as_str()
        .expect("id")
        .to_string();
    tokio::time::sleep(Duration::from_millis(800)).await;
    let r = h
        .http
        .get(h.url(&format!("/v1/plans/{id}")))
        .bearer_auth("s3cret")
        .send()
        .await
        .expect("get");
    assert_eq!(r.status(), StatusCode::NOT_FOUND);
    h.stop().await;

    // A non-loopback bind needs a token.
    let mut cfg = config(&temp_dir("cfg"));
    cfg.bind = "0.0.0.0:0".parse().expect("addr");
    assert!(cfg.validate().is_err());
    cfg.token = Some("t".into());
    assert!(cfg.validate().is_err(), "a short token off loopback");
    cfg.token = Some("0123456789abcdef".into());
    assert!(cfg.validate().is_ok());
}
