//! J+-RRT (paper 000 §IV-B, Alg. 1–2) and dual-arm J+-RRT (000 §V-A, Alg. 4–5) on the shipped
//! kitchen scenes. Every returned path is checked independently of the planner, as in
//! tests/grasp_planners.rs: it starts at the start, its last state reaches a grasp (FK within
//! 1e-6), it stays within joint limits, and the exact (parry) checker finds it collision-free at
//! 5 mm / 0.5° — held object included.

mod common;
use common::{check_handoff, check_reach, far_wok_problem, kitchen_wok_handoff, scene};

use std::time::{Duration, Instant};

use nalgebra::{Translation3, Vector3};

use manyhands::collision::CollisionWorld;
use manyhands::geometry::Pose;
use manyhands::kinematics::pose_error;
use manyhands::planning::problems::grasping::ReachProblem;
use manyhands::planning::{
    DualArmJPlusRrt, JPlusRrt, JPlusRrtSettings, PlanError, PlanResult, Termination,
};

fn reach_problem(scene_name: &str) -> ReachProblem {
    let s = scene(scene_name);
    let world = CollisionWorld::from_scene(&s);
    let wq = CollisionWorld::start_config(&s);
    ReachProblem::grasp(&s, &world, &wq, "armar", "torso_right_arm", "wok").expect("problem")
}

fn report(what: &str, ms: f64, r: &PlanResult) {
    eprintln!(
        "{what}: {ms:.1} ms, {} iterations, tree {}, {} Jacobian steps, {} checks, grasp {}, \
         {} → {} vertices",
        r.stats.iterations,
        r.stats.start_tree_size,
        r.stats.jacobian_steps,
        r.stats.collision_checks,
        r.goal_index,
        r.stats.vertices_raw,
        r.stats.vertices_simplified
    );
}

#[test]
fn j_plus_rrt_reaches_the_wok_with_and_without_obstacle() {
    for scene_name in ["kitchen", "obstacle"] {
        let p = reach_problem(scene_name);
        let mut planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
        for seed in 0..3 {
            let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
            let t = Instant::now();
            let r = planner
                .plan(&p.start, &mut term, seed)
                .unwrap_or_else(|e| panic!("{scene_name} seed {seed}: {e}"));
            let ms = t.elapsed().as_secs_f64() * 1e3;
            report(&format!("J+ {scene_name} seed {seed}"), ms, &r);
            assert!(r.stats.jacobian_steps > 0);
            assert!(r.stats.start_tree_size >= 1);
            check_reach(&p, &r);
        }
    }
}

#[test]
fn j_plus_rrt_is_deterministic_per_seed() {
    let p = reach_problem("kitchen");
    let mut planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
    let mut run = |seed| {
        planner
            .plan(&p.start, &mut Termination::new(), seed)
            .expect("solved")
    };
    let (a, b) = (run(7), run(7));
    assert_eq!(a.path, b.path);
    assert_eq!(a.goal_index, b.goal_index);
    assert_eq!(a.stats.iterations, b.stats.iterations);
    assert_eq!(a.stats.jacobian_steps, b.stats.jacobian_steps);
    assert_eq!(a.stats.start_tree_size, b.stats.start_tree_size);
}

#[test]
fn j_plus_rrt_fails_cleanly_for_an_unreachable_object() {
    let p = far_wok_problem();
    let mut planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
    let limit = Duration::from_millis(200);
    let mut term = Termination::new().with_time_limit(limit);
    let t = Instant::now();
    let r = planner.plan(&p.start, &mut term, 1);
    let el = t.elapsed();
    assert!(matches!(r, Err(PlanError::Timeout { .. })), "{r:?}");
    assert!(el < limit + Duration::from_millis(10), "{el:?}");
    let stats = r.err().and_then(|e| e.stats().cloned()).expect("stats");
    assert!(
        stats.iterations > 0 && stats.jacobian_steps > 0,
        "{stats:?}"
    );
}

#[test]
fn j_plus_rrt_rejects_bad_input() {
    let p = reach_problem("kitchen");
    let d = JPlusRrtSettings::default();
    for bad in [
        JPlusRrtSettings {
            p_extend_to_goal: 0.0,
            ..d
        },
        JPlusRrtSettings {
            p_extend_from_new: 1.5,
            ..d
        },
        JPlusRrtSettings {
            restart_nodes: 5,
            ..d
        },
    ] {
        assert!(
            matches!(
                JPlusRrt::for_problem(&p, bad),
                Err(PlanError::InvalidInput(_))
            ),
            "{bad:?}"
        );
    }
    let mut planner = JPlusRrt::new(
        p.space.clone(),
        &p.world,
        &p.hand,
        Vec::new(),
        JPlusRrtSettings::default(),
    )
    .expect("planner");
    let r = planner.plan(&p.start, &mut Termination::new(), 0);
    assert!(
        matches!(r, Err(PlanError::InvalidGoal { count: 0, .. })),
        "{r:?}"
    );
    let mut planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
    let short = &p.start[..3];
    let r = planner.plan(short, &mut Termination::new(), 0);
    assert!(matches!(r, Err(PlanError::InvalidStart { .. })), "{r:?}");
}

#[test]
fn dual_arm_j_plus_rrt_regrasps_the_wok() {
    // First grasp the wok with the right hand (IK-RRT), then re-grasp it with the left (J+).
    let h = kitchen_wok_handoff();
    let mut planner =
        DualArmJPlusRrt::for_problem(&h, JPlusRrtSettings::dual_arm()).expect("planner");
    let mut first = None;
    for seed in 0..2 {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        let t = Instant::now();
        let r = planner
            .plan(&h.start, &mut term, seed)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let ms = t.elapsed().as_secs_f64() * 1e3;
        report(&format!("dual-arm J+ seed {seed}"), ms, &r);
        check_handoff(&h, &r);
        first.get_or_insert(r);
    }
    // Same seed, same path.
    let a = first.expect("seed 0");
    let b = planner
        .plan(&h.start, &mut Termination::new(), 0)
        .expect("b");
    assert_eq!(a.path, b.path);
    assert_eq!(a.goal_index, b.goal_index);
}

/// Whether some state of `path` before its last puts `tcp(state)` within J+-RRT's goal threshold
/// (1 cm, 2°) of `pre(state)`.
fn passes_pregrasp(
    path: &[Vec<f64>],
    tcp_and_pre: impl Fn(&[f64]) -> (Pose, Pose),
    s: &JPlusRrtSettings,
) -> bool {
    path[..path.len() - 1].iter().any(|q| {
        let (tcp, pre) = tcp_and_pre(q);
        let (ep, ea) = pose_error(&tcp, &pre);
        ep <= s.goal_position + 1e-9 && ea <= s.goal_angle + 1e-9
    })
}

/// `pose · Translation(offset)`.
fn offset(pose: &Pose, o: &Vector3<f64>) -> Pose {
    pose * Pose::from_parts(Translation3::from(*o), nalgebra::UnitQuaternion::identity())
}

/// Goal extensions approach a grasp through its pre-grasp pose (the scene's 8 cm
/// `pregrasp_offset` of the wok grasps): the unpruned path of J+-RRT passes within the goal
/// threshold of the reached grasp's pre-grasp pose before it ends at the grasp, and so does
/// the receiver's TCP on the held object in dual-arm J+-RRT. Offsets of the wrong number or not
/// finite are input errors.
#[test]
fn j_plus_rrt_approaches_grasps_through_their_pregrasp_pose() {
    let p = reach_problem("kitchen");
    assert!(p.pregrasp_offsets.iter().all(|o| o.norm() > 0.05));
    let mut settings = JPlusRrtSettings::default();
    settings.rrt.shortcut = None;
    let mut planner = JPlusRrt::for_problem(&p, settings).expect("planner");
    for seed in 0..4 {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        let r = planner.plan(&p.start, &mut term, seed).expect("plan");
        check_reach(&p, &r);
        let g = r.goal_index;
        let pre = offset(&(p.object_pose * p.grasps[g]), &p.pregrasp_offsets[g]);
        assert!(
            passes_pregrasp(
                &r.path,
                |q| (p.hand.tcp_pose(&p.world, &p.space.to_world(q)), pre),
                &settings
            ),
            "seed {seed}: the path does not pass the pre-grasp pose of grasp {g}"
        );
    }

    let h = kitchen_wok_handoff();
    let mut settings = JPlusRrtSettings::dual_arm();
    settings.rrt.shortcut = None;
    let mut planner = DualArmJPlusRrt::for_problem(&h, settings).expect("planner");
    for seed in 0..3 {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        let r = planner.plan(&h.start, &mut term, seed).expect("plan");
        let g = r.goal_index;
        let pre = offset(&h.grasps[g], &h.pregrasp_offsets[g]);
        assert!(
            passes_pregrasp(
                &r.path,
                |q| {
                    let w = h.space.to_world(q);
                    let obj = h.giver.tcp_pose(&h.world, &w) * h.held.inverse();
                    (h.receiver.tcp_pose(&h.world, &w), obj * pre)
                },
                &settings
            ),
            "seed {seed}: the receiver does not pass the pre-grasp pose of grasp {g}"
        );
        check_handoff(&h, &r);
    }

    let planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
    let short = &p.pregrasp_offsets[1..];
    assert!(matches!(
        planner.with_pregrasp_offsets(short),
        Err(PlanError::InvalidInput(_))
    ));
    let mut nan = p.pregrasp_offsets.clone();
    nan[0].x = f64::NAN;
    let planner = DualArmJPlusRrt::for_problem(&h, JPlusRrtSettings::dual_arm()).expect("p");
    assert!(matches!(
        planner.with_pregrasp_offsets(&nan[..h.grasps.len()]),
        Err(PlanError::InvalidInput(_))
    ));
}

/// Restarts (`restart_nodes`): the search starts over with a new tree once the tree holds more
/// than that many nodes, counts it, and still returns a checked plan — the same plan for the
/// same seed (a setting of 1–9 is an input error: `j_plus_rrt_rejects_bad_input`).
#[test]
fn dual_arm_j_plus_rrt_restarts_with_a_new_tree() {
    let h = kitchen_wok_handoff();
    let settings = JPlusRrtSettings {
        restart_nodes: 300,
        ..JPlusRrtSettings::dual_arm()
    };
    let mut planner = DualArmJPlusRrt::for_problem(&h, settings).expect("planner");
    let mut restarted = 0;
    for seed in 0..6 {
        let mut term = Termination::new().with_time_limit(Duration::from_secs(10));
        let r = planner.plan(&h.start, &mut term, seed).expect("plan");
        check_handoff(&h, &r);
        // At most one iteration's nodes beyond the limit: one random extension and one goal
        // extension (two J+ steps per step pair, and the final snap).
        let bound = 300 + 1 + 2 * settings.max_goal_steps as usize + 1;
        assert!(
            r.stats.start_tree_size <= bound,
            "seed {seed}: tree of {} nodes",
            r.stats.start_tree_size
        );
        eprintln!(
            "seed {seed}: {} restarts, {} iterations, tree {}",
            r.stats.restarts, r.stats.iterations, r.stats.start_tree_size
        );
        if r.stats.restarts > 0 {
            restarted += 1;
            let again = planner
                .plan(&h.start, &mut Termination::new(), seed)
                .expect("again");
            assert_eq!(again.path, r.path, "seed {seed}");
        }
    }
    assert!(restarted >= 2, "only {restarted} of 6 runs restarted");
}

/// Issue 28: a start value at most `Limits::TOLERANCE` (1e-5) outside a joint limit is clamped
/// into it, as RRT-Connect does; farther out the start is refused.
#[test]
fn start_within_the_tolerance_of_a_limit_is_clamped() {
    let p = reach_problem("kitchen");
    let mut planner = JPlusRrt::for_problem(&p, JPlusRrtSettings::default()).expect("planner");
    let (k, limit, beyond) = limit_start(&p, |q| planner.validator().invalidity(q).is_none());
    let mut near = p.start.clone();
    near[k] = limit + beyond * 0.5e-5;
    let mut term = Termination::new().with_time_limit(Duration::from_secs(20));
    let r = planner
        .plan(&near, &mut term, 1)
        .expect("plan from a start 5e-6 outside a limit");
    let mut clamped = near.clone();
    clamped[k] = limit;
    assert_eq!(r.path[0], clamped, "start clamped into the limit");
    let last = r.path.last().unwrap();
    assert!(planner.validator().invalidity(last).is_none(), "goal valid");
    near[k] = limit + beyond * 2e-5;
    match planner.plan(&near, &mut Termination::new(), 1) {
        Err(PlanError::InvalidStart { .. }) => {}
        other => panic!("expected InvalidStart, got {other:?}"),
    }
}

/// A joint `k` and one of its limits such that the problem's start with that joint at the
/// limit is a valid start; `beyond` is the sign pointing out of the limits.
fn limit_start(p: &ReachProblem, mut valid: impl FnMut(&[f64]) -> bool) -> (usize, f64, f64) {
    let (lo, hi) = (p.space.lower().to_vec(), p.space.upper().to_vec());
    (0..p.space.dim())
        .flat_map(|k| [(k, lo[k], -1.0), (k, hi[k], 1.0)])
        .find(|&(k, x, _)| {
            let mut q = p.start.clone();
            q[k] = x;
            x.is_finite() && valid(&q)
        })
        .expect("a joint limit that is a valid start")
}
