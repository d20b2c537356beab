//! Helpers shared by the planner tests: the shipped scenes, and the independent re-check of a
//! planner's answer (joint limits, and the exact parry checker at 5 mm / 0.5°).
#![allow(dead_code)] // each test binary uses its own subset

pub mod server;
pub mod spec;
pub mod tmp;

use std::path::PathBuf;

use manyhands::collision::{CollisionWorld, ExactChecker, MotionValidator};
use manyhands::geometry::Pose;
use manyhands::kinematics::randomized::RandomizedIkSettings;
use manyhands::model::{load_robot_dir, Scene};
use manyhands::planning::problems::grasping::{HandOffProblem, ReachProblem};
use manyhands::planning::{IkRrt, IkRrtSettings, JointSpace, PlanResult, Termination};

/// A fixed obstacle of one shape at `xyz`, turned by `rpy`.
pub fn obstacle(
    name: &str,
    xyz: [f64; 3],
    rpy: [f64; 3],
    shape: manyhands::geometry::Shape,
) -> manyhands::collision::StaticBody {
    manyhands::collision::StaticBody {
        name: name.into(),
        kind: manyhands::collision::StaticKind::Obstacle,
        pose: manyhands::geometry::iso_from_rpy(xyz, rpy),
        shapes: vec![manyhands::geometry::Geometry {
            origin: Pose::identity(),
            shape,
        }],
    }
}

/// A free-floating probe robot: prismatic joints x, y, z (limits ±`limit`) carrying one
/// collision geometry (URDF `<geometry>` text) on its link `tool`.
pub fn probe_urdf(geometry: &str, limit: f64) -> String {
    let pj = |name: &str, parent: &str, child: &str, axis: &str| {
        format!(
            r#"<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="{child}"/>
               <axis xyz="{axis}"/><limit lower="-{limit}" upper="{limit}" velocity="1" effort="1"/></joint>"#
        )
    };
    format!(
        r#"<robot name="probe">
  <link name="world"/><link name="px"/><link name="py"/>
  <link name="tool"><collision>{geometry}</collision></link>
  {}{}{}
</robot>"#,
        pj("x", "world", "px", "1 0 0"),
        pj("y", "px", "py", "0 1 0"),
        pj("z", "py", "tool", "0 0 1"),
    )
}

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A shipped scene by name.
pub fn scene(name: &str) -> Scene {
    let lib = load_robot_dir(&root().join("robots")).expect("robots");
    Scene::from_file(&root().join("scenes").join(format!("{name}.json")), &lib).expect("scene")
}

/// Exact re-check of a path (space coordinates) in `world` at 5 mm / 0.5°, and joint limits.
pub fn assert_exactly_free(world: &CollisionWorld, space: &JointSpace, path: &[Vec<f64>]) {
    for (k, q) in path.iter().enumerate() {
        assert!(
            space.bounds_violation(q).is_none(),
            "state {k}: {:?}",
            space.bounds_violation(q)
        );
    }
    let wpath = space.path_to_world(path);
    let mut mv = MotionValidator::new(world, ExactChecker::new(world), 0.5f64.to_radians(), 0.005);
    assert!(
        mv.is_path_valid(&wpath),
        "path not collision-free under the exact checker"
    );
}

/// Position and rotation angle both within `tol`.
pub fn pose_close(a: &Pose, b: &Pose, tol: f64) -> bool {
    (a.translation.vector - b.translation.vector).norm() < tol
        && a.rotation.angle_to(&b.rotation) < tol
}

/// A grasp plan of `p`: starts at the start, ends exactly (1e-6) at grasp `goal_index`, and is
/// within limits and collision-free under the exact checker.
pub fn check_reach(p: &ReachProblem, r: &PlanResult) {
    assert_eq!(r.path[0], p.start, "path must start at the start");
    let last = r.path.last().expect("non-empty path");
    let wq = p.space.to_world(last);
    let tcp = p.hand.tcp_pose(&p.world, &wq);
    let target = p.object_pose * p.grasps[r.goal_index];
    assert!(
        pose_close(&tcp, &target, 1e-6),
        "last state does not reach grasp {}: {tcp:?} vs {target:?}",
        r.goal_index
    );
    assert_exactly_free(&p.world, &p.space, &r.path);
}

/// The kitchen re-grasp: armar's right hand (hip + arm) grasps the wok first (IK-RRT, seed 3,
/// at most 50 IK tries per query), then the left hand is to take it over.
pub fn kitchen_wok_handoff() -> HandOffProblem {
    let s = scene("kitchen");
    let world = CollisionWorld::from_scene(&s);
    let wq = CollisionWorld::start_config(&s);
    let p = ReachProblem::grasp(&s, &world, &wq, "armar", "torso_right_arm", "wok").expect("p");
    let ik = RandomizedIkSettings {
        max_tries: 50,
        ..RandomizedIkSettings::default()
    };
    let r = IkRrt::new(p.space.clone(), &p.world, IkRrtSettings::default())
        .expect("planner")
        .plan(&p.start, &mut p.goals(None, ik), &mut Termination::new(), 3)
        .expect("grasp");
    let wq2 = p.space.to_world(r.path.last().expect("path"));
    HandOffProblem::new(
        &s,
        &world,
        &wq2,
        ("armar", "torso_right_arm"),
        ("armar", "torso_left_arm"),
        "wok",
        p.grasps[r.goal_index],
    )
    .expect("hand-off problem")
}

/// A re-grasp plan of `h`: starts at the start, its last state puts the receiver's TCP exactly
/// (1e-6) at grasp `goal_index` on the object where the giver holds it, and it is within limits
/// and collision-free under the exact checker (held object included).
pub fn check_handoff(h: &HandOffProblem, r: &PlanResult) {
    assert_eq!(r.path[0], h.start, "path must start at the start");
    let last = h.space.to_world(r.path.last().expect("non-empty path"));
    let obj = h.giver.tcp_pose(&h.world, &last) * h.held.inverse();
    let tcp = h.receiver.tcp_pose(&h.world, &last);
    assert!(
        pose_close(&tcp, &(obj * h.grasps[r.goal_index]), 1e-6),
        "the receiver does not reach grasp {}",
        r.goal_index
    );
    assert_exactly_free(&h.world, &h.space, &r.path);
}

/// The kitchen wok moved 3 m away from armar: no grasp of `torso_right_arm` is reachable.
/// `ReachProblem::grasp` refuses such a problem at once (tests/unreachable.rs); to see how the
/// planners themselves end on unreachable goals, the problem is made with the wok in place and
/// the wok moved afterwards (its world body and the goals' object pose).
pub fn far_wok_problem() -> ReachProblem {
    let s = scene("kitchen");
    let world = CollisionWorld::from_scene(&s);
    let wq = CollisionWorld::start_config(&s);
    let mut p =
        ReachProblem::grasp(&s, &world, &wq, "armar", "torso_right_arm", "wok").expect("problem");
    let wi = p
        .world
        .statics
        .iter()
        .position(|b| b.name == "wok")
        .expect("wok");
    p.world.statics[wi].pose.translation.vector.y += 3.0;
    p.object_pose.translation.vector.y += 3.0;
    p
}

/// A kitchen re-grasp plan (server or CLI JSON) made with the J+ planners: J+-RRT grasps with
/// the right hand, dual-arm J+-RRT hands the wok to the left; events grasp (right), grasp
/// (left), release (right).
pub fn assert_j_plus_regrasp_plan(plan: &serde_json::Value) {
    let planners: Vec<&str> = plan["phases"]
        .as_array()
        .expect("phases")
        .iter()
        .filter_map(|p| p["planner"].as_str())
        .collect();
    assert_eq!(
        planners,
        vec!["j_plus_rrt", "dual_arm_j_plus_rrt"],
        "{plan}"
    );
    let events: Vec<(&str, &str)> = plan["events"]
        .as_array()
        .expect("events")
        .iter()
        .filter_map(|e| Some((e["kind"].as_str()?, e["end_effector"].as_str()?)))
        .collect();
    assert_eq!(
        events,
        vec![
            ("grasp", "right_hand"),
            ("grasp", "left_hand"),
            ("release", "right_hand")
        ],
        "{plan}"
    );
}
