//! Job kinds `multi_robot`, `schedule` and `multi_arm` over HTTP: the real server on an ephemeral loopback
//! port, SSE events of a Multi-Robot-RRT job, and bad schedules refused with the field named.

mod common;
use common::server::{field, start};

use std::time::Duration;

use reqwest::StatusCode;
use serde_json::{json, Value};

/// `result.trajectories`: one JointTrajectory per robot (`variables[k]` its joint names),
/// sampled every `period` s on one clock (the schedule's duration), at rest at both ends, every
/// point within the robot's velocity and acceleration limits, with `grasps` events each.
fn assert_common_clock(
    result: &Value,
    names: &[&str],
    variables: &[Value],
    period: f64,
    grasps: usize,
) {
    let armar = common::scene("kitchen_two").robots[0].robot.clone();
    let duration = result["schedule"]["duration"]
        .as_f64()
        .or(result["duration"].as_f64())
        .expect("duration");
    let mut times: Option<Vec<Value>> = None;
    for (name, vars) in names.iter().zip(variables) {
        let t = &result["trajectories"][name];
        assert_eq!(&t["joint_names"], vars, "{name}");
        assert_eq!(t["sample_period"].as_f64(), Some(period), "{name}");
        assert_eq!(t["duration"].as_f64(), Some(duration), "{name}");
        assert_eq!(
            t["events"].as_array().map(|e| e.len()),
            Some(grasps),
            "{name}"
        );
        let pts = t["points"].as_array().expect("points");
        let these: Vec<Value> = pts.iter().map(|p| p["time_from_start"].clone()).collect();
        if let Some(first) = &times {
            assert_eq!(first, &these, "one clock");
        }
        times = Some(these);
        assert!(pts.len() as f64 >= duration / period);
        for (i, p) in pts.iter().enumerate() {
            for (k, joint) in vars.as_array().expect("vars").iter().enumerate() {
                let var = armar.var(joint.as_str().unwrap_or("")).expect("joint");
                let v = p["velocities"][k].as_f64().expect("v").abs();
                let a = p["accelerations"][k].as_f64().expect("a").abs();
                assert!(
                    v <= armar.velocity_limit(var) * (1.0 + 1e-6),
                    "{name} {i} {joint}: v {v}"
                );
                assert!(
                    a <= armar.acceleration_limit(var) * (1.0 + 1e-6),
                    "{name} {i} {joint}: a {a}"
                );
                if i == 0 || i + 1 == pts.len() {
                    assert!(v < 1e-12, "{name}: not at rest");
                }
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn multi_robot_job_runs_end_to_end_with_events() {
    let h = start("multi-robot").await;
    let req = json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table",
        "seed": 2, "deterministic": true, "time_limit": 60, "sample_period": 0.05});
    let (s, v) = h.post("/v1/plans", &req).await;
    assert_eq!(s, StatusCode::ACCEPTED, "{v}");
    let id = v["id"].as_str().expect("id").to_string();
    let mut resp = h
        .http
        .get(format!("{}/v1/plans/{id}/events", h.base))
        .send()
        .await
        .expect("events");
    assert_eq!(resp.status(), StatusCode::OK);
    let mut text = String::new();
    while let Some(chunk) = tokio::time::timeout(Duration::from_secs(90), resp.chunk())
        .await
        .expect("event in time")
        .expect("chunk")
    {
        text.push_str(&String::from_utf8_lossy(&chunk));
        if text.contains("event: end") {
            break;
        }
    }
    // Progress snapshots: at most one per 50 ms within a phase, so which of the planner's
    // cumulative snapshots arrive depends on timing; the phases always do.
    assert!(text.contains("\"phase\":\"reachability grids\""), "{text}");
    assert!(text.contains("\"planner\":\"multi_robot_rrt\""), "{text}");
    // A snapshot of a new phase is published at once, whatever the throttle.
    assert!(text.contains("\"phase\":\"phase space\""), "{text}");
    let resp = h
        .http
        .get(format!("{}/v1/plans/{id}", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(resp.status(), StatusCode::OK);
    let v: Value = resp.json().await.expect("json");
    assert_eq!(v["state"], "succeeded", "{v}");
    // The job record keeps the planner's last snapshot (never dropped by the throttle).
    assert_eq!(v["progress"]["phase"], "phase space", "{}", v["progress"]);
    let r = &v["result"];
    assert_eq!(r["robots"].as_array().map(|a| a.len()), Some(2), "{r}");
    assert!(r["score"]["force_closure"].as_bool().unwrap_or(false));
    let sched = &r["schedule"];
    assert_eq!(sched["robots"], json!(["armar_a", "armar_b"]));
    let pts = sched["points"].as_array().expect("points");
    assert!(pts.len() >= 2);
    assert_eq!(pts[0]["time_from_start"], 0.0);
    assert!(sched["samples"].as_array().is_some_and(|s| s.len() >= 2));
    assert_eq!(r["events"].as_array().map(|e| e.len()), Some(4));
    for k in [
        "ik_results",
        "solution_trajectories",
        "collision_checks",
        "combinations_checked",
        "phase_space_time_ms",
    ] {
        assert!(r["stats"][k].is_number(), "{k}: {}", r["stats"]);
    }

    // The same trajectories through kind `schedule`, given as `joints` + `path`.
    let trajs: Vec<Value> = r["robots"]
        .as_array()
        .expect("robots")
        .iter()
        .map(|rb| json!({"robot": rb["name"], "joints": rb["variables"], "path": rb["waypoints"]}))
        .collect();
    let req = json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": trajs});
    let (s, v) = h.post("/v1/plans?wait=30", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    assert!(v["result"]["duration"].as_f64().unwrap_or(0.0) > 0.0, "{v}");

    // Every robot's JointTrajectory on the common clock, within armar's limits, in both.
    let names = ["armar_a", "armar_b"];
    let variables: Vec<Value> = r["robots"]
        .as_array()
        .expect("robots")
        .iter()
        .map(|rb| rb["variables"].clone())
        .collect();
    assert_common_clock(r, &names, &variables, 0.05, 2);
    assert_common_clock(&v["result"], &names, &variables, 0.01, 0);

    // A trajectory through the table: refused, naming the robot and the waypoint.
    let bad = json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["base_x", "base_y"], "path": [[0.0, 0.0], [2.75, 0.7]]}]});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "trajectories[0].path[1]", "{v}");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("armar_a"),
        "{v}"
    );
    // Unknown joint and robot.
    let bad = json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["nope"], "path": [[0.0]]}]});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(field(&v), "trajectories[0].joints[0]", "{v}");
    // Trajectories each free alone that end in the same spot: no schedule exists. The job
    // fails with its own code and wording (no goal is involved).
    let (s, v) = h.post("/v1/plans?wait=30", &same_end_schedule()).await;
    assert!(s.is_success(), "{s}: {v}");
    assert_eq!(v["state"], "failed", "{v}");
    assert_eq!(v["error"]["code"], "no_schedule", "{v}");
    let msg = v["error"]["message"].as_str().unwrap_or("");
    assert!(
        msg.starts_with("no collision-free schedule") && msg.contains("final configurations"),
        "{v}"
    );
    assert!(!msg.contains("goal"), "{v}");
    let bad = json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table", "robots": ["armar_a", "ghost"]});
    let (s, v) = h.post("/v1/plans", &bad).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert!(field(&v).starts_with("robots[1]"), "{v}");
    h.server.shutdown().await.expect("shutdown");
}

/// The `arms_crossing` task as a `multi_arm` request: armar_a's right arm and armar_b's left arm
/// to the scene's `goal` configurations.
fn multi_arm_body() -> Value {
    let text =
        std::fs::read_to_string(common::root().join("scenes/arms_crossing.json")).expect("scene");
    let scene: Value = serde_json::from_str(&text).expect("json");
    let goal = |k: usize| scene["robots"][k]["configs"]["goal"].clone();
    json!({"kind": "multi_arm", "scene": "arms_crossing", "seed": 1, "time_limit": 30,
        "robots": [{"name": "armar_a", "group": "right_arm", "goal": goal(0)},
                   {"name": "armar_b", "group": "left_arm", "goal": goal(1)}]})
}

/// Kind `multi_arm` over HTTP: the crossing that decoupled scheduling cannot solve is solved
/// (the method and the failed decoupled attempt reported), with one trajectory on one clock,
/// the schedule and the makespans; the same request gives the same plan; bad fields are
/// refused with 422 naming them.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn multi_arm_job_solves_the_crossing_and_names_bad_fields() {
    let h = start("multi-arm").await;
    let body = multi_arm_body();
    let (s, v) = h.post("/v1/plans?wait=60", &body).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let r = &v["result"];
    let method = r["method"].as_str().unwrap_or("");
    assert!(method == "prioritized" || method == "composite", "{r}");
    assert_eq!(r["stats"]["attempts"][0]["method"], "decoupled", "{r}");
    assert_eq!(r["stats"]["attempts"][0]["solved"], false, "{r}");
    assert_eq!(r["certified"], true);
    let (before, after) = (
        r["makespan_before_shortcut"].as_f64().expect("before"),
        r["makespan"].as_f64().expect("makespan"),
    );
    assert!(after > 0.0 && after <= before + 1e-9, "{after} {before}");
    assert_eq!(r["trajectory"]["duration"].as_f64(), Some(after));
    assert_eq!(
        r["trajectory"]["joint_names"].as_array().map(|j| j.len()),
        Some(14)
    );
    let pts = r["schedule"]["points"].as_array().expect("schedule");
    assert_eq!(pts[0]["time_from_start"], 0.0);
    assert_eq!(pts[0]["positions"].as_array().map(|p| p.len()), Some(2));
    let (s, v2) = h.post("/v1/plans?wait=60", &body).await;
    assert_eq!(s, StatusCode::OK, "{v2}");
    assert_eq!(v2["result"]["path"], r["path"], "same request, same plan");

    let bad = |f: &dyn Fn(&mut Value)| {
        let mut b = multi_arm_body();
        f(&mut b);
        b
    };
    let cases: Vec<(Value, &str)> = vec![
        (
            bad(&|b| b["robots"][1]["goal"]["bogus"] = json!(0.1)),
            "robots[1].goal.bogus",
        ),
        (
            bad(&|b| b["robots"][0]["goal"]["left_elbow"] = json!(-1.0)),
            "robots[0].goal.left_elbow",
        ),
        (
            bad(&|b| b["robots"][0]["goal_pose"] = json!({"position": [0.4, -0.3, 1.0]})),
            "robots[0].goal_pose",
        ),
        (
            bad(&|b| {
                b["robots"][0]["goal"] = Value::Null;
                b["robots"][0]["goal_pose"] = json!({"position": [5.0, 5.0, 5.0]});
            }),
            "robots[0].goal_pose",
        ),
        (
            bad(&|b| b["robots"][1]["goal"] = Value::Null),
            "robots[1].goal",
        ),
        (
            bad(&|b| b["robots"][1]["name"] = json!("armar_a")),
            "robots[1].name",
        ),
        (
            bad(&|b| b["robots"][1]["group"] = json!("tentacle")),
            "robots[1].group",
        ),
        (bad(&|b| b["method"] = json!("fastest")), "method"),
        (
            bad(&|b| b["shortcut_iterations"] = json!(20000)),
            "shortcut_iterations",
        ),
        (bad(&|b| b["robots"] = json!([])), "robots"),
    ];
    for (body, want) in cases {
        let (s, v) = h.post("/v1/plans", &body).await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{want}: {v}");
        assert_eq!(field(&v), want, "{v}");
    }
    // Dropped rather than shut down: a graceful shutdown waits out the 5 s drain.
    drop(h);
}

/// A `schedule` body for kitchen_two whose two platforms (side by side, 1.4 m apart) each
/// drive forward 1 m and then sideways into the lane between them, ending in the same spot.
fn same_end_schedule() -> Value {
    json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["base_x", "base_y"],
         "path": [[0.0, 0.0], [1.0, 0.0], [1.0, 0.7]]},
        {"robot": "armar_b", "joints": ["base_x", "base_y"],
         "path": [[0.0, 0.0], [1.0, 0.0], [1.0, -0.7]]}]})
}
