//! `POST /v1/trajectories`: the time-optimal trajectory of a given path of one robot
//! ([`crate::trajectory::time_request`]), synchronous and bounded (at most
//! 10 000 waypoints and 100 000 points).

use std::sync::Arc;

use axum::extract::State;
use axum::Json;

use super::api::{JointTrajectory, TrajectoryRequest};
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::AppState;
use crate::trajectory::time_request;

#[utoipa::path(post, path = "/v1/trajectories", tag = "queries", request_body = TrajectoryRequest,
    responses((status = 200, body = JointTrajectory), (status = 404, body = super::error::ErrorBody),
              (status = 422, body = super::error::ErrorBody)))]
pub async fn time_path(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<TrajectoryRequest>,
) -> ApiResult<Json<JointTrajectory>> {
    let robot = st.catalog.robot(&req.robot, "robot")?.robot.clone();
    st.pool
        .run(move || time_request(&robot, &req).map_err(|e| ApiError::invalid(e.field, e.reason)))
        .await
        .map(Json)
}
