//! Every request field of every job kind is validated at submission: for each numeric field
//! of each kind's schema in the spec (`api/openapi.json`), a value just inside each of its
//! bounds is accepted (202, the job is cancelled at once) and a value just outside is refused
//! with 422 naming the field — never accepted to fail later. Every numeric field has a bound in
//! the spec, so a new unbounded field fails here.

mod common;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use manyhands::server::{Config, Server};
use serde_json::{json, Value};

/// A body of each kind that the server accepts (names of the shipped scenes and robots).
fn base_bodies() -> Vec<Value> {
    vec![
        json!({"kind": "joint_space", "scene": "empty",
            "robots": [{"name": "armar", "group": "right_arm", "goal": {"right_elbow": -1.0}}]}),
        json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 100}),
        json!({"kind": "reach", "scene": "kitchen", "robot": "armar", "group": "torso_right_arm",
            "object": "wok"}),
        json!({"kind": "regrasp", "scene": "handoff",
            "giver": {"robot": "armar_a", "group": "torso_right_arm"},
            "receiver": {"robot": "armar_b", "group": "torso_left_arm"}, "object": "wok"}),
        json!({"kind": "kitchen_task", "scene": "kitchen"}),
        json!({"kind": "bimanual", "scene": "kitchen", "robot": "armar", "object": "table"}),
        json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table"}),
        json!({"kind": "schedule", "scene": "kitchen_two",
            "trajectories": [{"robot": "armar_a", "joints": ["right_elbow"], "path": [[0.0]]}]}),
        // Few positions, so that every orientation level stays within the frame bound
        // (positions × orientations, a rule of the spec across the two fields).
        json!({"kind": "grasp_list", "robot": "justin", "hand": "left_hand", "mesh": "statuette",
            "params": {"positions": 1}}),
        json!({"kind": "pick_place", "scene": "pick_place", "robot": "justin",
            "object": "statuette", "pick_hand": "right_hand", "place_hand": "left_hand"}),
        json!({"kind": "multi_arm", "scene": "arms_crossing",
            "robots": [{"name": "armar_a", "group": "right_arm", "goal": {"right_elbow": -1.0}}]}),
    ]
}

/// The schema of `v` with `$ref`s resolved and `null` alternatives dropped.
fn resolve<'a>(spec: &'a Value, v: &'a Value) -> &'a Value {
    if let Some(r) = v["$ref"].as_str() {
        let name = r.trim_start_matches("#/components/schemas/");
        return resolve(spec, &spec["components"]["schemas"][name]);
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(alts) = v[key].as_array() {
            let non_null: Vec<&Value> = alts.iter().filter(|a| a["type"] != "null").collect();
            if non_null.len() == 1 {
                return resolve(spec, non_null[0]);
            }
        }
    }
    v
}

fn types(v: &Value) -> Vec<String> {
    match &v["type"] {
        Value::String(s) => vec![s.clone()],
        Value::Array(a) => a
            .iter()
            .filter_map(|t| t.as_str().map(str::to_string))
            .collect(),
        _ => Vec::new(),
    }
}

/// A numeric field: its path in the body (`params.positions`, `trajectories[0].max_acceleration`),
/// whether it is an integer, and its bounds.
#[derive(Debug, Clone)]
struct NumField {
    path: Vec<String>,
    integer: bool,
    schema: Value,
}

impl NumField {
    fn name(&self) -> String {
        let mut s = String::new();
        for p in &self.path {
            if p.starts_with('[') || s.is_empty() {
                s.push_str(p);
            } else {
                s.push('.');
                s.push_str(p);
            }
        }
        s
    }
}

/// The numeric fields of `schema` (an object), recursively through objects and the first
/// element of arrays of objects (which the base body must have).
fn numeric_fields(spec: &Value, schema: &Value, prefix: &[String], out: &mut Vec<NumField>) {
    let Some(props) = schema["properties"].as_object() else {
        return;
    };
    for (name, p) in props {
        let p = resolve(spec, p);
        let t = types(p);
        let mut path = prefix.to_vec();
        path.push(name.clone());
        if t.iter().any(|t| t == "number" || t == "integer") {
            out.push(NumField {
                path,
                integer: t.iter().any(|t| t == "integer"),
                schema: p.clone(),
            });
        } else if t.iter().any(|t| t == "object") && p["properties"].is_object() {
            numeric_fields(spec, p, &path, out);
        } else if t.iter().any(|t| t == "array") {
            let items = resolve(spec, &p["items"]);
            if items["properties"].is_object() {
                path.push("[0]".into());
                numeric_fields(spec, items, &path, out);
            }
        }
    }
}

/// `body` with the field at `path` set to `x` (objects on the way created).
fn with(body: &Value, path: &[String], x: Value) -> Value {
    let mut b = body.clone();
    let mut cur = &mut b;
    for (i, p) in path.iter().enumerate() {
        let last = i + 1 == path.len();
        if let Some(idx) = p.strip_prefix('[').and_then(|p| p.strip_suffix(']')) {
            let idx: usize = idx.parse().expect("index");
            cur = &mut cur[idx];
        } else if last {
            cur[p.as_str()] = x.clone();
        } else {
            if cur.get(p.as_str()).is_none_or(Value::is_null) {
                cur[p.as_str()] = json!({});
            }
            cur = &mut cur[p.as_str()];
        }
    }
    b
}

/// (value just inside, value just outside) of each bound of `f`.
fn probes(f: &NumField) -> Vec<(String, Value, Value)> {
    let s = &f.schema;
    let mut out = Vec::new();
    let num = |x: f64| {
        if f.integer {
            json!(x as i64)
        } else {
            json!(x)
        }
    };
    let step = |x: f64| {
        if f.integer {
            1.0
        } else {
            (x.abs() * 1e-6).max(1e-9)
        }
    };
    if let Some(m) = s["minimum"].as_f64() {
        out.push((format!("minimum {m}"), num(m), num(m - step(m))));
    }
    if let Some(m) = s["exclusiveMinimum"].as_f64() {
        out.push((format!("exclusiveMinimum {m}"), num(m + step(m)), num(m)));
    }
    if let Some(m) = s["maximum"].as_f64() {
        out.push((format!("maximum {m}"), num(m), num(m + step(m))));
    }
    if let Some(m) = s["exclusiveMaximum"].as_f64() {
        out.push((format!("exclusiveMaximum {m}"), num(m - step(m)), num(m)));
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_numeric_field_of_every_kind_is_checked_at_submission_at_its_bounds() {
    let spec: Value =
        serde_json::from_str(&manyhands::server::openapi::openapi_json()).expect("spec");
    let kinds = spec["components"]["schemas"]["PlanRequest"]["oneOf"]
        .as_array()
        .expect("PlanRequest.oneOf")
        .clone();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!("manyhands-bounds-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    // One worker, held by a long sweep: every job accepted here waits in the queue and is
    // cancelled there, so nothing but the validation runs.
    cfg.workers = 1;
    cfg.query_threads = 2;
    cfg.max_queue = 10_000;
    cfg.shutdown_grace = Duration::from_millis(200);
    cfg.drain = Duration::ZERO;
    let server = Server::start(cfg).await.expect("server");
    let base = format!("http://{}", server.addr());
    let http = reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .expect("client");
    let post = |body: Value| {
        let http = http.clone();
        let url = format!("{base}/v1/plans");
        async move {
            let r = http.post(url).json(&body).send().await.expect("POST");
            let s = r.status().as_u16();
            (s, r.json::<Value>().await.unwrap_or(Value::Null))
        }
    };
    let cancel = |id: String| {
        let http = http.clone();
        let url = format!("{base}/v1/plans/{id}");
        async move {
            let r = http.delete(url).send().await.expect("DELETE");
            assert!(r.status().is_success(), "cancel {id}: {}", r.status());
        }
    };
    let (s, blocker) = post(json!({"kind": "collision_sweep", "scene": "kitchen",
        "samples": 1_000_000_000u64, "time_limit": 120}))
    .await;
    assert_eq!(s, 202, "{blocker}");
    let blocker_id = blocker["id"].as_str().expect("id").to_string();
    let t0 = Instant::now();
    loop {
        let j: Value = http
            .get(format!("{base}/v1/plans/{blocker_id}"))
            .send()
            .await
            .expect("GET")
            .json()
            .await
            .expect("job");
        if j["state"] == "running" {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the sweep never ran"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let bodies = base_bodies();
    assert_eq!(bodies.len(), kinds.len(), "a base body per kind");
    let mut checked = 0;
    let mut failures = Vec::new();
    for body in &bodies {
        let kind = body["kind"].as_str().expect("kind");
        let schema = kinds
            .iter()
            .find(|k| k["properties"]["kind"]["enum"][0] == kind)
            .unwrap_or_else(|| panic!("no schema for {kind}"));
        // The base body is accepted as it is.
        let (s, j) = post(body.clone()).await;
        assert_eq!(s, 202, "{kind} base body: {j}");
        cancel(j["id"].as_str().expect("id").to_string()).await;
        let mut fields = Vec::new();
        numeric_fields(&spec, schema, &[], &mut fields);
        assert!(!fields.is_empty(), "{kind}: no numeric field");
        for f in &fields {
            let name = f.name();
            let bounds = probes(f);
            // Every numeric field is bounded below in the spec (a seed by its type's 0).
            assert!(
                !bounds.is_empty(),
                "{kind}.{name} has no bound in the spec: {}",
                f.schema
            );
            for (what, inside, outside) in bounds {
                let (s, j) = post(with(body, &f.path, inside.clone())).await;
                if s == 202 {
                    cancel(j["id"].as_str().expect("id").to_string()).await;
                } else {
                    failures.push(format!("{kind}.{name} = {inside} (inside {what}): {s} {j}"));
                }
                // u64 fields: a negative number is refused by the type (422 naming it too).
                let (s, j) = post(with(body, &f.path, outside.clone())).await;
                let field = j["error"]["field"].as_str().unwrap_or("");
                if s != 422 || field != name {
                    failures.push(format!(
                        "{kind}.{name} = {outside} (outside {what}): {s} {j}"
                    ));
                }
                checked += 2;
            }
        }
    }
    cancel(blocker_id).await;
    server.shutdown().await.expect("shutdown");
    assert!(
        failures.is_empty(),
        "{} of {checked} probes failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(checked > 150, "{checked}");
}
