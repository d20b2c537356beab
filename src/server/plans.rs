//! `POST /v1/plans` (202 + Location, or the final job with `?wait=SECONDS`), `GET /v1/plans`,
//! `GET /v1/plans/{id}` (`?wait=` too), `GET /v1/plans/{id}/events` (Server-Sent Events),
//! `DELETE /v1/plans/{id}` (cancel).

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use futures_util::Stream;
use serde::de::DeserializeOwned;
use serde_json::{json, Value};

use super::api::*;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::jobs::JobEntry;
use super::{kinds, AppState};

/// Longest a `DELETE` waits for the planner to stop (with its statistics) before it records the
/// job `cancelled` itself (keeping the last progress; the worker, which polls the stop flag in
/// every phase, stops soon after and its late answer is dropped).
pub const CANCEL_WAIT: Duration = Duration::from_millis(5);

/// Longest `?wait=` honoured, in seconds.
pub const MAX_WAIT: f64 = 600.0;

/// Decodes one `application/x-www-form-urlencoded` query component (`%XX`, `+` = space).
fn percent_decode(s: &str) -> ApiResult<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' => {
                let hex = b
                    .get(i + 1..i + 3)
                    .and_then(|h| std::str::from_utf8(h).ok())
                    .and_then(|h| u8::from_str_radix(h, 16).ok())
                    .ok_or_else(|| {
                        ApiError::bad_request(format!("query '{s}': bad percent escape"))
                    })?;
                out.push(hex);
                i += 3;
            }
            b'+' => {
                out.push(b' ');
                i += 1;
            }
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out)
        .map_err(|_| ApiError::bad_request(format!("query '{s}': not UTF-8 after decoding")))
}

fn parse_wait(q: Option<String>) -> ApiResult<Option<Duration>> {
    let mut wait = None;
    for pair in q
        .as_deref()
        .unwrap_or("")
        .split('&')
        .filter(|p| !p.is_empty())
    {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        let (k, v) = (percent_decode(k)?, percent_decode(v)?);
        let (k, v) = (k.as_str(), v.as_str());
        match k {
            "wait" => {
                let s: f64 = v
                    .parse()
                    .ok()
                    .filter(|s: &f64| s.is_finite() && *s >= 0.0)
                    .ok_or_else(|| {
                        ApiError::bad_request(format!("wait: '{v}' is not a number of seconds ≥ 0"))
                            .at("wait")
                    })?;
                wait = Some(Duration::from_secs_f64(s.min(MAX_WAIT)));
            }
            other => {
                return Err(
                    ApiError::bad_request(format!("unknown query parameter '{other}'")).at(other),
                )
            }
        }
    }
    Ok(wait)
}

fn de_kind<T: DeserializeOwned>(mut v: Value) -> ApiResult<T> {
    if let Some(o) = v.as_object_mut() {
        o.remove("kind");
    }
    serde_path_to_error::deserialize(v).map_err(|e| {
        let path = e.path().to_string();
        let msg = e.into_inner().to_string();
        ApiError::invalid(if path == "." { String::new() } else { path }, msg)
    })
}

/// Parses a plan request, dispatching on `kind` so errors keep their field paths.
pub fn parse_plan_request(v: Value) -> ApiResult<PlanRequest> {
    if !v.is_object() {
        return Err(ApiError::invalid("", "the body must be a JSON object"));
    }
    let kind = match v.get("kind") {
        Some(Value::String(k)) => k.clone(),
        Some(_) => return Err(ApiError::invalid("kind", "must be a string")),
        None => {
            return Err(ApiError::invalid(
                "kind",
                format!("missing; one of {:?}", PlanRequest::KINDS),
            ))
        }
    };
    match kind.as_str() {
        "joint_space" => Ok(PlanRequest::JointSpace(de_kind(v)?)),
        "collision_sweep" => Ok(PlanRequest::CollisionSweep(de_kind(v)?)),
        "reach" => Ok(PlanRequest::Reach(de_kind(v)?)),
        "regrasp" => Ok(PlanRequest::Regrasp(de_kind(v)?)),
        "kitchen_task" => Ok(PlanRequest::KitchenTask(de_kind(v)?)),
        "bimanual" => Ok(PlanRequest::Bimanual(de_kind(v)?)),
        "multi_robot" => Ok(PlanRequest::MultiRobot(de_kind(v)?)),
        "schedule" => Ok(PlanRequest::Schedule(de_kind(v)?)),
        "grasp_list" => Ok(PlanRequest::GraspList(de_kind(v)?)),
        "pick_place" => Ok(PlanRequest::PickPlace(de_kind(v)?)),
        k => Err(ApiError::invalid(
            "kind",
            format!("unknown kind '{k}'; one of {:?}", PlanRequest::KINDS),
        )),
    }
}

fn location(id: &str) -> HeaderValue {
    HeaderValue::from_str(&format!("/v1/plans/{id}"))
        .unwrap_or_else(|_| HeaderValue::from_static("/v1/plans"))
}

async fn wait_final(entry: &JobEntry, d: Duration) {
    let mut rx = entry.subscribe();
    let _ = tokio::time::timeout(d, rx.wait_for(|j| j.state.is_final())).await;
}

fn job_response(entry: &JobEntry, created: bool) -> Response {
    let job = entry.snapshot();
    let status = if job.state.is_final() {
        StatusCode::OK
    } else if created {
        StatusCode::ACCEPTED
    } else {
        StatusCode::OK
    };
    let mut resp = (status, Json(job)).into_response();
    resp.headers_mut()
        .insert(header::LOCATION, location(&entry.id));
    resp
}

#[utoipa::path(post, path = "/v1/plans", tag = "plans", request_body = PlanRequest,
    params(("wait" = Option<f64>, Query, description = "seconds to wait for the final state (≤ 600)")),
    responses((status = 202, body = Job, description = "accepted; `Location` names the job"),
              (status = 200, body = Job, description = "final state reached within `wait`"),
              (status = 404, body = ErrorBody), (status = 422, body = ErrorBody),
              (status = 429, body = ErrorBody, description = "queue full; see `Retry-After`"),
              (status = 503, body = ErrorBody, description = "shutting down or overloaded; see `Retry-After`")))]
pub async fn submit(
    State(st): State<Arc<AppState>>,
    RawQuery(q): RawQuery,
    ApiJson(body): ApiJson<Value>,
) -> ApiResult<Response> {
    if st.shutting_down.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(ApiError::unavailable(
            "shutting_down",
            "the server is shutting down",
            5,
        ));
    }
    let wait = parse_wait(q)?;
    let requested_limit = body.get("time_limit").and_then(Value::as_f64);
    let req = parse_plan_request(body)?;
    let kind = req.kind();
    let request = serde_json::to_value(&req).map_err(|e| ApiError::internal(e.to_string()))?;
    let st2 = st.clone();
    let prepared = st
        .pool
        .run(move || kinds::prepare(&req, &st2.catalog, st2.cfg.max_plan_seconds))
        .await?;
    let mut warnings = Vec::new();
    if let Some(t) = requested_limit.filter(|&t| t > prepared.time_limit) {
        warnings.push(format!(
            "time_limit {t} s capped to {} s, the server's maximum (--max-plan-seconds)",
            prepared.time_limit
        ));
    }
    let jobs = st.jobs.clone();
    let entry = tokio::task::spawn_blocking(move || {
        jobs.submit_with_warnings(kind, request, prepared, warnings)
    })
    .await
    .map_err(|e| ApiError::internal(format!("submit task: {e}")))??;
    if let Some(d) = wait {
        wait_final(&entry, d).await;
    }
    Ok(job_response(&entry, true))
}

#[utoipa::path(get, path = "/v1/plans", tag = "plans", responses((status = 200, body = JobList)))]
pub async fn list(State(st): State<Arc<AppState>>) -> Json<JobList> {
    Json(JobList {
        jobs: st
            .jobs
            .list()
            .into_iter()
            .map(|j| JobSummary {
                id: j.id,
                kind: j.kind,
                state: j.state,
                created_ms: j.created_ms,
            })
            .collect(),
    })
}

fn entry(st: &AppState, id: &str) -> ApiResult<Arc<JobEntry>> {
    st.jobs
        .get(id)
        .ok_or_else(|| ApiError::not_found("id", format!("unknown job '{id}'")))
}

#[utoipa::path(get, path = "/v1/plans/{id}", tag = "plans",
    params(("id" = String, Path), ("wait" = Option<f64>, Query, description = "seconds to wait for the final state")),
    responses((status = 200, body = Job), (status = 404, body = ErrorBody)))]
pub async fn get(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
    RawQuery(q): RawQuery,
) -> ApiResult<Response> {
    let wait = parse_wait(q)?;
    let e = entry(&st, &id)?;
    if let Some(d) = wait {
        wait_final(&e, d).await;
    }
    Ok(job_response(&e, false))
}

#[utoipa::path(delete, path = "/v1/plans/{id}", tag = "plans", params(("id" = String, Path)),
    responses((status = 200, body = Job, description = "the job after the cancel (final jobs are unchanged)"),
              (status = 404, body = ErrorBody)))]
pub async fn cancel(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
) -> ApiResult<Response> {
    let e = entry(&st, &id)?;
    let jobs = st.jobs.clone();
    let e2 = e.clone();
    tokio::task::spawn_blocking(move || jobs.cancel(&e2))
        .await
        .map_err(|err| ApiError::internal(format!("cancel task: {err}")))?;
    // The planner polls its stop flag (every phase, grid builds too) and normally ends the job
    // within milliseconds, with its statistics; a DELETE never waits longer than this for it.
    wait_final(&e, CANCEL_WAIT).await;
    if !e.state().is_final() {
        let jobs = st.jobs.clone();
        let e2 = e.clone();
        tokio::task::spawn_blocking(move || jobs.cancel_now(&e2))
            .await
            .map_err(|err| ApiError::internal(format!("cancel task: {err}")))?;
    }
    Ok(job_response(&e, false))
}

#[utoipa::path(get, path = "/v1/plans/{id}/events", tag = "plans", params(("id" = String, Path)),
    responses((status = 200, content_type = "text/event-stream",
               description = "events `state` (the job when its state changes), `progress` ({id, state, progress}) and a last `end` (the final job)"),
              (status = 404, body = ErrorBody)))]
pub async fn events(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
) -> ApiResult<Sse<impl Stream<Item = Result<Event, Infallible>>>> {
    let e = entry(&st, &id)?;
    let rx = e.subscribe();
    drop(e);
    let stream = futures_util::stream::unfold(
        (rx, None::<JobState>, false),
        |(mut rx, last, done)| async move {
            if done {
                return None;
            }
            if last.is_some() && rx.changed().await.is_err() {
                return None;
            }
            let job = rx.borrow_and_update().clone();
            let (name, data) = if job.state.is_final() {
                ("end", serde_json::to_string(&job))
            } else if Some(job.state) != last {
                ("state", serde_json::to_string(&job))
            } else {
                (
                    "progress",
                    serde_json::to_string(
                        &json!({"id": job.id, "state": job.state, "progress": job.progress}),
                    ),
                )
            };
            let ev = Event::default()
                .event(name)
                .data(data.unwrap_or_else(|_| "{}".into()));
            let fin = job.state.is_final();
            Some((Ok(ev), (rx, Some(job.state), fin)))
        },
    );
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}
