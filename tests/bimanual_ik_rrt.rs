//! Bimanual IK-RRT (paper 002 Alg. 2): ARMAR (20 DoF: platform, hip, both arms) grasps the
//! kitchen table with both hands. Every path is checked independently of the planner: it starts
//! at the start, both TCPs reach the label's grasps (FK within 1e-6), it stays within the space's
//! bounds, and the exact (parry) checker finds it collision-free at 5 mm / 0.5°.

mod common;
use common::{pose_close, scene};

use std::sync::{Arc, OnceLock};
use std::time::Duration;

use manyhands::collision::{CollisionWorld, ExactChecker, MotionValidator};
use manyhands::kinematics::randomized::RandomizedIkSettings;
use manyhands::kinematics::Chain;
use manyhands::model::Scene;
use manyhands::planning::planners::bimanual_ik_rrt::{
    paper_settings, BimanualProblem, BimanualSettings,
};
use manyhands::planning::{PlanError, PlanResult, Termination};
use manyhands::reachability::{GridParams, ReachabilityGrid};

/// Platform-frame grids of both 10-DoF chains, built once for the file.
fn grids() -> &'static (ReachabilityGrid, ReachabilityGrid) {
    static G: OnceLock<(ReachabilityGrid, ReachabilityGrid)> = OnceLock::new();
    G.get_or_init(|| {
        let s = scene("kitchen");
        let robot: Arc<_> = s.robots[0].robot.clone();
        let mk = |group: &str, seed: u64| {
            let chain = Chain::from_group(&robot, group).expect("chain");
            let p = GridParams::auto(&robot, &chain, 0.1, 8, 300_000, seed).expect("params");
            ReachabilityGrid::build(&robot, group, &p, &|_| {}).expect("grid")
        };
        (mk("torso_left_arm", 1), mk("torso_right_arm", 2))
    })
}

fn problem(s: &Scene, object: &str) -> Result<BimanualProblem, PlanError> {
    let world = CollisionWorld::from_scene(s);
    let q0 = CollisionWorld::start_config(s);
    let g = grids();
    BimanualProblem::new(
        s,
        &world,
        &q0,
        "armar",
        ("torso_left_arm", "torso_right_arm"),
        object,
        (&g.0, &g.1),
        BimanualSettings::default(),
    )
}

fn ik() -> RandomizedIkSettings {
    RandomizedIkSettings {
        max_tries: 30,
        ..RandomizedIkSettings::default()
    }
}

fn check(p: &BimanualProblem, r: &PlanResult) {
    assert_eq!(r.path[0], p.start, "path must start at the start");
    for (k, q) in r.path.iter().enumerate() {
        assert!(
            p.space.bounds_violation(q).is_none(),
            "state {k}: {:?}",
            p.space.bounds_violation(q)
        );
    }
    let last = p.space.to_world(r.path.last().expect("non-empty"));
    let (tl, tr) = p.targets(r.goal_index);
    assert!(
        pose_close(&p.left.tcp_pose(&p.world, &last), &tl, 1e-6),
        "left TCP"
    );
    assert!(
        pose_close(&p.right.tcp_pose(&p.world, &last), &tr, 1e-6),
        "right TCP"
    );
    let wpath = p.space.path_to_world(&r.path);
    let mut mv = MotionValidator::new(
        &p.world,
        ExactChecker::new(&p.world),
        0.5f64.to_radians(),
        0.005,
    );
    assert!(mv.is_path_valid(&wpath), "path not exactly collision-free");
}

#[test]
fn armar_grasps_the_kitchen_table_with_both_hands() {
    let s = scene("kitchen");
    let p = problem(&s, "table").expect("problem");
    assert_eq!(p.space.dim(), 20, "platform 3 + hip 3 + arms 14");
    for seed in 0..5 {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        let r = p
            .plan(paper_settings(), ik(), &mut term, seed)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let (l, rr) = p.decode(r.goal_index);
        eprintln!(
            "bimanual seed {seed}: {:.1} ms (+{:.1} ms pruning), {} iterations, {} IK solutions, grasps {} + {}",
            r.stats.time.as_secs_f64() * 1e3,
            r.stats.simplify_time.as_secs_f64() * 1e3,
            r.stats.iterations,
            r.stats.ik_solutions,
            p.left_names[l],
            p.right_names[rr]
        );
        check(&p, &r);
    }
}

#[test]
fn bimanual_is_deterministic_per_seed() {
    let s = scene("kitchen");
    let p = problem(&s, "table").expect("problem");
    let run = || {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        p.plan(paper_settings(), ik(), &mut term, 7).expect("plan")
    };
    let (a, b) = (run(), run());
    assert_eq!(a.path, b.path);
    assert_eq!(a.goal_index, b.goal_index);
}

#[test]
fn bimanual_rejects_bad_requests_cleanly() {
    let s = scene("kitchen");
    assert!(matches!(
        problem(&s, "nope").err(),
        Some(PlanError::InvalidInput(_))
    ));
    let world = CollisionWorld::from_scene(&s);
    let q0 = CollisionWorld::start_config(&s);
    let g = grids();
    // Grids swapped: the left grid belongs to another chain.
    let e = BimanualProblem::new(
        &s,
        &world,
        &q0,
        "armar",
        ("torso_left_arm", "torso_right_arm"),
        "table",
        (&g.1, &g.0),
        BimanualSettings::default(),
    );
    let e = e.err();
    assert!(matches!(e, Some(PlanError::InvalidInput(_))), "{e:?}");
    // A threshold no reachability entry passes: no base position → clean error.
    let e = BimanualProblem::new(
        &s,
        &world,
        &q0,
        "armar",
        ("torso_left_arm", "torso_right_arm"),
        "table",
        (&g.0, &g.1),
        BimanualSettings {
            threshold: 0.999_999,
            ..BimanualSettings::default()
        },
    );
    let e = e.err();
    assert!(matches!(e, Some(PlanError::InvalidGoal { .. })), "{e:?}");
}
