//! Timed trajectories over HTTP: a plan's `trajectory` replayed against the exact checker,
//! the trajectory of a grasp plan with its event times, `POST /v1/trajectories` and its 4xx
//! answers, and joint limits uploaded with a robot.

mod common;

use common::server::{field, start};
use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker};
use reqwest::StatusCode;
use serde_json::{json, Value};

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// Shape checks common to every trajectory: joint names, points on the period, at rest at
/// both ends, the last point at the duration.
fn assert_shape(t: &Value, names: &Value) {
    assert_eq!(&t["joint_names"], names, "{t}");
    let pts = t["points"].as_array().expect("points");
    let period = t["sample_period"].as_f64().expect("period");
    let duration = t["duration"].as_f64().expect("duration");
    assert!(duration > 0.0 && pts.len() >= 2, "{t}");
    let n = names.as_array().map(|a| a.len()).unwrap_or(0);
    for (i, p) in pts.iter().enumerate() {
        for k in ["positions", "velocities", "accelerations"] {
            assert_eq!(p[k].as_array().map(|a| a.len()), Some(n), "point {i} {k}");
        }
        let t = p["time_from_start"].as_f64().expect("time");
        if i + 1 < pts.len() {
            assert!((t - i as f64 * period).abs() < 1e-9, "point {i} at {t}");
        } else {
            assert!((t - duration).abs() < 1e-12);
        }
    }
    for p in [&pts[0], &pts[pts.len() - 1]] {
        assert!(
            f64s(&p["velocities"]).iter().all(|v| v.abs() < 1e-12),
            "not at rest"
        );
    }
    let wps = t["waypoints"].as_array().expect("waypoints");
    assert_eq!(wps[0]["time_from_start"].as_f64(), Some(0.0));
    assert!(
        (wps[wps.len() - 1]["time_from_start"]
            .as_f64()
            .unwrap_or(0.0)
            - duration)
            .abs()
            < 1e-9
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plan_trajectories_replay_free_under_the_exact_checker() {
    let h = start("trajectories").await;
    // A joint-space plan around the obstacle; its trajectory is replayed point by point.
    let req = json!({"kind": "joint_space", "scene": "obstacle", "seed": 4, "time_limit": 20,
        "sample_period": 0.02,
        "robots": [{"name": "armar", "group": "right_arm",
                    "goal": {"right_elbow": -1.0, "right_shoulder_1": -0.4}}]});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    // GET /v1/plans/{id} answers the same result.
    let id = v["id"].as_str().expect("id");
    let got: Value = h
        .http
        .get(format!("{}/v1/plans/{id}", h.base))
        .send()
        .await
        .expect("GET")
        .json()
        .await
        .expect("json");
    assert_eq!(got["result"]["trajectory"], v["result"]["trajectory"]);
    let r = &v["result"];
    let t = &r["trajectory"];
    assert_shape(t, &r["joints"]);
    assert_eq!(t["sample_period"].as_f64(), Some(0.02));
    let path: Vec<Vec<f64>> = serde_json::from_value(r["path"].clone()).expect("path");
    let wps: Vec<Vec<f64>> = t["waypoints"]
        .as_array()
        .expect("waypoints")
        .iter()
        .map(|w| f64s(&w["positions"]))
        .collect();
    assert_eq!(wps, path, "the trajectory's waypoints are the planned path");
    // Replay: every sampled configuration, in the scene's world, free under the exact checker.
    let scene = common::scene("obstacle");
    let world = CollisionWorld::from_scene(&scene);
    let base = CollisionWorld::start_config(&scene);
    let robot = &world.robots[0].robot;
    let names: Vec<String> = serde_json::from_value(r["joints"].clone()).expect("joints");
    let vars: Vec<usize> = names
        .iter()
        .map(|n| {
            let bare = n.rsplit('/').next().unwrap_or(n);
            world.robots[0].offset + robot.var(bare).expect("joint")
        })
        .collect();
    let mut exact = ExactChecker::new(&world);
    let pts = t["points"].as_array().expect("points");
    assert!(pts.len() > 10, "{} points", pts.len());
    for (i, p) in pts.iter().enumerate() {
        let mut q = base.clone();
        for (&v, x) in vars.iter().zip(f64s(&p["positions"])) {
            q[v] = x;
        }
        assert!(exact.is_free(&q), "trajectory point {i} collides");
        // Within the robot's limits (URDF velocity, armar.joint_limits.yaml acceleration).
        for (k, (&v, (vel, acc))) in vars
            .iter()
            .zip(
                f64s(&p["velocities"])
                    .into_iter()
                    .zip(f64s(&p["accelerations"])),
            )
            .enumerate()
        {
            let var = v - world.robots[0].offset;
            assert!(
                vel.abs() <= robot.velocity_limit(var) * (1.0 + 1e-6),
                "{i}/{k}"
            );
            assert!(
                acc.abs() <= robot.acceleration_limit(var) * (1.0 + 1e-6),
                "{i}/{k}"
            );
        }
    }
    // Scaled limits give a slower trajectory of the same path.
    let mut slow = req.clone();
    slow["velocity_scaling"] = json!(0.5);
    slow["acceleration_scaling"] = json!(0.25);
    let (_, v2) = h.post("/v1/plans?wait=60", &slow).await;
    assert_eq!(v2["result"]["path"], r["path"]);
    assert!(
        v2["result"]["trajectory"]["duration"]
            .as_f64()
            .unwrap_or(0.0)
            > t["duration"].as_f64().unwrap_or(0.0) * 1.5
    );
    // Bad timing fields are 422s naming the field.
    for (k, x) in [
        ("sample_period", json!(0.0)),
        ("sample_period", json!(1e-6)),
        ("velocity_scaling", json!(1.5)),
        ("acceleration_scaling", json!(0.0)),
    ] {
        let mut bad = req.clone();
        bad[k] = x;
        let (s, v) = h.post("/v1/plans", &bad).await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{k}: {v}");
        assert_eq!(field(&v), k, "{v}");
    }

    // A grasp plan: the trajectory in the scene's variables, the grasp at its time.
    let req = json!({"kind": "reach", "scene": "kitchen", "robot": "armar",
        "group": "torso_right_arm", "object": "wok", "seed": 3, "time_limit": 20});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let r = &v["result"];
    let t = &r["trajectory"];
    assert_shape(t, &r["variables"]);
    assert_eq!(t["sample_period"].as_f64(), Some(0.01));
    let e = &t["events"][0];
    assert_eq!(e["kind"], "grasp");
    assert_eq!(e["waypoint"], r["events"][0]["waypoint"]);
    let w = e["waypoint"].as_u64().expect("waypoint") as usize;
    assert_eq!(
        e["time_from_start"], t["waypoints"][w]["time_from_start"],
        "{e}"
    );
    assert_eq!(e["grasp"], r["events"][0]["grasp"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn post_trajectories_times_a_path_and_refuses_bad_input() {
    let h = start("post-trajectories").await;
    let body = json!({"robot": "armar", "group": "right_arm",
        "waypoints": [[0, 0, 0, 0, 0, 0, 0], [0.5, -0.3, 0.2, -1.0, 0.1, 0.2, 0.3],
                      [0.1, 0.1, 0.1, -0.5, 0, 0, 0]]});
    let (s, t) = h.post("/v1/trajectories", &body).await;
    assert_eq!(s, StatusCode::OK, "{t}");
    let names = json!([
        "right_shoulder_1",
        "right_shoulder_2",
        "right_shoulder_3",
        "right_elbow",
        "right_wrist_1",
        "right_wrist_2",
        "right_wrist_3"
    ]);
    assert_shape(&t, &names);
    // The same by joint names, with a tighter velocity limit on the elbow: slower.
    let mut named = body.clone();
    named.as_object_mut().map(|o| o.remove("group"));
    named["joint_names"] = names.clone();
    named["max_velocity"] = json!({"right_elbow": 0.1});
    let (s, t2) = h.post("/v1/trajectories", &named).await;
    assert_eq!(s, StatusCode::OK, "{t2}");
    assert!(t2["duration"].as_f64() > t["duration"].as_f64());
    for p in t2["points"].as_array().expect("points") {
        assert!(p["velocities"][3].as_f64().unwrap_or(1.0).abs() <= 0.1 * (1.0 + 1e-6));
    }
    let many: Vec<Value> = (0..10_001)
        .map(|i| json!(vec![i as f64 * 1e-4; 7]))
        .collect();
    let cases: Vec<(Value, &str, StatusCode)> = vec![
        (
            json!({"robot": "nobody", "waypoints": [[0]]}),
            "robot",
            StatusCode::NOT_FOUND,
        ),
        (
            json!({"robot": "armar", "joint_names": ["nope"], "waypoints": [[0]]}),
            "joint_names[0]",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": [[0, 0]]}),
            "waypoints[0]",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": []}),
            "waypoints",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": many}),
            "waypoints",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": [[0, 0, 0, 0, 0, 0, 0]],
            "max_acceleration": {"right_elbow": 0.0}}),
            "max_acceleration.right_elbow",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": [[0, 0, 0, 0, 0, 0, 0]],
            "max_velocity": {"left_elbow": 1.0}}),
            "max_velocity.left_elbow",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": [[0, 0, 0, 0, 0, 0, 0]],
            "sample_period": -1}),
            "sample_period",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "waypoints": [[0, 0, 0, 0, 0, 0, 0]],
            "velocity_scaling": 2}),
            "velocity_scaling",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "nope", "waypoints": [[0]]}),
            "group",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        (
            json!({"robot": "armar", "group": "right_arm", "joint_names": ["right_elbow"],
            "waypoints": [[0]]}),
            "group",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
        // 100 000 points at most: a slow path sampled every millisecond is refused.
        (
            json!({"robot": "armar", "group": "right_arm", "sample_period": 0.001,
            "velocity_scaling": 0.01, "acceleration_scaling": 0.01,
            "waypoints": [[0, 0, 0, 0, 0, 0, 0], [2, 0, 0, 0, 0, 0, 0]]}),
            "sample_period",
            StatusCode::UNPROCESSABLE_ENTITY,
        ),
    ];
    for (b, want, status) in cases {
        let (s, v) = h.post("/v1/trajectories", &b).await;
        assert_eq!(s, status, "{want}: {v}");
        assert_eq!(field(&v), want, "{v}");
    }
    // Non-finite values cannot be JSON; a string where a number belongs is a 4xx too.
    let (s, _) = h
        .post(
            "/v1/trajectories",
            &json!({"robot": "armar", "waypoints": [["x"]]}),
        )
        .await;
    assert!(s.is_client_error());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploaded_joint_limits_time_the_robot() {
    let h = start("joint-limits").await;
    let urdf = std::fs::read_to_string(common::root().join("robots/armar.urdf")).expect("urdf");
    let srdf = std::fs::read_to_string(common::root().join("robots/armar.srdf")).expect("srdf");
    let path = json!([[0, 0, 0, 0, 0, 0, 0], [0, 0, 0, -1.0, 0, 0, 0]]);
    let time = |robot: &str| json!({"robot": robot, "group": "right_arm", "waypoints": path});
    let put = |limits: Option<&str>| {
        let mut b = json!({"urdf": urdf, "srdf": srdf});
        if let Some(l) = limits {
            b["joint_limits"] = json!(l);
        }
        b
    };
    let url = format!("{}/v1/robots/slow_armar", h.base);
    let limits = "joint_limits:\n  right_elbow:\n    has_velocity_limits: true\n    max_velocity: 0.2\n    has_acceleration_limits: true\n    max_acceleration: 0.5\n";
    let r = h
        .http
        .put(&url)
        .json(&put(Some(limits)))
        .send()
        .await
        .expect("PUT");
    assert!(r.status().is_success(), "{:?}", r.text().await);
    let (_, fast) = h.post("/v1/trajectories", &time("armar")).await;
    let (_, slow) = h.post("/v1/trajectories", &time("slow_armar")).await;
    // 1 rad at 0.2 rad/s, 0.5 rad/s²: 0.4 s up, 4.6 s cruise, 0.4 s down = 5.4 s.
    let d = slow["duration"].as_f64().expect("duration");
    assert!((d - 5.4).abs() < 1e-9, "{slow}");
    assert!(fast["duration"].as_f64().unwrap_or(9.0) < d);
    for (bad, want) in [
        ("joint_limits:\n  nope:\n    has_velocity_limits: true\n    max_velocity: 1\n", "joint_limits.joint_limits.nope"),
        ("joint_limits:\n  right_elbow:\n    has_acceleration_limits: true\n    max_acceleration: -1\n", "joint_limits.joint_limits.right_elbow.max_acceleration"),
        ("joint_limits: [1, 2", "joint_limits"),
    ] {
        let r = h.http.put(&url).json(&put(Some(bad))).send().await.expect("PUT");
        assert_eq!(r.status(), StatusCode::UNPROCESSABLE_ENTITY);
        let v: Value = r.json().await.expect("json");
        assert_eq!(field(&v), want, "{v}");
    }
}
