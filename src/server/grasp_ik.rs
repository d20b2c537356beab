//! `POST /v1/ik/grasp`: randomized whole-body IK over a grasp set (paper 000 §II-A/§II-D,
//! [`crate::reachability::queries::SingleArmProblem`]): sample the chain's free joints (hip), solve
//! the S-R-S arm analytically for the object's grasps, check self- and environment collision
//! with the object in the hand, stop after `max_tries`. The answer is a configuration plus the
//! grasp it reaches. With `reachability` (default) the arm IK is called only for grasps the arm's
//! 6-D reachability grid (000 §II-B) marks reachable. A synchronous query: lookups on the async side, the search on the CPU pool.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::Json;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::kinematics::randomized::{
    ArmChain, IkCounters, RandomizedIkError, RandomizedIkSettings,
};
use crate::model::{Robot, Scene};
use crate::reachability::cache::GridCache;
use crate::reachability::queries::{QueryError, SingleArmProblem};
use crate::reachability::ReachabilityGrid;

use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::AppState;

/// Largest `max_tries` of one request (a try is a hip sample plus up to one arm IK per grasp;
/// 10⁶ tries of the kitchen wok take ~2 s).
pub const MAX_TRIES: u64 = 1_000_000;

/// `POST /v1/ik/grasp`: a configuration of `robot`'s chain `group` whose hand holds one of
/// `object`'s grasps where the object lies in `scene`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct GraspIkRequest {
    pub scene: String,
    /// Robot instance of the scene.
    pub robot: String,
    /// Chain group "free joints + 7-DoF S-R-S arm" (e.g. `torso_right_arm`, 10 DoF).
    pub group: String,
    /// Object of the scene; its grasp set for the end effector at the chain's tip is used.
    pub object: String,
    /// Samples of the free joints before "no solution" (1..=1000000, default 20000).
    #[serde(default)]
    pub max_tries: Option<u64>,
    /// Swivel angles per arm-IK call (1..=360, default 8).
    #[serde(default)]
    pub psi_samples: Option<u32>,
    /// Random seed (default 1): same request and seed, same answer.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Call the arm IK only for grasps whose cell of the arm's 6-D reachability grid is
    /// reachable (000 §II-B/§II-D; default true). The grid of the arm chain (an SRDF group from
    /// the arm's base to its tip, e.g. `right_arm`) is built on first use and kept under the
    /// server's data folder; without such a group the query runs unfiltered.
    #[serde(default)]
    pub reachability: Option<bool>,
}

/// The answer: `found` with the configuration and grasp, or not found after `counters.tries`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct GraspIkResponse {
    pub found: bool,
    /// Why nothing was found (`found: false`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Name of the grasp reached.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grasp: Option<String>,
    /// Names of the chain's joints, the order of `solution`.
    pub joints: Vec<String>,
    /// Values of the chain's joints.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solution: Option<Vec<f64>>,
    /// Every variable of the robot (`joint: value`), the chain's from the solution, the rest
    /// from the scene's start configuration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub config: Option<serde_json::Map<String, serde_json::Value>>,
    /// Free-joint samples, analytic IK calls, collision checks.
    pub tries: u64,
    pub ik_calls: u64,
    pub collision_checks: u64,
    /// Whether the reachability filter was used.
    pub reachability: bool,
    /// Wall time of the search (µs), without building or loading the grid.
    pub time_us: f64,
}

#[utoipa::path(post, path = "/v1/ik/grasp", tag = "queries", request_body = GraspIkRequest,
    responses((status = 200, body = GraspIkResponse, description = "a solution, or `found: false` after `max_tries`"),
              (status = 400, body = ErrorBody, description = "malformed JSON"),
              (status = 404, body = ErrorBody, description = "unknown scene"),
              (status = 422, body = ErrorBody, description = "bad value; `field` names it (`robot`, `group`, `object`, `max_tries`, `psi_samples`)")))]
pub async fn grasp_ik(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<GraspIkRequest>,
) -> ApiResult<Json<GraspIkResponse>> {
    let entry = st.catalog.scene(&req.scene, "scene")?;
    let grids = st.catalog.grids();
    st.pool
        .run_heavy(move || compute(&entry.scene, &req, Some(&grids)))
        .await
        .map(Json)
}

/// Randomized-IK settings of a request: `max_tries` (1..=[`MAX_TRIES`], default 20 000) and
/// `psi_samples` (1..=360, default 8) checked, the rest the defaults.
pub fn ik_settings(max_tries: Option<u64>, psi: Option<u32>) -> ApiResult<RandomizedIkSettings> {
    let max_tries = max_tries.unwrap_or(20_000);
    if !(1..=MAX_TRIES).contains(&max_tries) {
        return Err(ApiError::invalid(
            "max_tries",
            format!("{max_tries} is not in 1..={MAX_TRIES}"),
        ));
    }
    let psi = psi.unwrap_or(8);
    if !(1..=360).contains(&psi) {
        return Err(ApiError::invalid(
            "psi_samples",
            format!("{psi} is not in 1..=360"),
        ));
    }
    Ok(RandomizedIkSettings {
        max_tries,
        psi_samples: psi,
        ..RandomizedIkSettings::default()
    })
}

/// A query set-up error as a 422 naming its field; errors about the chain name `group_field`.
pub fn query_error(e: QueryError, group_field: &str) -> ApiError {
    let field = match &e {
        QueryError::NoRobot { .. } => "robot",
        QueryError::NoObject { .. } | QueryError::NoGrasps { .. } => "object",
        _ => group_field,
    };
    ApiError::invalid(field, e.to_string())
}

/// The full configuration of robot `model` as a `joint: value` map.
pub fn config_map(model: &Robot, q: &[f64]) -> serde_json::Map<String, serde_json::Value> {
    (0..model.dof())
        .map(|v| (model.var_name(v).to_string(), q[v].into()))
        .collect()
}

/// The reachability grid of `arm` from `grids`, when the robot has a group for the arm chain.
pub fn arm_grid(
    grids: &GridCache,
    robot: &Arc<Robot>,
    arm: &ArmChain,
) -> ApiResult<Option<Arc<ReachabilityGrid>>> {
    grids
        .arm_grid(robot, arm)
        .map_err(|e| ApiError::invalid("reachability", e.to_string()))
}

/// Validates and solves a request on `scene`; `grids` supplies the arm's reachability grid.
pub fn compute(
    scene: &Scene,
    req: &GraspIkRequest,
    grids: Option<&GridCache>,
) -> ApiResult<GraspIkResponse> {
    let settings = ik_settings(req.max_tries, req.psi_samples)?;
    if scene.object(&req.object).is_none() {
        return Err(ApiError::invalid(
            "object",
            format!("scene '{}' has no object '{}'", scene.name, req.object),
        ));
    }
    let mut problem = SingleArmProblem::new(scene, &req.robot, &req.group, &req.object)
        .map_err(|e| query_error(e, "group"))?;
    let grid = match grids.filter(|_| req.reachability.unwrap_or(true)) {
        Some(g) => arm_grid(g, &problem.ik.robot().clone(), problem.ik.split())?,
        None => None,
    };
    let reachability = grid.is_some();
    problem
        .set_grid(grid)
        .map_err(|e| query_error(e, "group"))?;
    let mut rng = ChaCha8Rng::seed_from_u64(req.seed.unwrap_or(1));
    let started = Instant::now();
    let object_pose = problem.object_pose;
    let answer = problem.solve(&object_pose, reachability, &settings, &mut rng);
    let time_us = started.elapsed().as_secs_f64() * 1e6;
    let robot = problem.ik.robot().clone();
    let vars = problem.ik.split().chain.vars.clone();
    let joints: Vec<String> = vars
        .iter()
        .map(|&v| robot.var_name(v).to_string())
        .collect();
    let counters = |c: &IkCounters| (c.tries, c.ik_calls, c.collision_checks);
    match answer {
        Ok(sol) => {
            let (tries, ik_calls, collision_checks) = counters(&sol.counters);
            Ok(GraspIkResponse {
                found: true,
                reason: None,
                grasp: problem.grasps.names.get(sol.grasp).cloned(),
                solution: Some(vars.iter().map(|&v| sol.config[v]).collect()),
                config: Some(config_map(&robot, &sol.config)),
                joints,
                tries,
                ik_calls,
                collision_checks,
                reachability,
                time_us,
            })
        }
        Err(RandomizedIkError::NoSolution { tries, counters: c }) => {
            let (_, ik_calls, collision_checks) = counters(&c);
            let reason = RandomizedIkError::NoSolution { tries, counters: c }.to_string();
            Ok(GraspIkResponse {
                found: false,
                reason: Some(reason),
                grasp: None,
                solution: None,
                config: None,
                joints,
                tries,
                ik_calls,
                collision_checks,
                reachability,
                time_us,
            })
        }
        Err(e) => Err(ApiError::invalid("group", e.to_string())),
    }
}
