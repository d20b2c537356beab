//! Every motion the grasp planners return is collision-free as a continuous motion (issue #27):
//! the plans of `manyhands plan reach / regrasp / kitchen / bimanual` (IK-RRT and J+-RRT reach,
//! dual-arm IK-RRT and J+-RRT re-grasp, the two-robot hand-off, the kitchen task, Bimanual IK-RRT;
//! the CLI's settings and grids; seeds 1–20, which include the seeds the issue lists) are
//! re-checked phase by phase in the world each phase was planned in (held objects attached) by
//! the exact parry checker at steps of at most 0.002 rad and 1 mm, and every segment is
//! certified again by a fresh fast checker of that world. 0 penetrations allowed.

mod common;
use common::scene;

use std::sync::Arc;
use std::time::Duration;

use rayon::prelude::*;

use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker, FastChecker};
use manyhands::kinematics::randomized::RandomizedIkSettings;
use manyhands::model::JointKind;
use manyhands::planning::planners::bimanual_ik_rrt::{BimanualProblem, BimanualSettings};
use manyhands::planning::problems::grasping::arm_grid;
use manyhands::planning::tasks::task::{
    bimanual_task, kitchen_task, reach_task, regrasp_task, GraspAlgorithm, KitchenTask,
    RegraspTask, TaskPlan,
};
use manyhands::planning::{IkRrtSettings, Termination};
use manyhands::reachability::{GridCache, GridRecipe};

/// The CLI's planner settings (`plan`: p_IK 0.1, bimanual 0.03; 50 IK tries per query).
fn settings(p_ik: f64) -> (IkRrtSettings, RandomizedIkSettings) {
    (
        IkRrtSettings {
            p_ik,
            ..IkRrtSettings::default()
        },
        RandomizedIkSettings {
            max_tries: 50,
            ..RandomizedIkSettings::default()
        },
    )
}

fn term() -> Termination {
    Termination::new().with_time_limit(Duration::from_secs(30))
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Job {
    Reach(&'static str, GraspAlgorithm),
    Regrasp(GraspAlgorithm),
    HandOff,
    Kitchen,
    Bimanual,
}

/// Dense states of `a → b`: at most 0.002 rad per revolute and 1 mm per prismatic variable.
fn steps(world: &CollisionWorld, a: &[f64], b: &[f64]) -> usize {
    let mut n = 1.0f64;
    let mut v = 0;
    for p in &world.robots {
        for k in 0..p.robot.dof() {
            let step = match p.robot.joints[p.robot.vars[k]].kind {
                JointKind::Prismatic => 0.001,
                _ => 0.002,
            };
            n = n.max(((b[v] - a[v]).abs() / step).ceil());
            v += 1;
        }
    }
    n as usize
}

/// Re-checks every phase of `plan`; returns (segments, dense states checked) or the failures.
fn recheck(label: &str, plan: &TaskPlan) -> Result<(usize, usize), Vec<String>> {
    let mut bad = Vec::new();
    let (mut segments, mut states) = (0, 0);
    for ph in &plan.phases {
        let world = &ph.world;
        let mut exact = ExactChecker::new(world);
        let mut fast = FastChecker::new(world);
        if !exact.is_free(&plan.waypoints[ph.first]) {
            bad.push(format!("{label} {}: first state collides", ph.name));
        }
        for k in ph.first..ph.last {
            let (a, b) = (&plan.waypoints[k], &plan.waypoints[k + 1]);
            segments += 1;
            if !fast.motion_certified(a, b) {
                bad.push(format!("{label} {}: segment {k} not certified", ph.name));
            }
            let n = steps(world, a, b);
            let mut q = a.clone();
            for s in 1..=n {
                let t = s as f64 / n as f64;
                for i in 0..q.len() {
                    q[i] = a[i] + (b[i] - a[i]) * t;
                }
                states += 1;
                if let Some(c) = exact.first_contact(&q) {
                    bad.push(format!(
                        "{label} {}: segment {k} state {s}/{n}: {} collides with {}",
                        ph.name, c.a, c.b
                    ));
                    break;
                }
            }
        }
        // What the phase reports: its search certified every segment it checked this way.
        let c = ph.stats.certification.unwrap_or_default();
        if c.motions == 0 || c.max_inflation <= 0.0 {
            bad.push(format!("{label} {}: no certification reported", ph.name));
        }
    }
    if bad.is_empty() {
        Ok((segments, states))
    } else {
        Err(bad)
    }
}

#[test]
fn grasp_plans_are_free_under_a_dense_exact_recheck() {
    let cache = GridCache::new(Some(common::tmp::test_root().join("test-data/reach")));
    let kitchen = scene("kitchen");
    let obstacle = scene("obstacle");
    let handoff = scene("handoff");
    let world = CollisionWorld::from_scene(&kitchen);
    let right = arm_grid(&cache, &world, "armar", "torso_right_arm").expect("grid");
    let left = arm_grid(&cache, &world, "armar", "torso_left_arm").expect("grid");
    let hw = CollisionWorld::from_scene(&handoff);
    let receiver = arm_grid(&cache, &hw, "armar_b", "torso_left_arm").expect("grid");
    let model = kitchen.robots[0].robot.clone();
    let gl: Arc<_> = cache
        .get(&model, "torso_left_arm", GridRecipe::default())
        .expect("platform grid");
    let gr: Arc<_> = cache
        .get(&model, "torso_right_arm", GridRecipe::default())
        .expect("platform grid");
    let jobs = [
        Job::Reach("kitchen", GraspAlgorithm::IkRrt),
        Job::Reach("obstacle", GraspAlgorithm::IkRrt),
        Job::Reach("kitchen", GraspAlgorithm::JPlusRrt),
        Job::Regrasp(GraspAlgorithm::IkRrt),
        Job::Regrasp(GraspAlgorithm::JPlusRrt),
        Job::HandOff,
        Job::Kitchen,
        Job::Bimanual,
    ];
    let runs: Vec<(Job, u64)> = jobs
        .iter()
        .flat_map(|&j| (1..=20).map(move |s| (j, s)))
        .collect();
    let results: Vec<Result<(usize, usize), Vec<String>>> = runs
        .par_iter()
        .map(|&(job, seed)| {
            let label = format!("{job:?} seed {seed}");
            let plan = match job {
                Job::Reach(name, alg) => {
                    let s = if name == "kitchen" {
                        &kitchen
                    } else {
                        &obstacle
                    };
                    let (p, ik) = settings(0.1);
                    let grid = (alg == GraspAlgorithm::IkRrt)
                        .then(|| right.clone())
                        .flatten();
                    reach_task(
                        s,
                        "armar",
                        "torso_right_arm",
                        "wok",
                        grid,
                        alg,
                        p,
                        ik,
                        &mut term(),
                        seed,
                    )
                }
                Job::Regrasp(_) | Job::HandOff => {
                    let (p, ik) = settings(0.1);
                    let algorithm = match job {
                        Job::Regrasp(a) => a,
                        _ => GraspAlgorithm::IkRrt,
                    };
                    let (s, giver, receiver, grid) = if job == Job::HandOff {
                        (&handoff, "armar_a", "armar_b", receiver.clone())
                    } else {
                        let g = (algorithm == GraspAlgorithm::IkRrt)
                            .then(|| left.clone())
                            .flatten();
                        (&kitchen, "armar", "armar", g)
                    };
                    let task = RegraspTask {
                        giver: (giver.into(), "torso_right_arm".into()),
                        receiver: (receiver.into(), "torso_left_arm".into()),
                        object: "wok".into(),
                        held: None,
                        grid,
                        algorithm,
                        planner: p,
                        ik,
                    };
                    regrasp_task(s, &task, &mut term(), seed)
                }
                Job::Kitchen => {
                    let (p, ik) = settings(0.1);
                    let task = KitchenTask {
                        planner: p,
                        ik,
                        grids: (right.clone(), left.clone()),
                        ..KitchenTask::armar_wok()
                    };
                    kitchen_task(&kitchen, &task, &mut term(), seed)
                }
                _ => {
                    let (p, ik) = settings(0.03);
                    let q0 = CollisionWorld::start_config(&kitchen);
                    let bp = BimanualProblem::new(
                        &kitchen,
                        &world,
                        &q0,
                        "armar",
                        ("torso_left_arm", "torso_right_arm"),
                        "table",
                        (&gl, &gr),
                        BimanualSettings::default(),
                    )
                    .expect("bimanual problem");
                    bimanual_task(&bp, p, ik, &mut term(), seed)
                }
            };
            match plan {
                Ok(plan) => recheck(&label, &plan),
                Err(e) => Err(vec![format!("{label}: not solved: {e}")]),
            }
        })
        .collect();
    let (mut segments, mut states) = (0, 0);
    let mut failures = Vec::new();
    for r in results {
        match r {
            Ok((s, n)) => {
                segments += s;
                states += n;
            }
            Err(f) => failures.extend(f),
        }
    }
    eprintln!(
        "{} plans, {segments} segments, {states} dense states re-checked",
        runs.len()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
