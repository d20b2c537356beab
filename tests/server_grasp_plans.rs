//! The grasp planners over HTTP (`POST /v1/plans` kinds `reach`, `regrasp`, `kitchen_task`,
//! `bimanual`): the real server on an ephemeral loopback port. Each answer is a plan of world
//! configurations whose last waypoint puts the hands where the events say (checked against
//! `POST /v1/fk`), and bad requests name their field.

mod common;
use common::server::{field, start, Harness};

use reqwest::StatusCode;
use serde_json::{json, Value};

/// `POST /v1/fk` of armar's `config`: its right TCP is near the kitchen wok (which lies still at
/// (0.65, -0.2, 0.9)).
async fn assert_right_tcp_at_wok(h: &Harness, config: &Value) {
    let (s, fk) = h
        .post(
            "/v1/fk",
            &json!({"robot": "armar", "config": config, "links": ["right_tcp"]}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{fk}");
    let p = &fk["links"][0]["pose"]["position"];
    let d = [0.65, -0.2, 0.9]
        .iter()
        .enumerate()
        .map(|(k, w)| (p[k].as_f64().unwrap_or(f64::NAN) - w).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(d < 0.4, "right TCP {p} is {d} m from the wok");
}

/// The plan's last waypoint as a `{joint: value}` map of `robot`.
fn last_config(result: &Value, robot: &str) -> Value {
    let vars = result["variables"].as_array().expect("variables");
    let last = result["waypoints"]
        .as_array()
        .and_then(|w| w.last())
        .and_then(|w| w.as_array())
        .expect("waypoints");
    let mut m = serde_json::Map::new();
    for (n, v) in vars.iter().zip(last) {
        let n = n.as_str().unwrap_or("");
        if let Some(j) = n.strip_prefix(&format!("{robot}/")) {
            m.insert(j.to_string(), v.clone());
        }
    }
    Value::Object(m)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grasp_planners_over_http() {
    let h = start("all").await;
    // reach: one phase, a grasp event at the last waypoint.
    let req = json!({"kind": "reach", "scene": "kitchen", "robot": "armar",
        "group": "torso_right_arm", "object": "wok", "seed": 3, "time_limit": 20});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let r = &v["result"];
    assert_eq!(r["phases"].as_array().map(|p| p.len()), Some(1), "{r}");
    assert_eq!(r["events"][0]["kind"], "grasp");
    let n = r["waypoints"].as_array().map(|w| w.len()).unwrap_or(0);
    assert_eq!(r["events"][0]["waypoint"].as_u64(), Some(n as u64 - 1));
    assert!(
        r["phases"][0]["stats"]["ik_solutions"]
            .as_u64()
            .unwrap_or(0)
            >= 1
    );
    // The same request and seed give the same plan.
    let (_, v2) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(v2["result"]["waypoints"], r["waypoints"]);
    // FK of the last waypoint: the right TCP is where a wok grasp puts it (the wok lies still).
    assert_right_tcp_at_wok(&h, &last_config(r, "armar")).await;

    // The same query with J+-RRT (000 Alg. 1–2): no IK solutions, Jacobian steps instead.
    let mut jreq = req.clone();
    jreq["planner"] = json!("j_plus_rrt");
    jreq["seed"] = json!(2);
    let (s, v) = h.post("/v1/plans?wait=60", &jreq).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let r = &v["result"];
    assert_eq!(r["phases"][0]["planner"], "j_plus_rrt", "{r}");
    assert_eq!(r["events"][0]["kind"], "grasp");
    assert!(
        r["phases"][0]["stats"]["jacobian_steps"]
            .as_u64()
            .unwrap_or(0)
            >= 1,
        "{r}"
    );

    // regrasp (hand-off between two robots), kitchen task, bimanual.
    let req = json!({"kind": "regrasp", "scene": "handoff",
        "giver": {"robot": "armar_a", "group": "torso_right_arm"},
        "receiver": {"robot": "armar_b", "group": "torso_left_arm"},
        "object": "wok", "time_limit": 20});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let kinds: Vec<&str> = v["result"]["events"]
        .as_array()
        .expect("events")
        .iter()
        .filter_map(|e| e["robot"].as_str())
        .collect();
    assert_eq!(kinds, vec!["armar_a", "armar_b", "armar_a"]);

    // Re-grasp of the kitchen wok from the right hand to the left with the J+ planners (000
    // Alg. 1–2 to grasp, dual-arm J+-RRT, Alg. 4–5, to re-grasp): grasp, grasp, release.
    let req = json!({"kind": "regrasp", "scene": "kitchen",
        "giver": {"robot": "armar", "group": "torso_right_arm"},
        "receiver": {"robot": "armar", "group": "torso_left_arm"},
        "object": "wok", "planner": "j_plus_rrt", "seed": 4, "time_limit": 20});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    common::assert_j_plus_regrasp_plan(&v["result"]);

    let (s, v) = h
        .post(
            "/v1/plans?wait=60",
            &json!({"kind": "kitchen_task", "scene": "kitchen", "time_limit": 30}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    assert_eq!(v["result"]["phases"].as_array().map(|p| p.len()), Some(4));
    assert_eq!(v["result"]["events"].as_array().map(|p| p.len()), Some(4));

    let (s, v) = h
        .post(
            "/v1/plans?wait=60",
            &json!({"kind": "bimanual", "scene": "kitchen", "robot": "armar", "object": "table", "time_limit": 30}),
        )
        .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    assert_eq!(v["result"]["phases"][0]["planner"], "bimanual_ik_rrt");
    assert_eq!(v["result"]["events"].as_array().map(|p| p.len()), Some(2));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grasp_plan_requests_name_their_bad_field() {
    let h = start("bad").await;
    let base = json!({"kind": "reach", "scene": "kitchen", "robot": "armar",
        "group": "torso_right_arm", "object": "wok"});
    for (key, val, want) in [
        ("robot", json!("robbie"), "robot"),
        ("group", json!("tail"), "group"),
        ("object", json!("spoon"), "object"),
        ("p_ik", json!(1.5), "p_ik"),
        ("ik_tries", json!(0), "ik_tries"),
        ("time_limit", json!(-2), "time_limit"),
        ("planner", json!("prm"), "planner"),
    ] {
        let mut b = base.clone();
        b[key] = val;
        let (s, v) = h.post("/v1/plans", &b).await;
        assert!(s.is_client_error(), "{key}: {s} {v}");
        assert_eq!(field(&v), want, "{v}");
    }
    let mut b = base.clone();
    b["colour"] = json!("red");
    let (s, _) = h.post("/v1/plans", &b).await;
    assert!(s.is_client_error(), "unknown field: {s}");
    let bad = json!({"kind": "regrasp", "scene": "handoff",
        "giver": {"robot": "armar_a", "group": "torso_right_arm"},
        "receiver": {"robot": "armar_c", "group": "torso_left_arm"}, "object": "wok"});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert!(s.is_client_error(), "{s} {v}");
    assert_eq!(field(&v), "receiver.robot", "{v}");
    // A held grasp that does not exist: the job fails cleanly, naming it.
    let bad = json!({"kind": "regrasp", "scene": "kitchen",
        "giver": {"robot": "armar", "group": "torso_right_arm"},
        "receiver": {"robot": "armar", "group": "torso_left_arm"}, "object": "wok",
        "held": "wok_r_99"});
    let (s, v) = h.post("/v1/plans?wait=30", &bad).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "failed", "{v}");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("wok_r_99"),
        "{v}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn randomized_grasp_ik_over_http() {
    let h = start("ik").await;
    let req = json!({"scene": "kitchen", "robot": "armar", "group": "torso_right_arm",
        "object": "wok", "seed": 5});
    let (s, v) = h.post("/v1/ik/grasp", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["found"], true, "{v}");
    assert!(
        v["grasp"].as_str().unwrap_or("").starts_with("wok_r"),
        "{v}"
    );
    assert_eq!(v["joints"].as_array().map(|j| j.len()), Some(10), "{v}");
    assert_eq!(v["solution"].as_array().map(|j| j.len()), Some(10), "{v}");
    assert!(v["tries"].as_u64().unwrap_or(0) >= 1 && v["ik_calls"].as_u64().unwrap_or(0) >= 1);
    // Same request and seed, same answer.
    let (_, v2) = h.post("/v1/ik/grasp", &req).await;
    assert_eq!(v2["solution"], v["solution"]);
    assert_eq!(v2["grasp"], v["grasp"]);
    // The hand is at the wok.
    assert_right_tcp_at_wok(&h, &v["config"]).await;
    // Bad fields are named.
    for (key, val, want) in [
        ("robot", json!("robbie"), "robot"),
        ("group", json!("right_hand"), "group"),
        ("object", json!("spoon"), "object"),
        ("max_tries", json!(0), "max_tries"),
        ("psi_samples", json!(100000), "psi_samples"),
    ] {
        let mut b = req.clone();
        b[key] = val;
        let (s, v) = h.post("/v1/ik/grasp", &b).await;
        assert!(s.is_client_error(), "{key}: {s} {v}");
        assert_eq!(field(&v), want, "{v}");
    }
    let mut b = req.clone();
    b["scene"] = json!("attic");
    let (s, _) = h.post("/v1/ik/grasp", &b).await;
    assert_eq!(s, StatusCode::NOT_FOUND);
}
