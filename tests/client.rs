//! The Rust client (the `manyhands-client` crate) against the real server on a loopback port: every
//! endpoint kind through typed requests, API errors decoded with their field, a job waited for,
//! its event stream read to `end`, and a running job cancelled.

mod common;
use common::server::start;
use common::spec::{errors, spec, validator};

use std::time::Duration;

use manyhands_client::api::JobState;
use manyhands_client::{Client, ClientError};
use reqwest::StatusCode;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{json, Value};

/// A typed request from JSON (the same text a curl user would send).
fn req<T: DeserializeOwned>(v: Value) -> T {
    serde_json::from_value(v).expect("request type")
}

/// `typed` as the client serialises it (unset options as `null`) validates against the spec's
/// request schema of `POST path`.
fn assert_valid_body<T: Serialize>(path: &str, typed: &T) {
    let spec = spec();
    let body = serde_json::to_value(typed).expect("serialise");
    let schema =
        &spec["paths"][path]["post"]["requestBody"]["content"]["application/json"]["schema"];
    assert!(schema.is_object(), "POST {path}: no request schema");
    let e = errors(&validator(&spec, schema), &body);
    assert!(
        e.is_empty(),
        "POST {path}: the client's body fails the spec: {e:?}\n{body}"
    );
}

#[test]
fn typed_requests_as_serialised_validate_against_the_spec() {
    use manyhands_client::api::*;
    let fk: FkRequest = req(json!({"robot": "armar", "config": {"right_elbow": -1.2}}));
    assert_valid_body("/v1/fk", &fk);
    let ik: IkRequest = req(json!({"robot": "armar", "group": "right_arm",
        "pose": {"position": [0.45, -0.26, 1.08], "rpy": [-2.7, -1.41, 1.08]}}));
    assert_valid_body("/v1/ik", &ik);
    let check: CheckRequest = req(json!({"scene": "kitchen", "robots": [{"name": "armar"}]}));
    assert_valid_body("/v1/check", &check);
    let g: GraspIkRequest = req(json!({"scene": "kitchen", "robot": "armar",
        "group": "torso_right_arm", "object": "wok"}));
    assert_valid_body("/v1/ik/grasp", &g);
    let d: DualArmIkRequest = req(
        json!({"scene": "kitchen", "robot": "armar", "object": "wok",
        "region": {"min": [0.3, -0.3, 1.0], "max": [0.6, 0.2, 1.4]}}),
    );
    assert_valid_body("/v1/ik/dual-arm", &d);
    let b: BasePlacementRequest =
        req(json!({"scene": "kitchen", "robot": "armar", "object": "table"}));
    assert_valid_body("/v1/ik/base-placement", &b);
    let q: GraspQualityRequest = req(json!({"scene": "kitchen", "object": "wok"}));
    assert_valid_body("/v1/grasp-quality", &q);
    let t: TrajectoryRequest = req(json!({"robot": "armar", "group": "right_arm",
        "waypoints": [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]], "max_acceleration": {"right_elbow": 2.0}, "sample_period": 0.02}));
    assert_valid_body("/v1/trajectories", &t);
    for plan in [
        json!({"kind": "joint_space", "scene": "empty",
            "robots": [{"name": "armar", "group": "right_arm", "goal": {"right_elbow": -1.0}}]}),
        json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 100}),
        json!({"kind": "reach", "scene": "kitchen", "robot": "armar", "group": "torso_right_arm",
            "object": "wok", "planner": "j_plus_rrt"}),
        json!({"kind": "regrasp", "scene": "handoff", "giver": {"robot": "armar_a", "group": "torso_right_arm"},
            "receiver": {"robot": "armar_b", "group": "torso_left_arm"}, "object": "wok"}),
        json!({"kind": "kitchen_task", "scene": "kitchen"}),
        json!({"kind": "bimanual", "scene": "kitchen", "robot": "armar", "object": "table"}),
        json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table"}),
        json!({"kind": "schedule", "scene": "kitchen_two",
            "trajectories": [{"robot": "armar_a", "path": [[0.0]]}]}),
    ] {
        let p: PlanRequest = req(plan);
        assert_valid_body("/v1/plans", &p);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn client_covers_every_endpoint_kind() {
    let h = start("rust-client").await;
    let c = Client::new(&h.base).expect("client");
    assert!(
        Client::new("localhost:8080").is_err(),
        "a URL without scheme is refused"
    );

    // Operations and resources.
    let health = c.health().await.expect("health");
    assert_eq!(health.status, "ok");
    assert!(health.robots >= 2 && health.scenes >= 4, "{health:?}");
    assert!(c.metrics().await.expect("metrics").contains("manyhands_"));
    let robots = c.robots().await.expect("robots");
    assert!(robots.iter().any(|r| r.name == "armar"));
    let armar = c.robot("armar").await.expect("armar");
    assert_eq!(armar.dof, 20);
    assert!(c
        .scenes()
        .await
        .expect("scenes")
        .iter()
        .any(|s| s.name == "kitchen"));
    let kitchen = c.scene("kitchen").await.expect("scene");
    let e = c.robot("robbie").await.expect_err("unknown robot");
    assert_eq!(e.status(), Some(StatusCode::NOT_FOUND), "{e}");
    // Upload a scene, read it back, delete it.
    let mut copy = kitchen.clone();
    copy["name"] = json!("kitchen_copy");
    let summary = c.put_scene("kitchen_copy", &copy).await.expect("put scene");
    assert_eq!(summary.name, "kitchen_copy");
    c.delete_scene("kitchen_copy").await.expect("delete scene");
    assert!(c.scene("kitchen_copy").await.is_err());
    // A robot's visual geometry: an uploaded robot whose visuals are a box and an uploaded mesh.
    let tet = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let r = h
        .http
        .put(format!("{}/v1/meshes/tet.obj", h.base))
        .header("content-type", "application/octet-stream")
        .body(tet)
        .send()
        .await
        .expect("PUT mesh");
    assert_eq!(r.status(), StatusCode::CREATED);
    let urdf = r#"<robot name="vis"><link name="base">
        <visual><geometry><box size="0.2 0.4 0.6"/></geometry></visual>
        <visual><geometry><mesh filename="meshes/tet.obj" scale="2 2 2"/></geometry></visual>
        <collision><geometry><sphere radius="0.05"/></geometry></collision></link></robot>"#;
    c.put_robot("vis", &req(json!({ "urdf": urdf })))
        .await
        .expect("put robot");
    let v = c.robot_visuals("vis").await.expect("visuals");
    assert_eq!(v.robot, "vis");
    assert_eq!(v.visuals.len(), 2, "{v:?}");
    let b = v.visuals[0].shape.as_ref().expect("box shape");
    assert_eq!(
        (b.kind.as_str(), b.half_extents),
        ("box", Some([0.1, 0.2, 0.3]))
    );
    let m = &v.visuals[1];
    let url = m.shape.as_ref().and_then(|s| s.url.as_deref());
    assert_eq!(url, Some("/v1/robots/vis/visuals/base/1"), "{m:?}");
    let obj = c
        .robot_visual_mesh("vis", &m.link, m.index)
        .await
        .expect("visual mesh");
    let verts: Vec<&str> = obj.lines().filter(|l| l.starts_with("v ")).collect();
    assert_eq!(verts.len(), 4, "{obj}");
    assert!(verts.contains(&"v 0.2 0 0"), "{obj}");
    let e = c
        .robot_visual_mesh("vis", "base", 0)
        .await
        .expect_err("a box is not a mesh");
    assert_eq!(e.status(), Some(StatusCode::NOT_FOUND), "{e}");
    assert_eq!(e.field(), Some("index"), "{e}");
    c.delete_robot("vis").await.expect("delete robot");

    // Queries.
    let fk = c
        .fk(&req(
            json!({"robot": "armar", "config": {"right_elbow": -1.2}, "links": ["right_tcp"]}),
        ))
        .await
        .expect("fk");
    let pose = &fk.links[0].pose;
    let ik = c
        .ik(&req(json!({"robot": "armar", "group": "right_arm",
            "pose": {"position": pose.position, "quat_xyzw": pose.quat_xyzw}})))
        .await
        .expect("ik");
    assert!(ik.solutions_found > 0, "{ik:?}");
    let check = c
        .check(&req(json!({"scene": "kitchen"})))
        .await
        .expect("check");
    assert!(!check.collision, "{check:?}");
    let g = c
        .grasp_ik(&req(json!({"scene": "kitchen", "robot": "armar",
            "group": "torso_right_arm", "object": "wok", "seed": 1})))
        .await
        .expect("grasp ik");
    assert!(g.found && g.reachability, "{g:?}");
    let d = c
        .dual_arm_ik(&req(
            json!({"scene": "kitchen", "robot": "armar", "object": "wok",
            "region": {"min": [0.3, -0.3, 1.0], "max": [0.6, 0.2, 1.4]}, "seed": 1}),
        ))
        .await
        .expect("dual-arm ik");
    assert!(
        d.found && d.left_grasp.is_some() && d.right_grasp.is_some(),
        "{d:?}"
    );
    let b = c
        .base_placement_ik(&req(json!({"scene": "kitchen", "robot": "armar",
            "object": "table", "seed": 1})))
        .await
        .expect("base placement");
    assert!(b.found && b.joints.len() == 20, "{b:?}");
    let q = c
        .grasp_quality(&req(json!({"scene": "kitchen", "object": "wok"})))
        .await
        .expect("grasp quality");
    assert_eq!(q.grasps.len(), 25);
    let t = c
        .time_path(&req(json!({"robot": "armar", "group": "right_arm",
            "waypoints": [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0]]})))
        .await
        .expect("trajectory");
    // 1 rad of the elbow at 2 rad/s, 4 rad/s² (robots/armar.joint_limits.yaml): 1 s.
    assert!((t.duration - 1.0).abs() < 1e-9, "{}", t.duration);
    assert_eq!(t.points.len(), 101);

    // An API error carries status and field.
    let e = c
        .fk(&req(
            json!({"robot": "armar", "config": {"right_elbow": 4.2}}),
        ))
        .await
        .expect_err("out of limits");
    assert_eq!(e.status(), Some(StatusCode::UNPROCESSABLE_ENTITY), "{e}");
    assert_eq!(e.field(), Some("config.right_elbow"), "{e}");
    assert!(matches!(e, ClientError::Api { .. }));

    // Jobs: wait in one call, poll with wait(), the event stream, cancel.
    let sweep =
        json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 2000, "time_limit": 5});
    let done = c
        .submit(&req(sweep.clone()), Some(30.0))
        .await
        .expect("submit");
    assert_eq!(done.state, JobState::Succeeded, "{done:?}");
    assert!(done.result.is_some());
    let job = c.submit(&req(sweep.clone()), None).await.expect("submit");
    let polled = c
        .wait(&job.id, Duration::from_secs(30))
        .await
        .expect("wait");
    assert_eq!(polled.state, JobState::Succeeded);
    assert!(c
        .jobs()
        .await
        .expect("jobs")
        .jobs
        .iter()
        .any(|j| j.id == job.id));
    // Paged and filtered: one job a page, only succeeded sweeps.
    let page = c
        .jobs_page(
            Some(1),
            None,
            Some(JobState::Succeeded),
            Some("collision_sweep"),
        )
        .await
        .expect("jobs page");
    assert_eq!(page.jobs.len(), 1);
    assert!(page
        .jobs
        .iter()
        .all(|j| j.state == JobState::Succeeded && j.kind == "collision_sweep"));
    if let Some(next) = page.next_cursor.as_deref() {
        let more = c
            .jobs_page(Some(1), Some(next), None, None)
            .await
            .expect("next page");
        assert!(more.jobs.iter().all(|j| j.id != page.jobs[0].id));
    }
    let long = json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 1_000_000_000u64, "time_limit": 0.5});
    let job = c.submit_json(&long, None).await.expect("submit");
    let mut seen = 0;
    let events = c.events(&job.id, |_| seen += 1).await.expect("events");
    assert_eq!(
        events.last().map(|e| e.event.as_str()),
        Some("end"),
        "{events:?}"
    );
    assert_eq!(seen, events.len());
    let mut long30 = long.clone();
    long30["time_limit"] = json!(30);
    let job = c.submit_json(&long30, None).await.expect("submit");
    let cancelled = c.cancel(&job.id).await.expect("cancel");
    assert!(
        matches!(
            cancelled.state,
            JobState::Cancelled | JobState::Running | JobState::Queued
        ),
        "{cancelled:?}"
    );
    let fin = c
        .wait(&job.id, Duration::from_secs(10))
        .await
        .expect("wait");
    assert_eq!(fin.state, JobState::Cancelled, "{fin:?}");
    // wait() gives up cleanly.
    let job = c.submit_json(&long30, None).await.expect("submit");
    let e = c
        .wait(&job.id, Duration::from_millis(50))
        .await
        .expect_err("not final yet");
    assert!(matches!(e, ClientError::WaitTimeout { .. }), "{e}");
    c.cancel(&job.id).await.expect("cancel");
    drop(h);
}
