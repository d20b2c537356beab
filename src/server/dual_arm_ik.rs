//! `POST /v1/ik/dual-arm` and `POST /v1/ik/base-placement`: the two-handed IK queries.
//!
//! - Dual-arm IK (paper 000 §III, [`DualArmProblem`]): the object pose is free inside a world box;
//!   hip and both arms are solved so that the left hand holds one of the object's left grasps and
//!   the right hand one of its right grasps, the object collision-free where it floats and in the
//!   hands. Variant (b), `held`: the object is already in the left hand by that grasp, so only the
//!   right grasp is chosen (17-D: hip + both arms). Arm IKs are called only for grasps whose arm
//!   reachability grid cell is reachable (000 §II-B), grids built on first use.
//! - Base placement (paper 002 §III, Alg. 1 IkDualArm, [`BimanualProblem`]): the object lies in the
//!   scene; the platform pose (x, y, yaw) is sampled from the bimanual inverse reachability map
//!   R_bi = min(R_left, R_right) of the object's grasps, then hip and both arms are solved for the
//!   grasps the sampled cell lists. Answers base + hip + both arms (20 DoF for ARMAR).
//!
//! Synchronous queries: lookups on the async side, the search on the CPU pool.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::Json;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::collision::CollisionWorld;
use crate::geometry::PoseJson;
use crate::kinematics::randomized::{IkCounters, RandomizedIkError};
use crate::model::{Robot, Scene};
use crate::planning::planners::bimanual_ik_rrt::{base_vars, BimanualProblem, BimanualSettings};
use crate::planning::{GoalSampler, PlanError};
use crate::reachability::cache::{GridCache, GridRecipe};
use crate::reachability::queries::DualArmProblem;

use super::api::pose_body;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::grasp_ik::{arm_grid, config_map, ik_settings, query_error};
use super::AppState;

pub use manyhands_api::{BasePlacementRequest, DualArmIkRequest, RegionJson, TwoHandIkResponse};

/// Largest edge of the object's position box (m).
pub const MAX_REGION_EDGE: f64 = 10.0;

/// Most platform poses (x, y cells × yaw bins within `radius`) one base-placement request may
/// evaluate; the default request has 31 × 31 × 16 = 15 376.
pub const MAX_PLACEMENT_POSES: usize = 250_000;

#[utoipa::path(post, path = "/v1/ik/dual-arm", tag = "queries", request_body = DualArmIkRequest,
    responses((status = 200, body = TwoHandIkResponse, description = "a solution, or `found: false` after `max_tries`"),
              (status = 400, body = ErrorBody, description = "malformed JSON"),
              (status = 404, body = ErrorBody, description = "unknown scene"),
              (status = 422, body = ErrorBody, description = "bad value; `field` names it (`robot`, `left_group`, `right_group`, `object`, `held`, `region`, `max_tries`, `psi_samples`)")))]
pub async fn dual_arm_ik(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<DualArmIkRequest>,
) -> ApiResult<Json<TwoHandIkResponse>> {
    let entry = st.catalog.scene(&req.scene, "scene")?;
    let grids = st.catalog.grids();
    st.pool
        .run_heavy(move || dual_arm_compute(&entry.scene, &req, Some(&grids)))
        .await
        .map(Json)
}

#[utoipa::path(post, path = "/v1/ik/base-placement", tag = "queries", request_body = BasePlacementRequest,
    responses((status = 200, body = TwoHandIkResponse, description = "a solution, or `found: false` after `max_tries`"),
              (status = 400, body = ErrorBody, description = "malformed JSON"),
              (status = 404, body = ErrorBody, description = "unknown scene"),
              (status = 422, body = ErrorBody, description = "bad value; `field` names it (`robot`, `left_group`, `right_group`, `object`, `radius`, `cell`, `yaw_bins`, `max_tries`, `psi_samples`)")))]
pub async fn base_placement(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<BasePlacementRequest>,
) -> ApiResult<Json<TwoHandIkResponse>> {
    let entry = st.catalog.scene(&req.scene, "scene")?;
    let grids = st.catalog.grids();
    st.pool
        .run_heavy(move || base_placement_compute(&entry.scene, &req, &grids))
        .await
        .map(Json)
}

/// The scene's robot instance `name` and its model.
fn robot_of<'a>(scene: &'a Scene, name: &str) -> ApiResult<&'a Arc<Robot>> {
    scene
        .robots
        .iter()
        .find(|r| r.name == name)
        .map(|r| &r.robot)
        .ok_or_else(|| {
            ApiError::invalid(
                "robot",
                format!("scene '{}' has no robot '{name}'", scene.name),
            )
        })
}

/// Checks that both groups exist on the robot and the object in the scene, so that set-up
/// errors name the right field.
fn check_names(
    scene: &Scene,
    robot: &Robot,
    left: &str,
    right: &str,
    object: &str,
) -> ApiResult<()> {
    for (field, g) in [("left_group", left), ("right_group", right)] {
        if robot.group(g).is_none() {
            return Err(ApiError::invalid(
                field,
                format!("robot '{}' has no group '{g}'", robot.name),
            ));
        }
    }
    if scene.object(object).is_none() {
        return Err(ApiError::invalid(
            "object",
            format!("scene '{}' has no object '{object}'", scene.name),
        ));
    }
    Ok(())
}

fn not_found(
    e: RandomizedIkError,
    joints: Vec<String>,
    reachability: bool,
    time_us: f64,
) -> ApiResult<TwoHandIkResponse> {
    match e {
        RandomizedIkError::NoSolution { tries, counters } => Ok(TwoHandIkResponse {
            found: false,
            reason: Some(RandomizedIkError::NoSolution { tries, counters }.to_string()),
            left_grasp: None,
            right_grasp: None,
            joints,
            solution: None,
            config: None,
            object_pose: None,
            tries,
            ik_calls: counters.ik_calls,
            collision_checks: counters.collision_checks,
            reachability,
            map_time_us: None,
            time_us,
        }),
        e => Err(ApiError::invalid("left_group", e.to_string())),
    }
}

/// Validates and solves a dual-arm IK request on `scene`; `grids` supplies the arms'
/// reachability grids.
pub fn dual_arm_compute(
    scene: &Scene,
    req: &DualArmIkRequest,
    grids: Option<&GridCache>,
) -> ApiResult<TwoHandIkResponse> {
    let settings = ik_settings(req.max_tries, req.psi_samples)?;
    let RegionJson { min, max } = req.region;
    if min.iter().chain(&max).any(|v| !v.is_finite())
        || (0..3).any(|i| min[i] > max[i] || max[i] - min[i] > MAX_REGION_EDGE)
    {
        return Err(ApiError::invalid(
            "region",
            format!(
                "min {min:?} / max {max:?}: finite, min ≤ max, edges at most {MAX_REGION_EDGE} m"
            ),
        ));
    }
    let model = robot_of(scene, &req.robot)?.clone();
    let left = req.left_group.as_deref().unwrap_or("torso_left_arm");
    let right = req.right_group.as_deref().unwrap_or("torso_right_arm");
    check_names(scene, &model, left, right, &req.object)?;
    let mut problem = DualArmProblem::new(scene, &req.robot, left, right, &req.object)
        .map_err(|e| query_error(e, "left_group"))?;
    let held = match &req.held {
        None => None,
        Some(name) => Some(
            problem
                .left_grasps
                .names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| {
                    ApiError::invalid(
                        "held",
                        format!(
                            "'{name}' is not a left grasp of '{}' (grasps: {})",
                            req.object,
                            problem.left_grasps.names.join(", ")
                        ),
                    )
                })?,
        ),
    };
    let pair = match grids.filter(|_| req.reachability.unwrap_or(true)) {
        Some(g) => {
            let l = arm_grid(g, &model, problem.ik.left())?;
            let r = arm_grid(g, &model, problem.ik.right())?;
            l.zip(r)
        }
        None => None,
    };
    let reachability = pair.is_some();
    problem
        .set_grids(pair)
        .map_err(|e| query_error(e, "left_group"))?;
    let mut vars: Vec<usize> = problem.ik.free_vars().to_vec();
    for arm in [problem.ik.left(), problem.ik.right()] {
        for &v in &arm.chain.vars {
            if !vars.contains(&v) {
                vars.push(v);
            }
        }
    }
    let joints: Vec<String> = vars
        .iter()
        .map(|&v| model.var_name(v).to_string())
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(req.seed.unwrap_or(1));
    let started = Instant::now();
    let answer = problem.solve((min, max), held, reachability, &settings, &mut rng);
    let time_us = started.elapsed().as_secs_f64() * 1e6;
    match answer {
        Ok(sol) => {
            let c: &IkCounters = &sol.counters;
            Ok(TwoHandIkResponse {
                found: true,
                reason: None,
                left_grasp: problem.left_grasps.names.get(sol.left_grasp).cloned(),
                right_grasp: problem.right_grasps.names.get(sol.right_grasp).cloned(),
                solution: Some(vars.iter().map(|&v| sol.config[v]).collect()),
                config: Some(config_map(&model, &sol.config)),
                object_pose: Some(pose_body(PoseJson::from_pose(
                    &problem.object_pose_of(&sol),
                ))),
                joints,
                tries: c.tries,
                ik_calls: c.ik_calls,
                collision_checks: c.collision_checks,
                reachability,
                map_time_us: None,
                time_us,
            })
        }
        Err(e) => not_found(e, joints, reachability, time_us),
    }
}

/// The field of a base-placement set-up error (the robot's `base` group is checked before).
fn placement_error(e: PlanError) -> ApiError {
    match e {
        PlanError::InvalidGoal { reason, .. } => ApiError::invalid("object", reason),
        e => ApiError::invalid("left_group", e.to_string()),
    }
}

/// Validates and solves a base-placement request on `scene`; the platform-frame reachability
/// grids of both chains come from `grids` (built on first use).
pub fn base_placement_compute(
    scene: &Scene,
    req: &BasePlacementRequest,
    grids: &GridCache,
) -> ApiResult<TwoHandIkResponse> {
    let settings = ik_settings(req.max_tries, req.psi_samples)?;
    let defaults = BimanualSettings::default();
    let radius = req.radius.unwrap_or(defaults.radius);
    if !(radius > 0.0 && radius <= 5.0) {
        return Err(ApiError::invalid(
            "radius",
            format!("{radius} is not in (0, 5] m"),
        ));
    }
    let cell = req.cell.unwrap_or(defaults.cell);
    if !(0.02..=1.0).contains(&cell) {
        return Err(ApiError::invalid(
            "cell",
            format!("{cell} is not in [0.02, 1] m"),
        ));
    }
    let yaw_bins = req.yaw_bins.unwrap_or(defaults.yaw_bins);
    if !(1..=360).contains(&yaw_bins) {
        return Err(ApiError::invalid(
            "yaw_bins",
            format!("{yaw_bins} is not in 1..=360"),
        ));
    }
    // The cost of one request: the platform poses of the map, checked before any work.
    let per_axis = 2.0 * (radius / cell).ceil() + 1.0;
    let poses = per_axis * per_axis * yaw_bins as f64;
    if poses > MAX_PLACEMENT_POSES as f64 {
        return Err(ApiError::invalid(
            "cell",
            format!(
                "cell {cell} m with radius {radius} m and {yaw_bins} yaw bins is {poses} platform \
                 poses; one request may evaluate at most {MAX_PLACEMENT_POSES} (a larger cell, a \
                 smaller radius or fewer yaw_bins)"
            ),
        ));
    }
    if radius / cell > 200.0 {
        return Err(ApiError::invalid(
            "cell",
            format!("radius {radius} m / cell {cell} m is more than 200 cells (the map's bound)"),
        ));
    }
    let model = robot_of(scene, &req.robot)?.clone();
    let left = req.left_group.as_deref().unwrap_or("torso_left_arm");
    let right = req.right_group.as_deref().unwrap_or("torso_right_arm");
    check_names(scene, &model, left, right, &req.object)?;
    base_vars(&model).map_err(|e| ApiError::invalid("robot", e.to_string()))?;
    let grid = |field: &str, g: &str| {
        grids
            .get(&model, g, GridRecipe::default())
            .map_err(|e| ApiError::invalid(field, e.to_string()))
    };
    let (gl, gr) = (grid("left_group", left)?, grid("right_group", right)?);
    let world = CollisionWorld::from_scene(scene);
    let q0 = CollisionWorld::start_config(scene);
    let problem = BimanualProblem::new(
        scene,
        &world,
        &q0,
        &req.robot,
        (left, right),
        &req.object,
        (&gl, &gr),
        BimanualSettings {
            radius,
            cell,
            yaw_bins,
            ..defaults
        },
    )
    .map_err(placement_error)?;
    let map_time_us = problem.map_time.as_secs_f64() * 1e6;
    let placed = world
        .robots
        .iter()
        .find(|p| p.name == req.robot)
        .ok_or_else(|| ApiError::invalid("robot", format!("no robot '{}'", req.robot)))?;
    let (off, dof) = (placed.offset, model.dof());
    let vars = problem.space.vars().to_vec();
    let joints: Vec<String> = vars
        .iter()
        .map(|&v| model.var_name(v - off).to_string())
        .collect();
    let mut goals = problem.goals(settings);
    let mut rng = ChaCha8Rng::seed_from_u64(req.seed.unwrap_or(1));
    let mut out = vec![0.0; vars.len()];
    let started = Instant::now();
    let label = goals.sample_goal(&mut rng, &mut out);
    let time_us = started.elapsed().as_secs_f64() * 1e6;
    let c = *goals.counters();
    match label {
        Some(label) => {
            let (l, r) = problem.decode(label);
            let wq = problem.space.to_world(&out);
            let q = &wq[off..off + dof];
            Ok(TwoHandIkResponse {
                found: true,
                reason: None,
                left_grasp: problem.left_names.get(l).cloned(),
                right_grasp: problem.right_names.get(r).cloned(),
                joints,
                solution: Some(out),
                config: Some(config_map(&model, q)),
                object_pose: Some(pose_body(PoseJson::from_pose(&problem.object_pose))),
                tries: c.tries,
                ik_calls: c.ik_calls,
                collision_checks: c.collision_checks,
                reachability: true,
                map_time_us: Some(map_time_us),
                time_us,
            })
        }
        None => {
            let e = RandomizedIkError::NoSolution {
                tries: c.tries,
                counters: c,
            };
            let mut r = not_found(e, joints, true, time_us)?;
            r.map_time_us = Some(map_time_us);
            Ok(r)
        }
    }
}
