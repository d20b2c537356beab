//! `GET/PUT/DELETE /v1/robots/{name}`, `GET /v1/robots`, `GET/PUT/DELETE /v1/scenes/{name}`,
//! `GET /v1/scenes`. Uploads are validated on the CPU pool; errors name the element (URDF/SRDF)
//! or the field path (scene JSON).

use std::sync::Arc;

use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::Value;

use crate::model::SceneJson;
use crate::Robot;

use super::api::*;
use super::catalog::SceneEntry;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::AppState;

fn robot_summary(name: &str, r: &Robot, source: Source) -> RobotSummary {
    RobotSummary {
        name: name.to_string(),
        dof: r.dof(),
        source,
        groups: r.groups.iter().map(|g| g.name.clone()).collect(),
        end_effectors: r.end_effectors.iter().map(|e| e.name.clone()).collect(),
    }
}

fn robot_detail(name: &str, r: &Robot, source: Source) -> RobotDetail {
    let mut states: Vec<String> = r.group_states.iter().map(|s| s.name.clone()).collect();
    states.sort();
    states.dedup();
    RobotDetail {
        name: name.to_string(),
        dof: r.dof(),
        source,
        joints: (0..r.dof())
            .map(|v| {
                let j = &r.joints[r.vars[v]];
                JointInfo {
                    name: j.name.clone(),
                    kind: j.kind.name().to_string(),
                    lower: j.limits.lower,
                    upper: j.limits.upper,
                    velocity: j.limits.velocity,
                }
            })
            .collect(),
        links: r.links.iter().map(|l| l.name.clone()).collect(),
        groups: r
            .groups
            .iter()
            .map(|g| GroupInfo {
                name: g.name.clone(),
                joints: g.vars.iter().map(|&v| r.var_name(v).to_string()).collect(),
                chain: g
                    .chain
                    .map(|(b, t)| [r.links[b].name.clone(), r.links[t].name.clone()]),
            })
            .collect(),
        end_effectors: r
            .end_effectors
            .iter()
            .map(|e| EndEffectorInfo {
                name: e.name.clone(),
                parent_link: r.links[e.parent_link].name.clone(),
                group: e.group.clone(),
            })
            .collect(),
        named_states: states,
        warnings: r.warnings.clone(),
    }
}

fn scene_summary(name: &str, e: &SceneEntry) -> SceneSummary {
    let s = &e.scene;
    SceneSummary {
        name: name.to_string(),
        description: s.description.clone(),
        source: e.source,
        robots: s
            .json
            .robots
            .iter()
            .map(|r| SceneRobotInfo {
                name: r.name.clone(),
                model: r.model.clone(),
            })
            .collect(),
        obstacles: s.obstacles.len(),
        objects: s.objects.len(),
        grasps: s.objects.iter().map(|o| o.grasps.len()).sum(),
    }
}

#[utoipa::path(get, path = "/v1/robots", tag = "resources", responses((status = 200, body = [RobotSummary])))]
pub async fn list_robots(State(st): State<Arc<AppState>>) -> Json<Vec<RobotSummary>> {
    Json(
        st.catalog
            .robots()
            .iter()
            .map(|(n, e)| robot_summary(n, &e.robot, e.source))
            .collect(),
    )
}

#[utoipa::path(get, path = "/v1/robots/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, body = RobotDetail), (status = 404, body = ErrorBody)))]
pub async fn get_robot(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<Json<RobotDetail>> {
    let e = st.catalog.robot(&name, "name")?;
    Ok(Json(robot_detail(&name, &e.robot, e.source)))
}

/// The robot's model as URDF: its collision geometry as the planners check it (after the
/// catalog's load-time fixes), written by `model::to_urdf`. The 3-D viewer draws robots from it.
#[utoipa::path(get, path = "/v1/robots/{name}/urdf", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, content_type = "application/xml", body = String, description = "URDF text"),
              (status = 404, body = ErrorBody)))]
pub async fn get_robot_urdf(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<Response> {
    let e = st.catalog.robot(&name, "name")?;
    Ok((
        [(header::CONTENT_TYPE, "application/xml; charset=utf-8")],
        crate::model::to_urdf(&e.robot),
    )
        .into_response())
}

#[utoipa::path(put, path = "/v1/robots/{name}", tag = "resources", params(("name" = String, Path)),
    request_body = RobotUpload,
    responses((status = 201, body = RobotDetail, description = "created"), (status = 200, body = RobotDetail, description = "replaced"),
              (status = 409, body = ErrorBody, description = "built-in, or a scene no longer validates"),
              (status = 422, body = ErrorBody, description = "invalid URDF/SRDF; `field` names the element")))]
pub async fn put_robot(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
    ApiJson(body): ApiJson<RobotUpload>,
) -> ApiResult<Response> {
    let st2 = st.clone();
    let n = name.clone();
    let stored = serde_json::to_vec(&body).map_err(|e| ApiError::internal(e.to_string()))?;
    let created = st
        .pool
        .run_heavy(move || {
            st2.catalog.put_robot(
                &n,
                &body.urdf,
                body.srdf.as_deref(),
                body.joint_limits.as_deref(),
            )
        })
        .await?;
    super::shared::publish(&st, "robot", &name, stored).await?;
    let e = st.catalog.robot(&name, "name")?;
    tracing::info!(robot = %name, created, "robot uploaded");
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(robot_detail(&name, &e.robot, e.source))).into_response())
}

#[utoipa::path(delete, path = "/v1/robots/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 204), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)))]
pub async fn delete_robot(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<StatusCode> {
    let st2 = st.clone();
    let n = name.clone();
    st.pool.run(move || st2.catalog.delete_robot(&n)).await?;
    super::shared::unpublish(&st, "robot", &name).await?;
    Ok(StatusCode::NO_CONTENT)
}

#[utoipa::path(get, path = "/v1/scenes", tag = "resources", responses((status = 200, body = [SceneSummary])))]
pub async fn list_scenes(State(st): State<Arc<AppState>>) -> Json<Vec<SceneSummary>> {
    Json(
        st.catalog
            .scenes()
            .iter()
            .map(|(n, e)| scene_summary(n, e))
            .collect(),
    )
}

#[utoipa::path(get, path = "/v1/scenes/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, description = "the scene JSON (schema: api/scene.schema.json)", body = Object),
              (status = 404, body = ErrorBody)))]
pub async fn get_scene(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<Json<Value>> {
    let e = st.catalog.scene(&name, "name")?;
    serde_json::to_value(&e.scene.json)
        .map(Json)
        .map_err(|e| ApiError::internal(e.to_string()))
}

#[utoipa::path(put, path = "/v1/scenes/{name}", tag = "resources", params(("name" = String, Path)),
    request_body(content = Object, description = "scene JSON (schema: api/scene.schema.json)"),
    responses((status = 201, body = SceneSummary, description = "created"), (status = 200, body = SceneSummary, description = "replaced"),
              (status = 404, body = ErrorBody, description = "unknown robot model"),
              (status = 409, body = ErrorBody, description = "built-in scene"),
              (status = 422, body = ErrorBody, description = "invalid scene; `field` is the JSON path")))]
pub async fn put_scene(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
    ApiJson(body): ApiJson<SceneJson>,
) -> ApiResult<Response> {
    let stored = serde_json::to_vec(&body).map_err(|e| ApiError::internal(e.to_string()))?;
    let put = |st: Arc<AppState>, body: SceneJson| {
        let n = name.clone();
        async move {
            let st2 = st.clone();
            st.pool
                .run_heavy(move || st2.catalog.put_scene(&n, body))
                .await
        }
    };
    // With a shared store, a robot or mesh uploaded through another replica whose notice has
    // not arrived yet: load the shared uploads and try once more.
    let again = (st.jobs.store().backend() != "embedded").then(|| body.clone());
    let created = match (put(st.clone(), body).await, again) {
        (Err(e), Some(body))
            if matches!(
                e.status,
                StatusCode::NOT_FOUND | StatusCode::UNPROCESSABLE_ENTITY
            ) =>
        {
            super::shared::sync_all(&st).await?;
            put(st.clone(), body).await?
        }
        (r, _) => r?,
    };
    super::shared::publish(&st, "scene", &name, stored).await?;
    let e = st.catalog.scene(&name, "name")?;
    tracing::info!(scene = %name, created, "scene uploaded");
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(scene_summary(&name, &e))).into_response())
}

#[utoipa::path(delete, path = "/v1/scenes/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 204), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)))]
pub async fn delete_scene(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<StatusCode> {
    let st2 = st.clone();
    let n = name.clone();
    st.pool.run(move || st2.catalog.delete_scene(&n)).await?;
    super::shared::unpublish(&st, "scene", &name).await?;
    Ok(StatusCode::NO_CONTENT)
}
