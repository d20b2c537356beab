//! Multi-Robot-RRT (002 Alg. 3) and phase-space scheduling (002 §V): schedules re-checked
//! densely in time with the exact checker while every robot moves at once, velocity limits,
//! monotone phases, the deterministic mode, one robot, and cancel; multi-arm plans (decoupled,
//! prioritized, composite, shortcut) re-checked densely with all arms moving.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker};
use manyhands::planning::planners::multi_arm::{
    plan_multi_arm, Arm, Methods, MultiArmMethod, MultiArmPlan, MultiArmProblem, MultiArmSettings,
};
use manyhands::planning::planners::multi_robot_rrt::{
    multi_robot_rrt, MultiRobotPlan, MultiRobotProblem, MultiRobotSettings,
};
use manyhands::planning::planners::phase_space::{
    PhaseSpace, PhaseSpaceSettings, RobotTrajectory, Schedule, ScheduleMethod,
};
use manyhands::planning::{PlanError, Termination};
use manyhands::reachability::{GridCache, GridRecipe};

/// Grids small enough for tests (built once per process, in memory).
fn grids() -> &'static GridCache {
    static CACHE: std::sync::OnceLock<GridCache> = std::sync::OnceLock::new();
    CACHE.get_or_init(|| GridCache::new(None))
}

fn recipe() -> GridRecipe {
    GridRecipe {
        samples: 200_000,
        ..GridRecipe::default()
    }
}

fn problem(scene: &str, robots: &[&str]) -> MultiRobotProblem {
    let s = common::scene(scene);
    let names: Vec<String> = robots.iter().map(|r| r.to_string()).collect();
    MultiRobotProblem::with_grids(
        &s,
        &names,
        "torso_left_arm",
        "torso_right_arm",
        "table",
        grids(),
        recipe(),
        Default::default(),
    )
    .expect("problem")
}

/// Samples the schedule every `dt` s and checks every instant with the exact checker in `world`
/// (every robot at its scheduled configuration at once), and every velocity against the URDF
/// limit (within 1e-6 relative).
fn assert_schedule_free(
    world: &CollisionWorld,
    world_q: &[f64],
    robots: &[usize],
    s: &Schedule,
    dt: f64,
) {
    let mut exact = ExactChecker::new(world);
    let mut q = world_q.to_vec();
    let samples = s.sample(dt);
    assert!(samples.len() >= 2);
    for (t, pos, vel) in &samples {
        for (k, &r) in robots.iter().enumerate() {
            let p = &world.robots[r];
            q[p.offset..p.offset + p.robot.dof()].copy_from_slice(&pos[k]);
            for (v, &x) in vel[k].iter().enumerate() {
                let l = p.robot.var_limits(v).velocity;
                if l.is_finite() && l > 0.0 {
                    assert!(
                        x.abs() <= l * (1.0 + 1e-6),
                        "{}: {} velocity {x} over {l} at t = {t}",
                        p.name,
                        p.robot.var_name(v)
                    );
                }
            }
        }
        if let Some(c) = exact.first_contact(&q) {
            panic!(
                "collision at t = {t:.4} s of {:.4}: {} with {}",
                s.duration, c.a, c.b
            );
        }
    }
    // Monotone phases.
    for w in s.phase_path.windows(2) {
        assert!(
            w[0].iter().zip(&w[1]).all(|(a, b)| a <= b),
            "phase runs backwards: {w:?}"
        );
    }
    assert!(s.phase_path[0].iter().all(|&p| p == 0.0));
    assert!(s
        .phase_path
        .last()
        .is_some_and(|p| p.iter().all(|&x| x == 1.0)));
}

fn assert_plan_valid(p: &MultiRobotProblem, plan: &MultiRobotPlan) {
    // Robots against each other, all moving at the schedule's times, held nothing.
    let robots: Vec<usize> = plan
        .solutions
        .iter()
        .map(|s| p.members[s.member].robot)
        .collect();
    assert_schedule_free(
        &p.world.between_robots(),
        &p.world_q,
        &robots,
        &plan.schedule,
        0.002,
    );
    assert!(plan.score.force_closure && plan.score.epsilon > 0.0);
    // The schedule starts at every robot's start and ends at its solution's goal.
    let first = &plan.schedule.knots[0];
    let last = plan.schedule.knots.last().expect("knots");
    for (k, s) in plan.solutions.iter().enumerate() {
        assert_eq!(first.configs[k], s.path[0]);
        assert_eq!(&last.configs[k], s.path.last().expect("path"));
    }
}

/// The two ARMARs of the `handoff` scene and their start.
fn handoff() -> (CollisionWorld, Vec<f64>) {
    let s = common::scene("handoff");
    (
        CollisionWorld::from_scene(&s),
        CollisionWorld::start_config(&s),
    )
}

/// Robot `r`'s start configuration with its platform at base variables (x, y).
fn platform_at(world: &CollisionWorld, q0: &[f64], r: usize, x: f64, y: f64) -> Vec<f64> {
    let model = &world.robots[r].robot;
    let mut c = world.robot_config(r, q0).to_vec();
    c[model.var("base_x").expect("base_x")] = x;
    c[model.var("base_y").expect("base_y")] = y;
    c
}

/// Robot `r` driving its platform on a straight line from `from` to `to` (base x, y).
fn drive(
    world: &CollisionWorld,
    q0: &[f64],
    r: usize,
    from: (f64, f64),
    to: (f64, f64),
) -> RobotTrajectory {
    RobotTrajectory {
        robot: r,
        waypoints: vec![
            platform_at(world, q0, r, from.0, from.1),
            platform_at(world, q0, r, to.0, to.1),
        ],
        accelerations: None,
    }
}

/// Two ARMAR platforms whose straight paths cross at the same phase: the straight line in P
/// collides, a schedule exists (one waits), and it is free when re-checked densely in time.
#[test]
fn crossing_trajectories_get_a_waiting_schedule() {
    let (world, q0) = handoff();
    let dof = world.robots[0].robot.dof();
    // armar_a (at the origin, facing +x) drives along y through (0.7, 0); armar_b (at 1.4,
    // facing -x) drives along x through the same point.
    let ta = drive(&world, &q0, 0, (0.7, -1.3), (0.7, 1.3));
    let tb = drive(&world, &q0, 1, (-0.6, 0.0), (2.0, 0.0));
    assert_eq!(ta.waypoints[0].len(), dof);
    let mut ps = PhaseSpace::new(&world, &q0, &[ta.clone(), tb.clone()]).expect("phase space");
    assert!(
        !ps.segment_valid(&[0.0, 0.0], &[1.0, 1.0]),
        "the straight line must collide"
    );
    let sched = ps
        .plan(&PhaseSpaceSettings::default(), &mut Termination::new(), 1)
        .expect("schedule");
    // One after the other is valid here, so the prioritized advance schedules them, with
    // overlap: faster than sequential execution.
    assert_eq!(sched.method, ScheduleMethod::Prioritized);
    assert!(sched.duration > 0.0);
    assert!(sched.duration < sched.robot_durations.iter().sum::<f64>() - 1e-6);
    assert_schedule_free(&world.between_robots(), &q0, &[0, 1], &sched, 0.002);
    // With acceleration limits the schedule is slower, still free and starts and ends at rest.
    let acc = vec![2.0; dof];
    let with_acc: Vec<RobotTrajectory> = [ta, tb]
        .into_iter()
        .map(|t| RobotTrajectory {
            accelerations: Some(acc.clone()),
            ..t
        })
        .collect();
    let mut ps = PhaseSpace::new(&world, &q0, &with_acc).expect("phase space");
    let slow = ps
        .plan(&PhaseSpaceSettings::default(), &mut Termination::new(), 1)
        .expect("schedule");
    assert!(slow.duration > sched.duration);
    assert_schedule_free(&world.between_robots(), &q0, &[0, 1], &slow, 0.002);
    let (_, v0) = slow.state_at(0.0);
    let (_, v1) = slow.state_at(slow.duration);
    assert!(v0.iter().chain(&v1).flatten().all(|v| v.abs() < 1e-9));
}

/// Sequential execution is refused when a robot's goal lies on the other's path (no schedule
/// exists) — the condition the deadlock check rules out.
#[test]
fn blocked_goal_has_no_schedule() {
    let (world, q0) = handoff();
    // armar_a (at the origin) drives from world (0.7, -1.3) to (0.7, 0); armar_b (at 1.4,
    // facing -x: world (1.4 - x, -y)) from world (0.7, 1.3) to (0.7, -1.3). armar_a ends right
    // on armar_b's path, and armar_b ends where armar_a starts: in no order and with no
    // timing can armar_b get past. The starts and the final configurations are free.
    let ta = drive(&world, &q0, 0, (0.7, -1.3), (0.7, 0.0));
    let tb = drive(&world, &q0, 1, (0.7, -1.3), (0.7, 1.3));
    let mut ps = PhaseSpace::new(&world, &q0, &[ta, tb]).expect("phase space");
    let settings = PhaseSpaceSettings {
        max_iterations: 300,
        ..PhaseSpaceSettings::default()
    };
    let r = ps.plan(&settings, &mut Termination::new(), 1);
    // Its own error, not a goal's: a schedule has no goal, only fixed trajectories to time.
    match r {
        Err(e @ PlanError::NoSchedule { .. }) => {
            assert!(
                e.to_string().starts_with("no collision-free schedule"),
                "{e}"
            )
        }
        other => panic!("expected NoSchedule, got {other:?}"),
    }
}

/// When the robots cannot go one after the other in index order (armar_a ends on armar_b's
/// path), the prioritized advance does not apply, and RRT-Connect in phase space finds the
/// schedule where armar_b passes first; it is free when re-checked densely in time.
#[test]
fn a_schedule_against_the_index_order_comes_from_the_phase_space_rrt() {
    let (world, q0) = handoff();
    let ta = drive(&world, &q0, 0, (0.7, -1.3), (0.7, 0.0));
    let tb = drive(&world, &q0, 1, (-0.6, 0.0), (2.0, 0.0));
    let mut ps = PhaseSpace::new(&world, &q0, &[ta, tb]).expect("phase space");
    assert!(
        !ps.path_valid(&ps.sequential_path()),
        "index-order sequential execution must collide"
    );
    let sched = ps
        .plan(&PhaseSpaceSettings::default(), &mut Termination::new(), 1)
        .expect("schedule");
    assert_eq!(sched.method, ScheduleMethod::PhaseSpaceRrt);
    assert_schedule_free(&world.between_robots(), &q0, &[0, 1], &sched, 0.002);
}

fn settings(deterministic: bool) -> MultiRobotSettings {
    MultiRobotSettings {
        deterministic,
        ..MultiRobotSettings::default()
    }
}

#[test]
fn two_robots_grasp_the_table_and_move_together() {
    let p = problem("kitchen_two", &["armar_a", "armar_b"]);
    let mut term = Termination::new().with_time_limit(Duration::from_secs(60));
    let plan = multi_robot_rrt(&p, &settings(true), &mut term, 3, &mut |_| {}).expect("plan");
    assert_eq!(plan.solutions.len(), 2);
    assert_plan_valid(&p, &plan);
    // Each robot's own path is free in the scene (checked densely by the exact checker).
    for s in &plan.solutions {
        let m = &p.members[s.member];
        let path: Vec<Vec<f64>> = s
            .path
            .iter()
            .map(|q| m.problem.space.from_world(q))
            .collect();
        common::assert_exactly_free(&m.problem.world, &m.problem.space, &path);
    }
    // Deterministic: the same request and seed give the same plan.
    let mut term = Termination::new().with_time_limit(Duration::from_secs(60));
    let again = multi_robot_rrt(&p, &settings(true), &mut term, 3, &mut |_| {}).expect("plan");
    let key = |p: &MultiRobotPlan| -> Vec<_> {
        p.solutions
            .iter()
            .map(|s| (s.member, s.grasps, s.path.clone()))
            .collect()
    };
    assert_eq!(key(&again), key(&plan));
    assert_eq!(again.schedule.phase_path, plan.schedule.phase_path);
    assert_eq!(again.schedule.knots, plan.schedule.knots);
    // The parallel mode solves it too.
    let mut term = Termination::new().with_time_limit(Duration::from_secs(60));
    let par = multi_robot_rrt(&p, &settings(false), &mut term, 5, &mut |_| {}).expect("plan");
    assert_plan_valid(&p, &par);
}

#[test]
fn one_robot_is_a_bimanual_plan() {
    let p = problem("kitchen", &["armar"]);
    let mut term = Termination::new().with_time_limit(Duration::from_secs(30));
    let plan = multi_robot_rrt(&p, &settings(true), &mut term, 1, &mut |_| {}).expect("plan");
    assert_eq!(plan.solutions.len(), 1);
    assert_eq!(
        plan.stats.combinations,
        plan.stats.rejected_collision
            + plan.stats.rejected_score
            + plan.stats.rejected_deadlock
            + 1
    );
    assert_eq!(plan.schedule.method, ScheduleMethod::Simultaneous);
    let m = &p.members[0];
    let (l, r) = plan.solutions[0].grasps;
    assert!(m.problem.left_names[l].starts_with("table_l"));
    assert!(m.problem.right_names[r].starts_with("table_r"));
    assert_plan_valid(&p, &plan);
}

/// A score no combination reaches keeps the workers busy until the stop flag: all of them and
/// the collector stop promptly.
#[test]
fn cancel_stops_every_worker() {
    let p = problem("kitchen_two", &["armar_a", "armar_b"]);
    let stop = Arc::new(AtomicBool::new(false));
    let s = MultiRobotSettings {
        s_min: 1e9,
        ..settings(false)
    };
    let flag = stop.clone();
    let setter = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        flag.store(true, Ordering::Relaxed);
        Instant::now()
    });
    let mut term = Termination::new()
        .with_time_limit(Duration::from_secs(60))
        .with_stop_flag(stop);
    let r = multi_robot_rrt(&p, &s, &mut term, 1, &mut |_| {});
    let done = Instant::now();
    let set = setter.join().expect("setter");
    assert!(matches!(r, Err(PlanError::Stopped { .. })), "{r:?}");
    let latency = done.saturating_duration_since(set);
    assert!(
        latency < Duration::from_millis(250),
        "stopped {latency:?} after the flag"
    );
}

/// A robot whose start collides with the scene ends the run at once with that reason, naming
/// the robot, in both modes (not a time-out after the whole limit).
#[test]
fn a_colliding_start_is_a_clear_error() {
    let root = common::root();
    let text = std::fs::read_to_string(root.join("scenes/kitchen_two.json")).expect("scene");
    let mut json: serde_json::Value = serde_json::from_str(&text).expect("json");
    // armar_b's platform inside the back wall's left part.
    json["robots"][1]["base_pose"]["position"] = serde_json::json!([-3.875, 1.65, 0.0]);
    let lib = manyhands::model::load_robot_dir(&root.join("robots")).expect("robots");
    let scene =
        manyhands::model::Scene::from_str(&json.to_string(), "test", &root.join("scenes"), &lib)
            .expect("scene");
    let names = vec!["armar_a".to_string(), "armar_b".to_string()];
    let p = MultiRobotProblem::with_grids(
        &scene,
        &names,
        "torso_left_arm",
        "torso_right_arm",
        "table",
        grids(),
        recipe(),
        Default::default(),
    )
    .expect("problem");
    for deterministic in [true, false] {
        let t0 = Instant::now();
        let mut term = Termination::new().with_time_limit(Duration::from_secs(30));
        let r = multi_robot_rrt(&p, &settings(deterministic), &mut term, 1, &mut |_| {});
        let e = r.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("armar_b") && e.contains("start"), "{e}");
        assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", t0.elapsed());
    }
}

/// The `arms_crossing` cell: armar_a's right arm and armar_b's left arm from the scene's start
/// to the goals `goals` (per arm: the named configuration whose group values are the goal).
fn crossing(goals: [&str; 2]) -> MultiArmProblem {
    let sc = common::scene("arms_crossing");
    let world = CollisionWorld::from_scene(&sc);
    let world_q = CollisionWorld::start_config(&sc);
    let arms = [(0, "right_arm"), (1, "left_arm")]
        .iter()
        .zip(goals)
        .map(|(&(r, group), goal)| {
            let p = &sc.robots[r];
            let vars = p.robot.group(group).expect("group").vars.clone();
            let named = p
                .configs
                .get(goal)
                .cloned()
                .or_else(|| p.robot.named_config(goal))
                .expect("named configuration");
            Arm {
                robot: r,
                goal: vars.iter().map(|&v| named[v]).collect(),
                vars,
            }
        })
        .collect();
    MultiArmProblem::new(world, world_q, arms).expect("problem")
}

fn only(decoupled: bool, prioritized: bool, composite: bool) -> MultiArmSettings {
    MultiArmSettings {
        methods: Methods {
            decoupled,
            prioritized,
            composite,
        },
        ..MultiArmSettings::default()
    }
}

fn plan_arms(
    p: &MultiArmProblem,
    s: &MultiArmSettings,
    seed: u64,
) -> Result<MultiArmPlan, PlanError> {
    let mut term = Termination::new().with_time_limit(Duration::from_secs(20));
    plan_multi_arm(p, s, &mut term, seed)
}

/// A multi-arm plan checked from outside: it starts at every arm's start and ends at its goal;
/// every straight composite segment is re-checked with the exact checker with all arms moving
/// together, at most 0.005 rad (or 0.5 mm) of any joint between two checked states; the timing
/// stays within every joint's velocity and acceleration limits, at rest at both ends; and the
/// makespan is the timing's duration, no longer than before shortcutting.
fn assert_multi_arm_free(p: &MultiArmProblem, plan: &MultiArmPlan) {
    assert_eq!(plan.path[0], p.start());
    assert_eq!(plan.path.last(), Some(&p.goal()));
    let mut exact = ExactChecker::new(&p.world);
    let vars = p.vars();
    for (k, w) in plan.path.windows(2).enumerate() {
        let delta = w[0]
            .iter()
            .zip(&w[1])
            .map(|(a, b)| (b - a).abs())
            .fold(0.0, f64::max);
        let steps = (delta / 0.005).ceil().max(1.0) as usize;
        for i in 0..=steps {
            let f = i as f64 / steps as f64;
            let c: Vec<f64> = w[0]
                .iter()
                .zip(&w[1])
                .map(|(a, b)| a + (b - a) * f)
                .collect();
            let mut q = p.world_q.clone();
            for (&v, &x) in vars.iter().zip(&c) {
                q[v] = x;
            }
            if let Some(c) = exact.first_contact(&q) {
                panic!("segment {k} at {f:.4}: {} with {}", c.a, c.b);
            }
        }
    }
    let limits = manyhands::trajectory::timing::world_limits(&p.world).select(&vars);
    let d = plan.timed.duration;
    assert!((plan.makespan - d).abs() < 1e-12);
    assert!(plan.makespan <= plan.makespan_before + 1e-9);
    let n = (d / 0.005).ceil() as usize;
    for i in 0..=n {
        let s = plan.timed.state_at(d * i as f64 / n as f64);
        for (j, (v, a)) in s.velocities.iter().zip(&s.accelerations).enumerate() {
            assert!(
                v.abs() <= limits.velocity[j] * (1.0 + 1e-6),
                "v {v} at {}",
                s.time
            );
            assert!(
                a.abs() <= limits.acceleration[j] * (1.0 + 1e-6),
                "a {a} at {}",
                s.time
            );
            if i == 0 || i == n {
                assert!(v.abs() < 1e-9, "not at rest");
            }
        }
    }
}

/// In the `arms_crossing` cell each goal lies on the other arm's path: the arms planned alone
/// have no schedule (the decoupled method alone fails), the multi-arm planner falls back and
/// solves it, and the plan is free when re-checked densely with the exact checker while both
/// arms move; the same seed gives the same plan.
#[test]
fn multi_arm_solves_a_crossing_that_decoupled_scheduling_cannot() {
    let p = crossing(["goal", "goal"]);
    let e = plan_arms(&p, &only(true, false, false), 1).expect_err("decoupled alone must fail");
    assert!(
        e.to_string().starts_with("decoupled: ")
            && e.to_string().contains("collision-free schedule"),
        "{e}"
    );
    let plan = plan_arms(&p, &MultiArmSettings::default(), 1).expect("multi-arm plan");
    assert_ne!(plan.method, MultiArmMethod::Decoupled);
    assert_eq!(plan.stats.attempts[0].method, MultiArmMethod::Decoupled);
    assert!(!plan.stats.attempts[0].solved);
    assert_eq!(plan.stats.attempts.last().map(|a| a.solved), Some(true));
    assert_multi_arm_free(&p, &plan);
    let again = plan_arms(&p, &MultiArmSettings::default(), 1).expect("again");
    assert_eq!(again.path, plan.path);
    assert_eq!(again.method, plan.method);
}

/// With `composite_first`, the failed schedule of the two arms names them as the pair in
/// conflict and the composite search over them comes straight after it: two attempts, no
/// prioritized planning, and the plan as free as before.
#[test]
fn composite_first_follows_the_failed_schedule_with_the_conflicting_arms() {
    let p = crossing(["goal", "goal"]);
    let s = MultiArmSettings {
        composite_first: true,
        ..MultiArmSettings::default()
    };
    let plan = plan_arms(&p, &s, 1).expect("multi-arm plan");
    let methods: Vec<_> = plan.stats.attempts.iter().map(|a| a.method).collect();
    assert_eq!(
        methods,
        [MultiArmMethod::Decoupled, MultiArmMethod::Composite],
        "{:?}",
        plan.stats.attempts
    );
    assert!(!plan.stats.attempts[0].solved && plan.stats.attempts[1].solved);
    assert_eq!(plan.method, MultiArmMethod::Composite);
    assert_eq!(plan.conflicts, [(0, 1)]);
    assert_eq!(plan.composite_arms, [0, 1]);
    assert_multi_arm_free(&p, &plan);
}

/// Prioritized planning in space-time (one arm retracts while the other rises to where it was)
/// and makespan-aware shortcutting: the raw plan's waits and detours are shortcut to a
/// strictly shorter makespan, still free when re-checked densely with both arms moving.
#[test]
fn prioritized_plans_are_shortcut_to_a_shorter_makespan() {
    let p = crossing(["home", "goal"]);
    let plan = plan_arms(&p, &only(false, true, false), 3).expect("prioritized plan");
    assert_eq!(plan.method, MultiArmMethod::Prioritized);
    assert!(
        plan.makespan < plan.makespan_before - 1e-6,
        "{} !< {}",
        plan.makespan,
        plan.makespan_before
    );
    assert!(plan.stats.shortcuts_composite + plan.stats.shortcuts_per_arm > 0);
    assert_multi_arm_free(&p, &plan);
    // Without shortcutting the makespan stays.
    let raw = plan_arms(
        &p,
        &MultiArmSettings {
            shortcut_iterations: 0,
            ..only(false, true, false)
        },
        3,
    )
    .expect("raw");
    assert_eq!(raw.makespan, raw.makespan_before);
    assert_eq!(raw.makespan_before, plan.makespan_before);
}
