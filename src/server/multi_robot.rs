//! Job kinds `multi_robot` (Multi-Robot-RRT, 002 Alg. 3, with phase-space scheduling, 002 §V)
//! and `schedule` (the phase-space scheduler alone, for trajectories planned anywhere): request
//! types, validation against the catalog and the work run on a planner thread.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};

use super::catalog::Catalog;
use super::error::{ApiError, ApiResult};
use super::kinds::{
    check_hand, check_object, ensure_grid, grasp_settings, plan_failure, time_limit,
    timing_failure, timing_options, JobContext, JobFailure, JobWork, Prepared,
};
use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::grasp::WrenchSpaceSettings;
use crate::model::Scene;
use crate::planning::planners::multi_robot_rrt::{
    multi_robot_rrt, MultiRobotEvent, MultiRobotProblem, MultiRobotSettings, Rejection, MAX_ROBOTS,
};
use crate::planning::planners::phase_space::{PhaseSpace, PhaseSpaceSettings, RobotTrajectory};
use crate::planning::PlanError;
use crate::reachability::{GridCache, GridRecipe};

pub use manyhands_api::{MultiRobotRequest, ScheduleRequest, ScheduleTrajectory};

/// Most waypoints of one trajectory of a `schedule` request.
pub const MAX_WAYPOINTS: usize = 10_000;

fn check_sample_period(p: Option<f64>) -> ApiResult<Option<f64>> {
    match p {
        None => Ok(None),
        Some(p) if p.is_finite() && (0.001..=10.0).contains(&p) => Ok(Some(p)),
        Some(p) => Err(ApiError::invalid(
            "sample_period",
            format!("{p} is not within [0.001, 10] seconds"),
        )),
    }
}

// ---------------------------------------------------------------- multi_robot

struct MultiRobotWork {
    scene: Arc<Scene>,
    names: Vec<String>,
    left: String,
    right: String,
    object: String,
    grids: Arc<GridCache>,
    settings: MultiRobotSettings,
    seed: u64,
    sample_period: Option<f64>,
    trajectory_period: f64,
}

pub fn prepare_multi_robot(
    r: &MultiRobotRequest,
    catalog: &Catalog,
    max: f64,
) -> ApiResult<Prepared> {
    let settings = crate::server::api::GraspPlanSettings {
        time_limit: r.time_limit,
        seed: r.seed,
        p_ik: r.p_ik,
        ik_tries: r.ik_tries,
        simplify: r.simplify,
        sample_period: r.sample_period,
        velocity_scaling: r.velocity_scaling,
        acceleration_scaling: r.acceleration_scaling,
    };
    let (limit, seed, planner, ik) = grasp_settings(&settings, 0.03, max)?;
    let timing = timing_options(r.sample_period, r.velocity_scaling, r.acceleration_scaling)?;
    let entry = catalog.scene(&r.scene, "scene")?;
    let scene = entry.scene.clone();
    let names: Vec<String> = match &r.robots {
        Some(n) => n.clone(),
        None => scene.robots.iter().map(|p| p.name.clone()).collect(),
    };
    if names.is_empty() || names.len() > MAX_ROBOTS {
        return Err(ApiError::invalid(
            "robots",
            format!("1 to {MAX_ROBOTS} robots, got {}", names.len()),
        ));
    }
    let left = r.left.clone().unwrap_or_else(|| "torso_left_arm".into());
    let right = r.right.clone().unwrap_or_else(|| "torso_right_arm".into());
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(ApiError::invalid(
                format!("robots[{i}]"),
                format!("robot '{n}' is given twice"),
            ));
        }
        check_hand(&scene, n, &left, "left.").map_err(|e| e.at(format!("robots[{i}]")))?;
        check_hand(&scene, n, &right, "right.").map_err(|e| e.at(format!("robots[{i}]")))?;
    }
    check_object(&scene, &r.object)?;
    let s_min = r.s_min.unwrap_or(0.0);
    if !(s_min.is_finite() && s_min >= 0.0) {
        return Err(ApiError::invalid("s_min", format!("{s_min} is not ≥ 0")));
    }
    let wrench = WrenchSpaceSettings {
        mu: r.mu.unwrap_or(0.5),
        cone_edges: r.cone_edges.unwrap_or(8),
        lambda: r.lambda,
        soft_finger: None,
    };
    if let Err(e) = wrench.validate() {
        return Err(ApiError::invalid(e.field().to_string(), e.to_string()));
    }
    let max_solutions = r.max_solutions.unwrap_or(32);
    if !(1..=256).contains(&max_solutions) {
        return Err(ApiError::invalid(
            "max_solutions",
            format!("{max_solutions} is not within [1, 256]"),
        ));
    }
    let sample_period = check_sample_period(r.sample_period)?;
    Ok(Prepared {
        work: Box::new(MultiRobotWork {
            scene,
            names,
            left,
            right,
            object: r.object.clone(),
            grids: catalog.grids(),
            settings: MultiRobotSettings {
                s_min,
                wrench,
                planner,
                ik,
                max_solutions,
                deterministic: r.deterministic.unwrap_or(false),
                phase: PhaseSpaceSettings {
                    velocity_scaling: timing.velocity_scaling,
                    acceleration_scaling: timing.acceleration_scaling,
                    ..MultiRobotSettings::default().phase
                },
                ..MultiRobotSettings::default()
            },
            seed,
            sample_period,
            trajectory_period: timing.sample_period,
        }),
        time_limit: limit,
    })
}

impl JobWork for MultiRobotWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        // The grids first, each within the job's time limit and stop flag (built on first use
        // on a build thread, see `super::builds`); the problem then finds them in memory.
        for n in &w.names {
            let model =
                w.scene.robot(n).map(|p| p.robot.clone()).ok_or_else(|| {
                    plan_failure(PlanError::InvalidInput(format!("no robot '{n}'")))
                })?;
            for g in [&w.left, &w.right] {
                ensure_grid(ctx, &w.grids, &model, g, GridRecipe::default())?;
            }
        }
        let p = MultiRobotProblem::with_grids(
            &w.scene,
            &w.names,
            &w.left,
            &w.right,
            &w.object,
            &w.grids,
            GridRecipe::default(),
            Default::default(),
        )
        .map_err(plan_failure)?;
        if ctx.stopped() || ctx.past_limit() {
            let reason = if ctx.stopped() {
                crate::planning::StopReason::Requested
            } else {
                crate::planning::StopReason::TimeLimit
            };
            return Err(plan_failure(PlanError::stopped(reason, Default::default())));
        }
        ctx.progress(json!({"phase": "planning", "planner": "multi_robot_rrt"}));
        let mut term = ctx.termination();
        // Snapshots are cumulative: the job keeps the latest (at most one per 50 ms).
        let mut solutions: HashMap<String, u64> = HashMap::new();
        let mut rejected = [0u64; 3];
        let (mut checked, mut best) = (0u64, 0.0f64);
        let mut phase = "planning";
        let plan = {
            let mut progress = |e: MultiRobotEvent<'_>| {
                match e {
                    MultiRobotEvent::Solution { robot, count } => {
                        solutions.insert(robot.to_string(), count);
                    }
                    MultiRobotEvent::Combination {
                        checked: c,
                        rejected: r,
                        best: b,
                        ..
                    } => {
                        if let Some(r) = r {
                            rejected[r as usize] += 1;
                        }
                        checked = c;
                        best = b;
                    }
                    MultiRobotEvent::Scheduling => phase = "phase space",
                }
                ctx.progress(json!({
                    "phase": phase,
                    "planner": if phase == "planning" { "multi_robot_rrt" } else { "phase_space_rrt" },
                    "solutions": solutions,
                    "combinations_checked": checked,
                    "rejected": {"collision": rejected[Rejection::Collision as usize],
                                 "score": rejected[Rejection::Score as usize],
                                 "deadlock": rejected[Rejection::Deadlock as usize]},
                    "best_score": best,
                }));
            };
            multi_robot_rrt(&p, &w.settings, &mut term, w.seed, &mut progress)
        }
        .map_err(plan_failure)?;
        plan.to_json(&p, w.sample_period, w.trajectory_period)
            .map_err(timing_failure)
    }
}

// ---------------------------------------------------------------- schedule

struct ScheduleWork {
    world: CollisionWorld,
    world_q: Vec<f64>,
    trajectories: Vec<RobotTrajectory>,
    names: Vec<String>,
    variables: Vec<Vec<String>>,
    settings: PhaseSpaceSettings,
    seed: u64,
    sample_period: Option<f64>,
    trajectory_period: f64,
}

/// The trajectories of a `schedule` request resolved against its scene, each checked free in
/// the scene on its own (joint limits, states and segments), or a 422 naming the robot and the
/// waypoint.
fn resolve_trajectories(
    scene: &Scene,
    world: &CollisionWorld,
    world_q: &[f64],
    given: &[ScheduleTrajectory],
) -> ApiResult<(Vec<RobotTrajectory>, Vec<String>)> {
    if given.is_empty() || given.len() > MAX_ROBOTS {
        return Err(ApiError::invalid(
            "trajectories",
            format!("1 to {MAX_ROBOTS} trajectories, got {}", given.len()),
        ));
    }
    let mut out = Vec::with_capacity(given.len());
    let mut names = Vec::new();
    for (i, t) in given.iter().enumerate() {
        let f = |s: &str| format!("trajectories[{i}].{s}");
        let r = world
            .robots
            .iter()
            .position(|p| p.name == t.robot)
            .ok_or_else(|| {
                ApiError::invalid(
                    f("robot"),
                    format!("scene '{}' has no robot '{}'", scene.name, t.robot),
                )
            })?;
        if names.contains(&t.robot) {
            return Err(ApiError::invalid(
                f("robot"),
                format!("robot '{}' has two trajectories", t.robot),
            ));
        }
        let placed = &world.robots[r];
        let model = &placed.robot;
        let dof = model.dof();
        let vars: Vec<usize> = match &t.joints {
            None => (0..dof).collect(),
            Some(j) => j
                .iter()
                .enumerate()
                .map(|(k, name)| {
                    let bare = name.strip_prefix(&format!("{}/", t.robot)).unwrap_or(name);
                    (0..dof)
                        .find(|&v| model.var_name(v) == bare)
                        .ok_or_else(|| {
                            ApiError::invalid(
                                f(&format!("joints[{k}]")),
                                format!("robot '{}' has no variable '{name}'", t.robot),
                            )
                        })
                })
                .collect::<ApiResult<_>>()?,
        };
        if t.path.is_empty() || t.path.len() > MAX_WAYPOINTS {
            return Err(ApiError::invalid(
                f("path"),
                format!("1 to {MAX_WAYPOINTS} waypoints, got {}", t.path.len()),
            ));
        }
        let start = world.robot_config(r, world_q).to_vec();
        let mut waypoints = Vec::with_capacity(t.path.len());
        for (w, row) in t.path.iter().enumerate() {
            if row.len() != vars.len() {
                return Err(ApiError::invalid(
                    f(&format!("path[{w}]")),
                    format!("{} values for {} joints", row.len(), vars.len()),
                ));
            }
            let mut q = start.clone();
            for (k, (&v, &x)) in vars.iter().zip(row).enumerate() {
                let l = model.var_limits(v);
                if !x.is_finite() || (l.bounded && !(l.lower - 1e-9..=l.upper + 1e-9).contains(&x))
                {
                    return Err(ApiError::invalid(
                        f(&format!("path[{w}][{k}]")),
                        format!(
                            "{} = {x} outside [{}, {}]",
                            model.var_name(v),
                            l.lower,
                            l.upper
                        ),
                    ));
                }
                q[v] = x.clamp(l.lower, l.upper);
            }
            waypoints.push(q);
        }
        // Free in the scene on its own: this robot alone with the fixed bodies.
        let Some(alone) = world.subset(&[r]) else {
            return Err(ApiError::invalid(f("robot"), "unknown robot"));
        };
        let mut checker = FastChecker::new(&alone);
        for (w, q) in waypoints.iter().enumerate() {
            if let Some(c) = checker.first_contact(q) {
                return Err(ApiError::invalid(
                    f(&format!("path[{w}]")),
                    format!(
                        "robot '{}' collides at waypoint {w}: {} with {}",
                        t.robot, c.a, c.b
                    ),
                ));
            }
        }
        for (w, pair) in waypoints.windows(2).enumerate() {
            if !checker.motion_certified(&pair[0], &pair[1]) {
                return Err(ApiError::invalid(
                    f(&format!("path[{}]", w + 1)),
                    format!(
                        "robot '{}': the motion from waypoint {w} to {} is not collision-free",
                        t.robot,
                        w + 1
                    ),
                ));
            }
        }
        // Acceleration limits: the request's by joint, else its max_acceleration, else the
        // robot's (joint-limits file or default), so the schedule runs rest to rest.
        if let Some(a) = t.max_acceleration {
            if !(a.is_finite() && a > 0.0) {
                return Err(ApiError::invalid(f("max_acceleration"), "must be > 0"));
            }
        }
        let map = t.accelerations.clone().unwrap_or_default();
        for (name, &a) in &map {
            let bare = name.strip_prefix(&format!("{}/", t.robot)).unwrap_or(name);
            if !(0..dof).any(|v| model.var_name(v) == bare) {
                return Err(ApiError::invalid(
                    f(&format!("accelerations.{name}")),
                    format!("robot '{}' has no variable '{name}'", t.robot),
                ));
            }
            if !(a.is_finite() && a > 0.0) {
                return Err(ApiError::invalid(
                    f(&format!("accelerations.{name}")),
                    "must be > 0",
                ));
            }
        }
        let accelerations = Some(
            (0..dof)
                .map(|v| {
                    let name = model.var_name(v);
                    map.get(name)
                        .or_else(|| map.get(&format!("{}/{name}", t.robot)))
                        .copied()
                        .or(t.max_acceleration)
                        .unwrap_or_else(|| model.acceleration_limit(v))
                })
                .collect(),
        );
        names.push(t.robot.clone());
        out.push(RobotTrajectory {
            robot: r,
            waypoints,
            accelerations,
        });
    }
    Ok((out, names))
}

pub fn prepare_schedule(r: &ScheduleRequest, catalog: &Catalog, max: f64) -> ApiResult<Prepared> {
    let entry = catalog.scene(&r.scene, "scene")?;
    schedule_work(r, entry.scene.clone(), max)
}

/// The work of a `schedule` request on `scene` (already resolved from `r.scene`).
fn schedule_work(r: &ScheduleRequest, scene: Arc<Scene>, max: f64) -> ApiResult<Prepared> {
    let limit = time_limit(r.time_limit, max)?;
    let extend = r.extend.unwrap_or(0.1);
    if !(extend.is_finite() && (0.001..=1.0).contains(&extend)) {
        return Err(ApiError::invalid(
            "extend",
            format!("{extend} is not within [0.001, 1]"),
        ));
    }
    let sample_period = check_sample_period(r.sample_period)?;
    let timing = timing_options(r.sample_period, r.velocity_scaling, r.acceleration_scaling)?;
    let world = CollisionWorld::from_scene(&scene);
    let world_q = CollisionWorld::start_config(&scene);
    let (trajectories, names) = resolve_trajectories(&scene, &world, &world_q, &r.trajectories)?;
    let variables = trajectories
        .iter()
        .map(|t| {
            let m = &world.robots[t.robot].robot;
            (0..m.dof()).map(|v| m.var_name(v).to_string()).collect()
        })
        .collect();
    Ok(Prepared {
        work: Box::new(ScheduleWork {
            world,
            world_q,
            trajectories,
            names,
            variables,
            settings: PhaseSpaceSettings {
                extend,
                sequential_fallback: r.sequential_fallback.unwrap_or(true),
                velocity_scaling: timing.velocity_scaling,
                acceleration_scaling: timing.acceleration_scaling,
                ..PhaseSpaceSettings::default()
            },
            seed: r.seed.unwrap_or(1),
            sample_period,
            trajectory_period: timing.sample_period,
        }),
        time_limit: limit,
    })
}

/// Runs a schedule request to its JSON answer (the job kind `schedule` and the CLI
/// `manyhands schedule`).
fn run_schedule(
    w: &ScheduleWork,
    term: &mut crate::planning::Termination,
) -> Result<Value, JobFailure> {
    let mut ps = PhaseSpace::new(&w.world, &w.world_q, &w.trajectories).map_err(plan_failure)?;
    let s = ps.plan(&w.settings, term, w.seed).map_err(plan_failure)?;
    let mut v = s.to_json(&w.names, w.sample_period);
    v["variables"] = json!(w.variables);
    // Every robot's trajectory on the common clock (no grasps in a bare schedule).
    let trajectories: serde_json::Map<String, Value> = w
        .names
        .iter()
        .cloned()
        .zip(
            s.trajectories(&w.variables, w.trajectory_period, Vec::new())
                .map_err(timing_failure)?
                .into_iter()
                .map(|t| json!(t)),
        )
        .collect();
    v["trajectories"] = Value::Object(trajectories);
    Ok(v)
}

impl JobWork for ScheduleWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        ctx.progress(
            json!({"phase": "phase space", "planner": "phase_space_rrt", "robots": self.names}),
        );
        let mut term = ctx.termination();
        run_schedule(&self, &mut term)
    }
}

/// `manyhands schedule`: the `schedule` job's JSON request in, its answer out, without a
/// server. Errors carry the field and reason as the HTTP 422 does.
pub fn schedule_locally(
    req: &ScheduleRequest,
    scene: Arc<Scene>,
    max_seconds: f64,
) -> Result<Value, String> {
    let prepared = schedule_work(req, scene, max_seconds).map_err(|e| e.to_string())?;
    let limit = Duration::from_secs_f64(prepared.time_limit);
    let mut ctx = JobContext::new(
        Arc::new(std::sync::atomic::AtomicBool::new(false)),
        limit,
        Box::new(|_| {}),
    );
    prepared
        .work
        .run(&mut ctx)
        .map_err(|f| format!("{}: {}", f.code, f.message))
}
