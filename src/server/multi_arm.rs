//! Job kind `multi_arm`: N independent arms of a scene planned together
//! ([`crate::planning::planners::multi_arm`]): request validation against the catalog (every error a 422
//! naming the field), the work run on a planner thread, and the same without a server for the
//! CLI (`manyhands plan multi-arm`).

use std::sync::Arc;
use std::time::Duration;

use serde_json::{json, Value};

use super::catalog::Catalog;
use super::error::{ApiError, ApiResult};
use super::kinds::{
    plan_failure, time_limit, timing_failure, timing_options, JobContext, JobFailure, JobWork,
    Prepared,
};
use super::queries::{apply_config, placement_base, pose_in};
use crate::collision::CollisionWorld;
use crate::model::Scene;
use crate::planning::planners::multi_arm::{
    plan_multi_arm, pose_goal, Arm, Methods, MultiArmProblem, MultiArmSettings, MAX_ARMS,
    MAX_VARIABLES,
};

pub use manyhands_api::{MultiArmRequest, MultiArmRobot};

/// Most shortcut tries a request may ask for.
pub const MAX_SHORTCUT_ITERATIONS: u64 = 10_000;

/// IK tries for a `goal_pose`.
const POSE_TRIES: usize = 20;

struct MultiArmWork {
    problem: MultiArmProblem,
    settings: MultiArmSettings,
    seed: u64,
    arm_names: Vec<String>,
    joint_names: Vec<String>,
    period: f64,
}

fn methods(m: Option<&str>) -> ApiResult<Methods> {
    let only = |d, p, c| Methods {
        decoupled: d,
        prioritized: p,
        composite: c,
    };
    match m {
        None | Some("auto") => Ok(Methods::default()),
        Some("decoupled") => Ok(only(true, false, false)),
        Some("prioritized") => Ok(only(false, true, false)),
        Some("composite") => Ok(only(false, false, true)),
        Some(other) => Err(ApiError::invalid(
            "method",
            format!("'{other}' is not one of auto, decoupled, prioritized, composite"),
        )),
    }
}

/// The problem of a request on `scene`: every robot's start and goal resolved (a `goal_pose`
/// by IK), or a 422 naming the field.
fn problem(r: &MultiArmRequest, scene: &Scene, seed: u64) -> ApiResult<MultiArmProblem> {
    if r.robots.is_empty() || r.robots.len() > MAX_ARMS {
        return Err(ApiError::invalid(
            "robots",
            format!("1 to {MAX_ARMS} robots, got {}", r.robots.len()),
        ));
    }
    let world = CollisionWorld::from_scene(scene);
    let mut world_q = CollisionWorld::start_config(scene);
    let mut resolved = Vec::with_capacity(r.robots.len());
    let mut total = 0;
    // Starts first: a pose goal is solved with every robot at its start.
    for (i, ar) in r.robots.iter().enumerate() {
        let field = format!("robots[{i}]");
        let ri = scene
            .robots
            .iter()
            .position(|p| p.name == ar.name)
            .ok_or_else(|| {
                ApiError::invalid(
                    format!("{field}.name"),
                    format!("scene '{}' has no robot '{}'", scene.name, ar.name),
                )
            })?;
        if r.robots[..i].iter().any(|o| o.name == ar.name) {
            return Err(ApiError::invalid(
                format!("{field}.name"),
                format!("robot '{}' listed twice", ar.name),
            ));
        }
        let p = &scene.robots[ri];
        let robot = &p.robot;
        let vars: Vec<usize> = match &ar.group {
            Some(g) => robot
                .group(g)
                .map(|g| g.vars.clone())
                .filter(|v| !v.is_empty())
                .ok_or_else(|| {
                    ApiError::invalid(
                        format!("{field}.group"),
                        format!("robot '{}' has no group '{g}' with joints", ar.name),
                    )
                })?,
            None => (0..robot.dof()).collect(),
        };
        total += vars.len();
        if total > MAX_VARIABLES {
            return Err(ApiError::invalid(
                format!("{field}.group"),
                format!("the arms move {total} joints, at most {MAX_VARIABLES}"),
            ));
        }
        let base = placement_base(p, None, &field)?;
        let start = apply_config(robot, &base, &ar.start, &format!("{field}.start"))?;
        let off = world.robots[ri].offset;
        world_q[off..off + start.len()].copy_from_slice(&start);
        resolved.push((ri, vars, start));
    }
    let mut arms = Vec::with_capacity(resolved.len());
    for (i, (ar, (ri, vars, start))) in r.robots.iter().zip(resolved).enumerate() {
        let field = format!("robots[{i}]");
        let robot = &scene.robots[ri].robot;
        let goal = match (&ar.goal, &ar.goal_pose) {
            (Some(map), None) => {
                for name in map.keys() {
                    if let Some(v) = robot.var(name) {
                        if !vars.contains(&v) {
                            return Err(ApiError::invalid(
                                format!("{field}.goal.{name}"),
                                format!(
                                    "joint '{name}' is not in the moved group; only the \
                                     group's joints move"
                                ),
                            ));
                        }
                    }
                }
                let q = apply_config(robot, &start, map, &format!("{field}.goal"))?;
                vars.iter().map(|&v| q[v]).collect()
            }
            (None, Some(pose)) => {
                let f = format!("{field}.goal_pose");
                let target = pose_in(pose, &f)?;
                let group = ar.group.as_deref().ok_or_else(|| {
                    ApiError::invalid(
                        format!("{field}.group"),
                        "a goal_pose needs a chain group (its tip link is the TCP)",
                    )
                })?;
                let g = pose_goal(
                    &world,
                    &world_q,
                    ri,
                    group,
                    &target,
                    POSE_TRIES,
                    seed.wrapping_add(i as u64),
                )
                .map_err(|e| ApiError::invalid(&f, e.to_string()))?;
                if g.len() != vars.len() {
                    return Err(ApiError::invalid(
                        format!("{field}.group"),
                        "a goal_pose needs a chain group (its tip link is the TCP)",
                    ));
                }
                g
            }
            (Some(_), Some(_)) => {
                return Err(ApiError::invalid(
                    format!("{field}.goal_pose"),
                    "give either goal or goal_pose, not both",
                ))
            }
            (None, None) => {
                return Err(ApiError::invalid(
                    format!("{field}.goal"),
                    "missing: give goal (joint values) or goal_pose (TCP pose)",
                ))
            }
        };
        arms.push(Arm {
            robot: ri,
            vars,
            goal,
        });
    }
    MultiArmProblem::new(world, world_q, arms)
        .map_err(|e| ApiError::invalid("robots", e.to_string()))
}

fn prepare(r: &MultiArmRequest, scene: &Scene, max: f64) -> ApiResult<Prepared> {
    let limit = time_limit(r.time_limit, max)?;
    let methods = methods(r.method.as_deref())?;
    let shortcut_iterations = r.shortcut_iterations.unwrap_or(200);
    if shortcut_iterations > MAX_SHORTCUT_ITERATIONS {
        return Err(ApiError::invalid(
            "shortcut_iterations",
            format!("{shortcut_iterations} is not within [0, {MAX_SHORTCUT_ITERATIONS}]"),
        ));
    }
    let timing = timing_options(r.sample_period, r.velocity_scaling, r.acceleration_scaling)?;
    let seed = r.seed.unwrap_or(1);
    let problem = problem(r, scene, seed)?;
    let arm_names: Vec<String> = r.robots.iter().map(|a| a.name.clone()).collect();
    let joint_names: Vec<String> = problem
        .arms
        .iter()
        .flat_map(|a| {
            let p = &problem.world.robots[a.robot];
            a.vars
                .iter()
                .map(|&v| format!("{}/{}", p.name, p.robot.var_name(v)))
                .collect::<Vec<_>>()
        })
        .collect();
    Ok(Prepared {
        work: Box::new(MultiArmWork {
            problem,
            settings: MultiArmSettings {
                methods,
                shortcut_iterations,
                velocity_scaling: timing.velocity_scaling,
                acceleration_scaling: timing.acceleration_scaling,
                ..MultiArmSettings::default()
            },
            seed,
            arm_names,
            joint_names,
            period: timing.sample_period,
        }),
        time_limit: limit,
    })
}

/// Validates a `multi_arm` request against the catalog and resolves it into work.
pub fn prepare_multi_arm(r: &MultiArmRequest, catalog: &Catalog, max: f64) -> ApiResult<Prepared> {
    let entry = catalog.scene(&r.scene, "scene")?;
    prepare(r, &entry.scene, max)
}

impl JobWork for MultiArmWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        ctx.progress(json!({"phase": "planning", "planner": "multi_arm", "arms": w.arm_names}));
        let mut term = ctx.termination();
        let plan =
            plan_multi_arm(&w.problem, &w.settings, &mut term, w.seed).map_err(plan_failure)?;
        plan.to_json(&w.arm_names, &w.joint_names, w.period)
            .map_err(timing_failure)
    }
}

/// `manyhands plan multi-arm`: the `multi_arm` job's JSON request in, its answer out, without
/// a server. Errors carry the field and reason as the HTTP 422 does.
pub fn multi_arm_locally(
    req: &MultiArmRequest,
    scene: Arc<Scene>,
    max_seconds: f64,
) -> Result<Value, String> {
    let prepared = prepare(req, &scene, max_seconds).map_err(|e| e.to_string())?;
    let mut ctx = JobContext::new(
        Arc::new(std::sync::atomic::AtomicBool::new(false)),
        Duration::from_secs_f64(prepared.time_limit),
        Box::new(|_| {}),
    );
    prepared
        .work
        .run(&mut ctx)
        .map_err(|f| format!("{}: {}", f.code, f.message))
}
