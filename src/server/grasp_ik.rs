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

pub use manyhands_api::{GraspIkRequest, GraspIkResponse};

/// Largest `max_tries` of one request (a try is a hip sample plus up to one arm IK per grasp;
/// 10⁶ tries of the kitchen wok take ~2 s).
pub const MAX_TRIES: u64 = 1_000_000;

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
