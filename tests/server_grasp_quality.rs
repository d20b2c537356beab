//! `POST /v1/grasp-quality` against the real server on an ephemeral loopback port: the reference
//! value of the notes, scene grasps, and input errors naming the field.

#[path = "common/tmp.rs"]
mod tmp;
use std::path::PathBuf;
use std::time::Duration;

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

impl Harness {
    async fn start(name: &str) -> Harness {
        let dir = temp_dir(name);
        let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.clone());
        let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        cfg.robots_dir = root.join("robots");
        cfg.scenes_dir = root.join("scenes");
        cfg.workers = 1;
        cfg.query_threads = 2;
        cfg.shutdown_grace = Duration::from_millis(200);
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

    async fn post(&self, body: &Value) -> (StatusCode, Value) {
        self.raw(body.to_string()).await
    }

    async fn raw(&self, body: String) -> (StatusCode, Value) {
        let r = self
            .http
            .post(format!("{}/v1/grasp-quality", self.base))
            .header("content-type", "application/json")
            .body(body)
            .send()
            .await
            .expect("request");
        let s = r.status();
        (s, r.json().await.unwrap_or(Value::Null))
    }

    async fn stop(mut self) {
        if let Some(s) = self.server.take() {
            s.shutdown().await.expect("clean shutdown");
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn field(v: &Value) -> &str {
    v["error"]["field"].as_str().unwrap_or("")
}

/// The four side-face centres of the unit cube at the origin, inward normals.
fn cube_sides() -> Value {
    json!([
        {"point": [0.5, 0, 0], "normal": [-1, 0, 0]}, {"point": [-0.5, 0, 0], "normal": [1, 0, 0]},
        {"point": [0, 0.5, 0], "normal": [0, -1, 0]}, {"point": [0, -0.5, 0], "normal": [0, 1, 0]}
    ])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn contacts_scene_grasps_and_errors() {
    let h = Harness::start("grasp-quality").await;

    // The reference value of the notes (μ = 0.5, m = 8, λ = 1).
    let (s, v) = h
        .post(&json!({"contacts": cube_sides(), "centre": [0, 0, 0], "lambda": 1}))
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["force_closure"], true);
    assert_eq!(v["rank"], 6);
    assert_eq!(v["wrenches"], 32);
    assert!(
        (v["epsilon"].as_f64().unwrap_or(0.0) - 0.169650).abs() < 1e-5,
        "{v}"
    );
    assert_eq!(v["grasps"], json!([]));
    // μ = 1 and m = 4; the default λ = 1 / 0.5.
    let (_, v) = h
        .post(&json!({"contacts": cube_sides(), "centre": [0, 0, 0], "lambda": 1, "mu": 1.0}))
        .await;
    assert!(
        (v["epsilon"].as_f64().unwrap_or(0.0) - 0.339299).abs() < 1e-5,
        "{v}"
    );
    let (_, v) = h
        .post(&json!({"contacts": cube_sides(), "centre": [0, 0, 0], "lambda": 1, "cone_edges": 4}))
        .await;
    assert!(
        (v["epsilon"].as_f64().unwrap_or(0.0) - 0.144338).abs() < 1e-5,
        "{v}"
    );
    let (_, v) = h
        .post(&json!({"contacts": cube_sides(), "centre": [0, 0, 0]}))
        .await;
    assert_eq!(v["lambda"], 2.0);
    // Two opposite contacts: rank 5, never force closure; soft fingers close it.
    let two = json!([cube_sides()[0], cube_sides()[1]]);
    let (s, v) = h.post(&json!({"contacts": two, "centre": [0, 0, 0]})).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(
        (v["rank"].clone(), v["force_closure"].clone()),
        (json!(5), json!(false))
    );
    assert_eq!(v["epsilon"], 0.0);
    let (_, v) = h
        .post(&json!({"contacts": two, "centre": [0, 0, 0], "soft_finger": 0.05}))
        .await;
    assert_eq!(v["rank"], 6, "{v}");

    // Scene grasps: every wok grasp scored with the object's centre and λ.
    let (s, v) = h.post(&json!({"scene": "kitchen", "object": "wok"})).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    let grasps = v["grasps"].as_array().expect("grasps");
    assert_eq!(grasps.len(), 25);
    assert!(
        v["force_closure"].is_null() && v["epsilon"].is_null(),
        "{v}"
    );
    let radius = v["radius"].as_f64().expect("radius");
    assert!(radius > 0.0);
    assert!((v["lambda"].as_f64().unwrap_or(0.0) - 1.0 / radius).abs() < 1e-12);
    for g in grasps {
        assert!(g["name"].as_str().is_some_and(|n| n.starts_with("wok_")));
        let rank = g["rank"].as_u64().expect("rank");
        let fc = g["force_closure"].as_bool().expect("force_closure");
        let eps = g["epsilon"].as_f64().expect("epsilon");
        assert!(
            rank <= 6 && (fc == (eps > 0.0)) && (!fc || rank == 6),
            "{g}"
        );
        assert_eq!(
            g["wrenches"].as_u64(),
            g["contacts"].as_u64().map(|c| c * 8)
        );
    }
    // A subset, plus contacts in the object frame scored with the same centre and λ.
    let (s, v) = h
        .post(
            &json!({"scene": "kitchen", "object": "wok", "grasps": ["wok_r_00", "wok_l_04"],
            "contacts": cube_sides()}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    let names: Vec<&str> = v["grasps"]
        .as_array()
        .expect("grasps")
        .iter()
        .filter_map(|g| g["name"].as_str())
        .collect();
    assert_eq!(names, ["wok_r_00", "wok_l_04"]);
    assert_eq!(v["rank"], 6);
    assert!((v["lambda"].as_f64().unwrap_or(0.0) - 1.0 / radius).abs() < 1e-12);
    // The same grasp scored alone gives the same answer.
    let (_, one) = h
        .post(&json!({"scene": "kitchen", "object": "wok", "grasps": ["wok_r_00"]}))
        .await;
    assert_eq!(one["grasps"][0], v["grasps"][0]);

    // Errors name the field.
    let c = cube_sides();
    let cases: Vec<(Value, StatusCode, &str)> = vec![
        (
            json!({"contacts": c, "centre": [0, 0, 0], "mu": 0}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "mu",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "mu": -0.5}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "mu",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "cone_edges": 2}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "cone_edges",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "cone_edges": 33}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "cone_edges",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "cone_edges": -1}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "cone_edges",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "lambda": 0}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "lambda",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "soft_finger": -1}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "soft_finger",
        ),
        (
            json!({"contacts": c}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "centre",
        ),
        (
            json!({"centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts",
        ),
        (
            json!({"contacts": c, "centre": [0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "centre",
        ),
        (
            json!({"contacts": [{"point": [0, 0, 0], "normal": [0, 0, 0]}], "centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts[0].normal",
        ),
        (
            json!({"contacts": [{"point": [0, 0, 0], "normal": [0, 0]}], "centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts[0].normal",
        ),
        (
            json!({"contacts": [{"point": [0, 0, 0], "normal": [0, 0, 1], "force": 1}], "centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts[0].force",
        ),
        (
            json!({"contacts": vec![c[0].clone(); 65], "centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts",
        ),
        (
            json!({"contacts": c, "centre": [0, 0, 0], "frobnicate": true}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "frobnicate",
        ),
        (
            json!({"scene": "kitchen"}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "object",
        ),
        (
            json!({"object": "wok", "contacts": c, "centre": [0, 0, 0]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "scene",
        ),
        (
            json!({"scene": "nope", "object": "wok"}),
            StatusCode::NOT_FOUND,
            "scene",
        ),
        (
            json!({"scene": "kitchen", "object": "nope"}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "object",
        ),
        (
            json!({"scene": "kitchen", "object": "wok", "grasps": ["wok_r_00", "nope"]}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "grasps[1]",
        ),
        (
            json!({"scene": "kitchen", "object": "wok", "mu": 0}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "mu",
        ),
        // 40 contacts × 32 edges = 1280 primitive wrenches > 1024.
        (
            json!({"contacts": vec![c[0].clone(); 40], "centre": [0, 0, 0], "cone_edges": 32}),
            StatusCode::UNPROCESSABLE_ENTITY,
            "contacts",
        ),
    ];
    for (body, status, f) in cases {
        let (s, v) = h.post(&body).await;
        assert_eq!(s, status, "{body} → {v}");
        assert_eq!(field(&v), f, "{body} → {v}");
        assert!(
            v["error"]["message"]
                .as_str()
                .is_some_and(|m| !m.is_empty()),
            "{v}"
        );
    }
    // NaN and infinities are not JSON: 400 (a number too large for f64 is rejected as well).
    for body in [
        r#"{"contacts": [{"point": [NaN, 0, 0], "normal": [0, 0, 1]}], "centre": [0, 0, 0]}"#,
        r#"{"contacts": [{"point": [Infinity, 0, 0], "normal": [0, 0, 1]}], "centre": [0, 0, 0]}"#,
        r#"{"contacts": [{"point": [1e999, 0, 0], "normal": [0, 0, 1]}], "centre": [0, 0, 0]}"#,
    ] {
        let (s, v) = h.raw(body.to_string()).await;
        assert_eq!(s, StatusCode::BAD_REQUEST, "{body} → {v}");
        assert_eq!(v["error"]["code"], "malformed_json", "{v}");
        assert_eq!(field(&v), "contacts[0].point[0]", "{v}");
    }
    // Finite values whose wrenches overflow.
    let (s, v) = h
        .post(
            &json!({"contacts": [{"point": [1.5e308, 0, 0], "normal": [0, 1, 0]}],
            "centre": [-1.5e308, 0, 0]}),
        )
        .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "contacts[0].point", "{v}");

    // An uploaded scene: an object whose grasp has 40 contacts (a ring around a sphere) is
    // scored with 8 cone edges (320 wrenches) but not with 32 (1280 > 1024).
    let ring: Vec<Value> = (0..40)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / 40.0;
            let z = if k % 2 == 0 { 0.02 } else { -0.02 };
            json!({"point": [0.1 * a.cos(), 0.1 * a.sin(), z], "normal": [-a.cos(), -a.sin(), 0.0]})
        })
        .collect();
    let scene = json!({"name": "gq", "objects": [{"name": "ball", "mass": 1.0,
        "shapes": [{"type": "sphere", "radius": 0.1}],
        "grasps": [{"name": "ring", "end_effector": "right_hand", "tcp": {}, "type": "power",
            "contacts": ring}]}]});
    let r = h
        .http
        .put(format!("{}/v1/scenes/gq", h.base))
        .json(&scene)
        .send()
        .await
        .expect("PUT scene");
    assert_eq!(r.status(), StatusCode::CREATED);
    let (s, v) = h.post(&json!({"scene": "gq", "object": "ball"})).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["grasps"][0]["contacts"], 40);
    assert_eq!(v["grasps"][0]["wrenches"], 320);
    assert_eq!(v["grasps"][0]["force_closure"], true, "{v}");
    assert!(
        (v["radius"].as_f64().unwrap_or(0.0) - 0.1).abs() < 1e-12,
        "{v}"
    );
    let (s, v) = h
        .post(&json!({"scene": "gq", "object": "ball", "cone_edges": 32}))
        .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "cone_edges", "{v}");

    // The endpoint is in the served spec.
    let spec: Value = h
        .http
        .get(format!("{}/openapi.json", h.base))
        .send()
        .await
        .expect("spec")
        .json()
        .await
        .expect("spec json");
    assert!(spec["paths"]["/v1/grasp-quality"]["post"].is_object());
    h.stop().await;
}
