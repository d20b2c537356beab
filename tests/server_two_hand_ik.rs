//! The two-handed IK queries over HTTP: `POST /v1/ik/dual-arm` (paper 000 §III, object pose free
//! or held in the left hand) and `POST /v1/ik/base-placement` (paper 002 Alg. 1, IkDualArm with
//! the platform placed from the bimanual inverse reachability map), and the reachability filter of
//! `POST /v1/ik/grasp`. Every answer is checked independently of the solver: both TCPs at the
//! named grasps (FK within 1e-6) and the configuration collision-free under the exact checker,
//! with the object in the hands.

mod common;
use common::server::{field, start, Harness};
use common::{pose_close, scene};

use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker};
use manyhands::geometry::{Pose, PoseJson};
use manyhands::model::Scene;
use manyhands::planning::problems::grasping::Hand;
use manyhands::reachability::hand_links;
use manyhands::reachability::queries::grasp_set;
use reqwest::StatusCode;
use serde_json::{json, Value};

/// armar's world configuration of an answer's `config` map.
fn world_config(s: &Scene, config: &Value) -> Vec<f64> {
    let model = &s.robots[0].robot;
    let mut q = CollisionWorld::start_config(s);
    for v in 0..model.dof() {
        q[v] = config[model.var_name(v)]
            .as_f64()
            .unwrap_or_else(|| panic!("config lacks {}", model.var_name(v)));
    }
    q
}

fn object_pose(v: &Value) -> Pose {
    let p: PoseJson = serde_json::from_value(v["object_pose"].clone()).expect("object_pose");
    p.to_pose().expect("pose")
}

/// Both TCPs at the answer's grasps of `object` posed at `pose`, to 1e-6.
fn assert_hands_at_grasps(s: &Scene, v: &Value, object: &str, pose: &Pose) -> (Hand, Hand) {
    let world = CollisionWorld::from_scene(s);
    let q = world_config(s, &v["config"]);
    let left = Hand::new(&world, "armar", "torso_left_arm").expect("left");
    let right = Hand::new(&world, "armar", "torso_right_arm").expect("right");
    for (hand, key) in [(&left, "left_grasp"), (&right, "right_grasp")] {
        let set = grasp_set(s, object, &hand.end_effector).expect("grasps");
        let name = v[key].as_str().expect("grasp name");
        let k = set
            .names
            .iter()
            .position(|n| n == name)
            .expect("known grasp");
        let target = pose * set.tcps[k];
        let tcp = hand.tcp_pose(&world, &q);
        assert!(
            pose_close(&tcp, &target, 1e-6),
            "{key} {name}: {tcp:?} vs {target:?}"
        );
    }
    (left, right)
}

/// Each `(key, value, field)`: `req` with `key` set to `value` gets a 422 naming `field`.
async fn assert_fields_named(h: &Harness, path: &str, req: &Value, bad: &[(&str, Value, &str)]) {
    for (key, val, want) in bad {
        let mut b = req.clone();
        b[*key] = val.clone();
        let (st, v) = h.post(path, &b).await;
        assert_eq!(st, StatusCode::UNPROCESSABLE_ENTITY, "{key}: {v}");
        assert_eq!(field(&v), *want, "{v}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dual_arm_ik_over_http() {
    let h = start("dual-arm-ik").await;
    let s = scene("kitchen");
    let req = json!({"scene": "kitchen", "robot": "armar", "object": "wok", "seed": 4,
        "region": {"min": [0.3, -0.3, 1.0], "max": [0.6, 0.2, 1.4]}});
    for held in [None, Some("wok_l_02")] {
        let mut b = req.clone();
        if let Some(g) = held {
            b["held"] = json!(g);
        }
        let (st, v) = h.post("/v1/ik/dual-arm", &b).await;
        assert_eq!(st, StatusCode::OK, "{v}");
        assert_eq!(v["found"], true, "{v}");
        assert_eq!(v["reachability"], true, "{v}");
        assert_eq!(
            v["joints"].as_array().map(|j| j.len()),
            Some(17),
            "hip + 2 arms: {v}"
        );
        if let Some(g) = held {
            assert_eq!(v["left_grasp"], g, "{v}");
        }
        let pose = object_pose(&v);
        let p = pose.translation.vector;
        for i in 0..3 {
            let (lo, hi) = (
                req["region"]["min"][i].as_f64(),
                req["region"]["max"][i].as_f64(),
            );
            assert!(p[i] >= lo.unwrap_or(0.0) - 1e-9 && p[i] <= hi.unwrap_or(0.0) + 1e-9);
        }
        let (left, right) = assert_hands_at_grasps(&s, &v, "wok", &pose);
        // Exactly collision-free with the wok in the left hand (both hands may touch it).
        let mut world = CollisionWorld::from_scene(&s);
        let q = world_config(&s, &v["config"]);
        let wi = world
            .statics
            .iter()
            .position(|b| b.name == "wok")
            .expect("wok");
        world.statics[wi].pose = pose;
        let model = &s.robots[0].robot;
        let mut touch = hand_links(model, &left.end_effector).expect("left hand");
        touch.extend(hand_links(model, &right.end_effector).expect("right hand"));
        world
            .attach("wok", 0, left.arm.chain.tip_link, &q, touch)
            .expect("attach");
        let mut exact = ExactChecker::new(&world);
        assert!(exact.is_free(&q), "{:?}", exact.first_contact(&q));
        // Same request and seed, same answer.
        let (_, v2) = h.post("/v1/ik/dual-arm", &b).await;
        assert_eq!(v2["solution"], v["solution"]);
    }
    // Bad fields are named.
    let bad = [
        ("robot", json!("robbie"), "robot"),
        ("left_group", json!("nope"), "left_group"),
        ("right_group", json!("nope"), "right_group"),
        ("object", json!("spoon"), "object"),
        ("held", json!("wok_r_00"), "held"),
        (
            "region",
            json!({"min": [0, 0, 1], "max": [0, 0, 0]}),
            "region",
        ),
        ("max_tries", json!(0), "max_tries"),
        ("psi_samples", json!(0), "psi_samples"),
    ];
    assert_fields_named(&h, "/v1/ik/dual-arm", &req, &bad).await;
    // Out of reach: "no solution after N tries", not an error.
    let mut b = req.clone();
    b["region"] = json!({"min": [3.0, 3.0, 1.0], "max": [3.2, 3.2, 1.2]});
    b["max_tries"] = json!(300);
    let (st, v) = h.post("/v1/ik/dual-arm", &b).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["found"], false, "{v}");
    assert_eq!(v["tries"], 300, "{v}");
    assert!(v["reason"].as_str().unwrap_or("").contains("300"), "{v}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn base_placement_ik_over_http() {
    let h = start("base-placement").await;
    let s = scene("kitchen");
    let req = json!({"scene": "kitchen", "robot": "armar", "object": "table", "seed": 2});
    let (st, v) = h.post("/v1/ik/base-placement", &req).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["found"], true, "{v}");
    assert_eq!(v["joints"].as_array().map(|j| j.len()), Some(20), "{v}");
    assert_eq!(v["joints"][0], "base_x", "{v}");
    let world = CollisionWorld::from_scene(&s);
    let table = world
        .statics
        .iter()
        .find(|b| b.name == "table")
        .expect("table");
    assert_hands_at_grasps(&s, &v, "table", &table.pose);
    let q = world_config(&s, &v["config"]);
    let mut exact = ExactChecker::new(&world);
    assert!(exact.is_free(&q), "{:?}", exact.first_contact(&q));
    let (_, v2) = h.post("/v1/ik/base-placement", &req).await;
    assert_eq!(v2["solution"], v["solution"], "same seed, same answer");
    let bad = [
        ("robot", json!("robbie"), "robot"),
        ("object", json!("spoon"), "object"),
        ("radius", json!(-1.0), "radius"),
        ("cell", json!(0.0), "cell"),
        ("yaw_bins", json!(0), "yaw_bins"),
        ("max_tries", json!(2_000_000), "max_tries"),
    ];
    assert_fields_named(&h, "/v1/ik/base-placement", &req, &bad).await;
    // Bases within 0.2 m of the table's centre stand in the table: every sample collides, and
    // the answer is a clean "no solution after N tries".
    let mut b = req.clone();
    b["radius"] = json!(0.2);
    b["max_tries"] = json!(2000);
    let (st, v) = h.post("/v1/ik/base-placement", &b).await;
    assert_eq!(st, StatusCode::OK, "{v}");
    assert_eq!(v["found"], false, "{v}");
    assert_eq!(v["tries"], 2000, "{v}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grasp_ik_uses_reachability_and_cuts_ik_calls() {
    let h = start("grasp-ik-reach").await;
    let mut with = (0u64, 0u64);
    let mut without = (0u64, 0u64);
    for seed in 1..=8u64 {
        for (reach, acc) in [(true, &mut with), (false, &mut without)] {
            let req = json!({"scene": "kitchen", "robot": "armar", "group": "torso_right_arm",
                "object": "wok", "seed": seed, "reachability": reach});
            let (st, v) = h.post("/v1/ik/grasp", &req).await;
            assert_eq!(st, StatusCode::OK, "{v}");
            assert_eq!(v["found"], true, "{v}");
            assert_eq!(v["reachability"], reach, "{v}");
            acc.0 += v["ik_calls"].as_u64().unwrap_or(0);
            acc.1 += v["tries"].as_u64().unwrap_or(0);
        }
    }
    // The filter skips hip samples whose grasps are out of the arm's reach (000 Table 1: 101.9
    // → 6.1 calls); the kitchen wok is close, so the cut is smaller, but it must be there.
    assert!(
        with.0 < without.0,
        "IK calls with reachability {} ≥ without {}",
        with.0,
        without.0
    );
}
