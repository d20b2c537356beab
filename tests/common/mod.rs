//! Helpers shared by the planner tests: the shipped scenes, and the independent re-check of a
//! planner's answer (joint limits, and the exact parry checker at 5 mm / 0.5°).
#![allow(dead_code)] // each test binary uses its own subset

pub mod server;

use std::path::PathBuf;

use manyhands::collision::{CollisionWorld, ExactChecker, MotionValidator};
use manyhands::geometry::Pose;
use manyhands::model::{load_robot_dir, Scene};
use manyhands::planning::grasping::ReachProblem;
use manyhands::planning::{JointSpace, PlanResult};

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

/// The kitchen wok moved 3 m away from armar: no grasp of `torso_right_arm` is reachable.
pub fn far_wok_problem() -> ReachProblem {
    let s = scene("kitchen");
    let mut world = CollisionWorld::from_scene(&s);
    let wi = world
        .statics
        .iter()
        .position(|b| b.name == "wok")
        .expect("wok");
    world.statics[wi].pose.translation.vector.y += 3.0;
    let wq = CollisionWorld::start_config(&s);
    ReachProblem::grasp(&s, &world, &wq, "armar", "torso_right_arm", "wok").expect("problem")
}
