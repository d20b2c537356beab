//! The `panda_four` cell (issue 23, 5c) — NEEDS THE MOTIONBENCHMAKER DATA (`manyhands data mbm`
//! or `../shared/benchmarks/mbm/`; skipped with a SKIPPED line without it): the benchmark's
//! spherized Panda uploaded to a real server as an outside robot, four of them placed around a
//! table with crossing goals, each arm planned alone (kind `joint_space`), then scheduled (kind
//! `schedule`). The schedule is re-checked with the exact checker every millisecond while all
//! four arms move, with velocity limits; the composite 28-D RRT-Connect plan is re-checked
//! densely along its path.

mod common;

use std::path::Path;

use common::server::start;
use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker, MotionValidator};
use manyhands::model::{panda_four, Scene};
use manyhands::planning::planners::decoupled::{composite, decoupled, RobotGoal};
use manyhands::planning::planners::phase_space::ScheduleMethod;
use manyhands::planning::{JointSpace, Termination};
use reqwest::StatusCode;
use serde_json::{json, Value};

fn local_scene(dir: &Path) -> Scene {
    manyhands::benchmark::mbm_data::panda_four_scene(dir).expect("panda_four")
}

fn goals(scene: &Scene) -> Vec<RobotGoal> {
    scene
        .robots
        .iter()
        .enumerate()
        .map(|(robot, p)| RobotGoal {
            robot,
            goal: p.configs["goal"].clone(),
        })
        .collect()
}

/// The cell as designed: free at start and goal, each motion free alone and one after the
/// other in index order, but the straight-line motions collide when run together.
#[test]
fn the_cell_has_crossing_goals_and_a_decoupled_schedule() {
    let Some(dir) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    let scene = local_scene(&dir);
    let world = CollisionWorld::from_scene(&scene);
    let q0 = CollisionWorld::start_config(&scene);
    let goals = goals(&scene);
    let mut exact = ExactChecker::new(&world);
    let mut qg = q0.clone();
    for g in &goals {
        let off = world.robots[g.robot].offset;
        qg[off..off + 7].copy_from_slice(&g.goal);
    }
    assert!(exact.first_contact(&q0).is_none(), "start collides");
    assert!(exact.first_contact(&qg).is_none(), "goal collides");
    let mut crossing = false;
    let mut q = q0.clone();
    for i in 0..=200 {
        let t = i as f64 / 200.0;
        for (a, (&s, &e)) in q.iter_mut().zip(q0.iter().zip(&qg)) {
            *a = s + (e - s) * t;
        }
        crossing |= exact.first_contact(&q).is_some();
    }
    assert!(crossing, "the straight-line motions must cross");

    let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(30));
    let plan = decoupled(&world, &q0, &goals, &Default::default(), &mut term, 3).expect("plan");
    assert_ne!(plan.schedule.method, ScheduleMethod::Simultaneous);
    assert!(plan.schedule.duration < plan.schedule.robot_durations.iter().sum::<f64>());
    // Every instant of the schedule, all four arms at once, scene and robots.
    for (t, pos, _) in plan.schedule.sample(0.001) {
        let mut q = q0.clone();
        for (k, g) in goals.iter().enumerate() {
            let off = world.robots[g.robot].offset;
            q[off..off + 7].copy_from_slice(&pos[k]);
        }
        if let Some(c) = exact.first_contact(&q) {
            panic!("collision at t = {t:.3} s: {} with {}", c.a, c.b);
        }
    }

    // The composite baseline, re-checked every 0.002 rad along its path.
    let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(30));
    let r = composite(&world, &q0, &goals, &Default::default(), &mut term, 3).expect("composite");
    let space = JointSpace::all(&world, q0.clone()).expect("space");
    let wpath = space.path_to_world(&r.path);
    let mut mv = MotionValidator::new(&world, ExactChecker::new(&world), 0.002, 0.001);
    assert!(mv.is_path_valid(&wpath), "composite path collides");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn panda_four_over_http_joint_space_plans_then_a_schedule() {
    let Some(dir) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    let h = start("panda-four").await;
    let f = manyhands::benchmark::mbm_data::robot_files(&dir, "panda");
    let urdf = std::fs::read_to_string(&f.urdf).expect("urdf");
    let srdf = std::fs::read_to_string(&f.srdf).expect("srdf");
    let put = |path: String, body: Value| {
        let http = h.http.clone();
        let url = format!("{}{path}", h.base);
        async move {
            let r = http.put(url).json(&body).send().await.expect("PUT");
            let s = r.status();
            (s, r.json::<Value>().await.unwrap_or(Value::Null))
        }
    };
    let (s, v) = put(
        "/v1/robots/panda".into(),
        json!({"urdf": urdf, "srdf": srdf}),
    )
    .await;
    assert!(s.is_success(), "{s} {v}");
    let scene_json = serde_json::to_value(panda_four("panda")).expect("json");
    let (s, v) = put("/v1/scenes/panda_four".into(), scene_json.clone()).await;
    assert!(s.is_success(), "{s} {v}");

    let mut trajectories = Vec::new();
    for r in scene_json["robots"].as_array().expect("robots") {
        let name = r["name"].as_str().expect("name");
        let req = json!({"kind": "joint_space", "scene": "panda_four", "seed": 2,
            "robots": [{"name": name, "goal": r["configs"]["goal"]}]});
        let (s, v) = h.post("/v1/plans?wait=60", &req).await;
        assert_eq!(s, StatusCode::OK, "{v}");
        assert_eq!(v["state"], "succeeded", "{v}");
        trajectories.push(json!({"robot": name, "joints": v["result"]["joints"],
            "path": v["result"]["path"]}));
    }
    let req = json!({"kind": "schedule", "scene": "panda_four", "trajectories": trajectories,
        "sample_period": 0.001});
    let (s, v) = h.post("/v1/plans?wait=60", &req).await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    let sched = &v["result"]["schedule"];
    let sched = if sched.is_null() { &v["result"] } else { sched };
    assert_ne!(sched["method"], "simultaneous", "{sched}");

    // Re-check every sample with the exact checker, all arms at once, and velocity limits.
    let scene = local_scene(&dir);
    let world = CollisionWorld::from_scene(&scene);
    let mut q = CollisionWorld::start_config(&scene);
    let mut exact = ExactChecker::new(&world);
    let samples = sched["samples"].as_array().expect("samples");
    assert!(samples.len() > 100, "{}", samples.len());
    let order: Vec<usize> = sched["robots"]
        .as_array()
        .expect("robots")
        .iter()
        .map(|n| {
            world
                .robots
                .iter()
                .position(|p| Some(p.name.as_str()) == n.as_str())
                .expect("robot")
        })
        .collect();
    for s in samples {
        for (k, &r) in order.iter().enumerate() {
            let p = &world.robots[r];
            for v in 0..7 {
                q[p.offset + v] = s["positions"][k][v].as_f64().expect("position");
                let vel = s["velocities"][k][v].as_f64().expect("velocity");
                let lim = p.robot.var_limits(v).velocity;
                assert!(vel.abs() <= lim * (1.0 + 1e-6), "{vel} over {lim}");
            }
        }
        if let Some(c) = exact.first_contact(&q) {
            panic!(
                "collision at t = {}: {} with {}",
                s["time_from_start"], c.a, c.b
            );
        }
    }
}

/// VAMP-MR's three public cells over the MotionBenchMaker Panda (NEEDS THE DATA, skipped
/// without it): each builds with its arms on the sphere model (rods included), its start free
/// under the exact checker; a seeded crossing task has free starts and goals (exact checker,
/// all arms at once) and straight motions that collide when run together; the same seed gives
/// the same task.
#[test]
fn vamp_mr_cells_and_crossing_tasks() {
    use manyhands::benchmark::multi_arm_cells::{
        crossing_task, vamp_mr, CrossingSettings, VampMrCell, ROD_LINK,
    };
    use manyhands::collision::AutoChecker;
    let Some(dir) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    for cell in VampMrCell::ALL {
        let c = vamp_mr(cell, &dir).expect("cell");
        let scene = &c.scene;
        let arms = if cell == VampMrCell::PandaTwoRod {
            2
        } else {
            4
        };
        assert_eq!(scene.robots.len(), arms, "{}", cell.name());
        let rod = scene.robots[0].robot.link(ROD_LINK).is_some();
        assert_eq!(rod, cell != VampMrCell::PandaFour, "{}", cell.name());
        let world = CollisionWorld::from_scene(scene);
        assert_eq!(AutoChecker::new(&world, 0.0).kind(), "spheres");
        let mut exact = ExactChecker::new(&world);
        let q0 = CollisionWorld::start_config(scene);
        assert!(exact.first_contact(&q0).is_none(), "{}", cell.name());

        // The sphere checker (several arms at once, the robot–robot tests) is conservative
        // against the exact one on random configurations of every arm.
        let mut spheres = AutoChecker::new(&world, 0.0);
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
        let (mut free, mut hits) = (0, 0);
        for _ in 0..1500 {
            let mut q = Vec::new();
            for r in &world.robots {
                let mut c = r.robot.zero_config();
                let vars: Vec<usize> = (0..r.robot.dof()).collect();
                r.robot.sample_vars(&vars, &mut c, &mut rng);
                q.extend(c);
            }
            let sphere_free = spheres.is_free(&q);
            if sphere_free {
                free += 1;
                if let Some(c) = exact.first_contact(&q) {
                    panic!("{}: spheres free, exact {} with {}", cell.name(), c.a, c.b);
                }
            } else {
                hits += 1;
            }
        }
        assert!(
            free > 20 && hits > 20,
            "{}: {free} free, {hits} hit",
            cell.name()
        );
        let settings = CrossingSettings::default();
        let task = crossing_task(scene, 7, &settings).expect("task");
        assert_eq!(task, crossing_task(scene, 7, &settings).expect("task"));
        assert!(!task.conflicts.is_empty());
        let (qs, qg) = (task.start_config(), task.goal_config());
        if let Some(c) = exact
            .first_contact(&qs)
            .or_else(|| exact.first_contact(&qg))
        {
            panic!(
                "{}: start or goal collides: {} with {}",
                cell.name(),
                c.a,
                c.b
            );
        }
        // The straight motions, all arms together, meet (exact checker, between arms).
        let mut between = ExactChecker::new(&world.between_robots());
        let mut q = qs.clone();
        let crossing = (1..400).any(|k| {
            let t = k as f64 / 400.0;
            for (x, (&s, &g)) in q.iter_mut().zip(qs.iter().zip(&qg)) {
                *x = s + (g - s) * t;
            }
            !between.is_free(&q)
        });
        assert!(
            crossing,
            "{}: the straight motions do not meet",
            cell.name()
        );
    }
}
