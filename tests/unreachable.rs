//! An object out of every hand's reach fails at once with the reason, instead of running a
//! grasp planner into its time limit: the kitchen's wok moved 4 m away, asked of IK-RRT and
//! J+-RRT through the library, the CLI (`plan reach --scene FILE`) and the HTTP API
//! (`kind: reach`, and `kitchen_task` on the same scene).

mod common;

use std::time::Instant;

use manyhands::collision::CollisionWorld;
use manyhands::model::{load_robot_dir, Scene, SceneJson};
use manyhands::planning::problems::grasping::ReachProblem;
use manyhands::planning::PlanError;
use serde_json::json;

/// The kitchen with its wok 4 m in front of the robot.
fn far_kitchen() -> SceneJson {
    let text =
        std::fs::read_to_string(common::root().join("scenes/kitchen.json")).expect("kitchen");
    let mut v: serde_json::Value = serde_json::from_str(&text).expect("json");
    let wok = v["objects"]
        .as_array_mut()
        .expect("objects")
        .iter_mut()
        .find(|o| o["name"] == "wok")
        .expect("wok");
    wok["pose"]["position"] = json!([4.65, -0.2, 0.901]);
    v["name"] = json!("far_kitchen");
    serde_json::from_value(v).expect("scene json")
}

fn assert_says_why(msg: &str) {
    assert!(msg.contains("out of reach"), "{msg}");
    assert!(msg.contains("nearest by"), "{msg}");
    assert!(msg.contains("'wok'"), "{msg}");
}

#[test]
fn the_reach_problem_refuses_an_object_out_of_reach() {
    let lib = load_robot_dir(&common::root().join("robots")).expect("robots");
    let scene = Scene::from_json(
        far_kitchen(),
        "far_kitchen",
        &common::root().join("scenes"),
        &lib,
    )
    .expect("scene");
    let world = CollisionWorld::from_scene(&scene);
    let q0 = CollisionWorld::start_config(&scene);
    let t0 = Instant::now();
    let e = ReachProblem::grasp(&scene, &world, &q0, "armar", "torso_right_arm", "wok")
        .expect_err("out of reach");
    assert!(t0.elapsed().as_secs_f64() < 1.0, "{:?}", t0.elapsed());
    assert!(matches!(e, PlanError::InvalidGoal { .. }), "{e:?}");
    assert_says_why(&e.to_string());
    // The shipped kitchen's wok is within reach: no error there.
    let kitchen =
        Scene::from_file(&common::root().join("scenes/kitchen.json"), &lib).expect("kitchen");
    let world = CollisionWorld::from_scene(&kitchen);
    let q0 = CollisionWorld::start_config(&kitchen);
    ReachProblem::grasp(&kitchen, &world, &q0, "armar", "torso_right_arm", "wok")
        .expect("the kitchen's wok is within reach");
}

#[test]
fn plan_reach_on_the_command_line_fails_fast_with_the_reason() {
    let dir = common::tmp::TestDir::new("unreachable-cli");
    let file = dir.join("far_kitchen.json");
    std::fs::write(&file, serde_json::to_string(&far_kitchen()).expect("json")).expect("write");
    for planner in ["ik-rrt", "j-plus-rrt"] {
        let t0 = Instant::now();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
            .args(["plan", "reach", "--planner", planner, "--scene"])
            .arg(&file)
            .args(["--grid-dir"])
            .arg(dir.join("grids"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("run manyhands");
        let secs = t0.elapsed().as_secs_f64();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{planner}: succeeded?");
        assert_says_why(&err);
        assert!(secs < 1.0, "{planner}: {secs:.2} s");
        // No reachability grid was built for it.
        assert!(
            !dir.join("grids").exists()
                || std::fs::read_dir(dir.join("grids"))
                    .map(|mut d| d.next().is_none())
                    .unwrap_or(true)
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reach_job_fails_fast_with_the_reason() {
    let h = common::server::start("unreachable").await;
    let r = h
        .http
        .put(format!("{}/v1/scenes/far_kitchen", h.base))
        .json(&far_kitchen())
        .send()
        .await
        .expect("PUT");
    assert!(r.status().is_success(), "{}", r.status());
    for body in [
        json!({"kind": "reach", "scene": "far_kitchen", "robot": "armar",
               "group": "torso_right_arm", "object": "wok", "seed": 1}),
        json!({"kind": "reach", "scene": "far_kitchen", "robot": "armar",
               "group": "torso_right_arm", "object": "wok", "planner": "j_plus_rrt", "seed": 1}),
        json!({"kind": "kitchen_task", "scene": "far_kitchen", "seed": 1}),
    ] {
        let t0 = Instant::now();
        let (s, job) = h.post("/v1/plans?wait=30", &body).await;
        let secs = t0.elapsed().as_secs_f64();
        assert!(s.is_success(), "{s}: {job}");
        assert_eq!(job["state"], "failed", "{job}");
        assert_eq!(job["error"]["code"], "invalid_goal", "{job}");
        assert_says_why(job["error"]["message"].as_str().unwrap_or(""));
        assert!(secs < 1.0, "{}: {secs:.2} s", body["kind"]);
    }
    h.server.shutdown().await.expect("shutdown");
}
