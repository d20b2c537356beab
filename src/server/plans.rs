//! `POST /v1/plans` (202 + Location, or the final job with `?wait=SECONDS`), `GET /v1/plans`
//! (paged: `limit`, `cursor`; filters `state`, `kind`), `GET /v1/plans/{id}` (`?wait=` too),
//! `GET /v1/plans/{id}/events` (Server-Sent Events, resumable with `Last-Event-ID`),
//! `DELETE /v1/plans/{id}` (cancel). Every answer is read from the job store (any replica
//! answers for any job); a result is served as the exact JSON text the store holds.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::Json;
use futures_util::Stream;
use serde::de::DeserializeOwned;
use serde_json::Value;

use super::api::*;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::extract::ApiJson;
use super::jobs::store_error;
use super::store::{job_json, Cursor, EventRec, ListQuery, StoredJob};
use super::{kinds, AppState};

/// Longest a `DELETE` waits for the planner to stop (with its statistics) before it records the
/// job `cancelled` itself (keeping the last progress; the worker, which polls the stop flag in
/// every phase, stops soon after and its late answer is dropped).
pub const CANCEL_WAIT: Duration = Duration::from_millis(5);

/// Longest `?wait=` accepted, in seconds (a longer one is refused, 400 naming `wait`).
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

/// The query's `key=value` pairs, decoded.
fn query_pairs(q: Option<&str>) -> ApiResult<Vec<(String, String)>> {
    let mut out = Vec::new();
    for pair in q.unwrap_or("").split('&').filter(|p| !p.is_empty()) {
        let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
        out.push((percent_decode(k)?, percent_decode(v)?));
    }
    Ok(out)
}

fn parse_wait(q: Option<String>) -> ApiResult<Option<Duration>> {
    let mut wait = None;
    for (k, v) in query_pairs(q.as_deref())? {
        let (k, v) = (k.as_str(), v.as_str());
        match k {
            "wait" => {
                let s: f64 = v
                    .parse()
                    .ok()
                    .filter(|s: &f64| s.is_finite() && (0.0..=MAX_WAIT).contains(s))
                    .ok_or_else(|| {
                        ApiError::bad_request(format!(
                            "wait: '{v}' is not a number of seconds in [0, {MAX_WAIT}]"
                        ))
                        .at("wait")
                    })?;
                wait = Some(Duration::from_secs_f64(s));
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
        "multi_arm" => Ok(PlanRequest::MultiArm(de_kind(v)?)),
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

/// Most queued-job attempts a request may ask for.
pub const MAX_ATTEMPTS: u32 = 10;
/// Largest queue priority (in absolute value).
pub const MAX_PRIORITY: i32 = 1000;
/// Largest page of `GET /v1/plans` (and its default).
pub const MAX_PAGE: usize = 1000;
pub const DEFAULT_PAGE: usize = 100;

/// The job's JSON as stored, with its status and `Location`.
fn job_response(job: &StoredJob, created: bool) -> Response {
    let status = if created && !job.job.state.is_final() {
        StatusCode::ACCEPTED
    } else {
        StatusCode::OK
    };
    let mut resp = (
        status,
        [(header::CONTENT_TYPE, "application/json")],
        job_json(job),
    )
        .into_response();
    resp.headers_mut()
        .insert(header::LOCATION, location(&job.job.id));
    resp
}

fn unknown(id: &str) -> ApiError {
    ApiError::not_found("id", format!("unknown job '{id}'"))
}

#[utoipa::path(post, path = "/v1/plans", tag = "plans", request_body = PlanRequest,
    params(("wait" = Option<f64>, Query, description = "seconds to wait for the final state (0..=600)")),
    responses((status = 202, body = Job, description = "accepted; `Location` names the job"),
              (status = 200, body = Job, description = "final state reached within `wait`"),
              (status = 404, body = ErrorBody), (status = 422, body = ErrorBody),
              (status = 429, body = ErrorBody, description = "queue full; see `Retry-After`"),
              (status = 503, body = ErrorBody, description = "shutting down, overloaded or the job store unreachable; see `Retry-After`")))]
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
    let (priority, max_attempts) = req.queue_settings();
    let priority = priority.unwrap_or(0);
    if priority.abs() > MAX_PRIORITY {
        return Err(ApiError::invalid(
            "priority",
            format!("{priority} is outside -{MAX_PRIORITY}..={MAX_PRIORITY}"),
        ));
    }
    let max_attempts = max_attempts.unwrap_or(1);
    if !(1..=MAX_ATTEMPTS).contains(&max_attempts) {
        return Err(ApiError::invalid(
            "max_attempts",
            format!("{max_attempts} is outside 1..={MAX_ATTEMPTS}"),
        ));
    }
    let kind = req.kind();
    let request = serde_json::to_value(&req).map_err(|e| ApiError::internal(e.to_string()))?;
    let req = Arc::new(req);
    let prep = |st: Arc<AppState>, req: Arc<PlanRequest>| async move {
        let st2 = st.clone();
        st.pool
            .run(move || kinds::prepare(&req, &st2.catalog, st2.cfg.max_plan_seconds))
            .await
    };
    let prepared = match prep(st.clone(), req.clone()).await {
        // A robot or scene uploaded through another replica whose notice has not arrived yet.
        Err(e) if e.status == StatusCode::NOT_FOUND && st.jobs.store().backend() != "embedded" => {
            super::shared::sync_all(&st).await?;
            prep(st.clone(), req.clone()).await?
        }
        r => r?,
    };
    let mut warnings = Vec::new();
    if let Some(t) = requested_limit.filter(|&t| t > prepared.time_limit) {
        warnings.push(format!(
            "time_limit {t} s capped to {} s, the server's maximum (--max-plan-seconds)",
            prepared.time_limit
        ));
    }
    let job = st
        .jobs
        .submit(kind, request, prepared, warnings, priority, max_attempts)
        .await?;
    let stored = match wait {
        Some(d) => st.jobs.wait_final(&job.id, d).await?,
        None => None,
    };
    match stored {
        Some(s) => Ok(job_response(&s, true)),
        None => {
            let mut resp = (StatusCode::ACCEPTED, Json(job.clone())).into_response();
            resp.headers_mut()
                .insert(header::LOCATION, location(&job.id));
            Ok(resp)
        }
    }
}

/// `GET /v1/plans` query: `limit`, `cursor`, `state`, `kind`.
fn parse_list_query(q: Option<String>) -> ApiResult<ListQuery> {
    let mut out = ListQuery {
        limit: DEFAULT_PAGE,
        ..ListQuery::default()
    };
    for (k, v) in query_pairs(q.as_deref())? {
        match k.as_str() {
            "limit" => {
                out.limit = v
                    .parse::<usize>()
                    .ok()
                    .filter(|n| (1..=MAX_PAGE).contains(n))
                    .ok_or_else(|| {
                        ApiError::invalid(
                            "limit",
                            format!("'{v}' is not an integer in 1..={MAX_PAGE}"),
                        )
                    })?;
            }
            "cursor" => {
                out.after = Some(Cursor::decode(&v).ok_or_else(|| {
                    ApiError::invalid(
                        "cursor",
                        format!("'{v}' is not a cursor of this list (use next_cursor)"),
                    )
                })?);
            }
            "state" => {
                out.state = Some(
                    JobState::ALL
                        .into_iter()
                        .find(|s| s.name() == v)
                        .ok_or_else(|| {
                            let names: Vec<&str> = JobState::ALL.iter().map(|s| s.name()).collect();
                            ApiError::invalid("state", format!("'{v}' is not one of {names:?}"))
                        })?,
                );
            }
            "kind" => {
                if !PlanRequest::KINDS.contains(&v.as_str()) {
                    return Err(ApiError::invalid(
                        "kind",
                        format!("'{v}' is not one of {:?}", PlanRequest::KINDS),
                    ));
                }
                out.kind = Some(v);
            }
            other => {
                return Err(
                    ApiError::bad_request(format!("unknown query parameter '{other}'")).at(other),
                )
            }
        }
    }
    Ok(out)
}

#[utoipa::path(get, path = "/v1/plans", tag = "plans",
    params(("limit" = Option<usize>, Query, description = "jobs per page, 1..=1000 (default 100)"),
           ("cursor" = Option<String>, Query, description = "the `next_cursor` of the previous page"),
           ("state" = Option<JobState>, Query, description = "only jobs in this state"),
           ("kind" = Option<String>, Query, description = "only jobs of this kind")),
    responses((status = 200, body = JobList, description = "newest first; `next_cursor` when more follow"),
              (status = 400, body = ErrorBody), (status = 422, body = ErrorBody),
              (status = 503, body = ErrorBody, description = "the job store is unreachable")))]
pub async fn list(
    State(st): State<Arc<AppState>>,
    RawQuery(q): RawQuery,
) -> ApiResult<Json<JobList>> {
    let q = parse_list_query(q)?;
    let page = st.jobs.store().list(&q).await.map_err(store_error)?;
    Ok(Json(JobList {
        jobs: page.jobs,
        next_cursor: page.next.map(|c| c.encode()),
    }))
}

#[utoipa::path(get, path = "/v1/plans/{id}", tag = "plans",
    params(("id" = String, Path), ("wait" = Option<f64>, Query, description = "seconds to wait for the final state (0..=600)")),
    responses((status = 200, body = Job), (status = 404, body = ErrorBody)))]
pub async fn get(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
    RawQuery(q): RawQuery,
) -> ApiResult<Response> {
    let wait = parse_wait(q)?;
    let j = match wait {
        Some(d) => st.jobs.wait_final(&id, d).await?,
        None => st.jobs.get(&id).await?,
    };
    let j = j.ok_or_else(|| unknown(&id))?;
    Ok(job_response(&j, false))
}

#[utoipa::path(delete, path = "/v1/plans/{id}", tag = "plans", params(("id" = String, Path)),
    responses((status = 200, body = Job, description = "the job after the cancel (final jobs are unchanged)"),
              (status = 404, body = ErrorBody)))]
pub async fn cancel(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
) -> ApiResult<Response> {
    // The replica running the job hears the cancel through the store at once and stops its
    // planner (which polls its stop flag in every phase); a DELETE never waits longer than
    // CANCEL_WAIT for it before recording the job `cancelled` itself.
    let j = st
        .jobs
        .cancel(&id, CANCEL_WAIT)
        .await?
        .ok_or_else(|| unknown(&id))?;
    Ok(job_response(&j, false))
}

/// The SSE event of a stored event (`end`: the final job as stored).
async fn sse_event(st: &AppState, id: &str, e: EventRec) -> Option<(Event, bool)> {
    let end = e.name == "end";
    let data = if end {
        match st.jobs.get(id).await {
            Ok(Some(j)) => job_json(&j),
            _ => return None,
        }
    } else {
        e.data
    };
    Some((
        Event::default()
            .id(e.seq.to_string())
            .event(e.name)
            .data(data),
        end,
    ))
}

#[utoipa::path(get, path = "/v1/plans/{id}/events", tag = "plans",
    params(("id" = String, Path),
           ("Last-Event-ID" = Option<u64>, Header, description = "resume after this event (the `id` of the last event received)")),
    responses((status = 200, content_type = "text/event-stream",
               description = "events `state` (the job when its state changes), `progress` ({id, state, progress}) and a last `end` (the final job), each with its `id`; without `Last-Event-ID` the stream starts with the job as it is now"),
              (status = 404, body = ErrorBody)))]
pub async fn events(
    State(st): State<Arc<AppState>>,
    Path(id): Path<String>,
    headers: HeaderMap,
) -> ApiResult<Sse<impl Stream<Item = Result<Event, Infallible>>>> {
    let resume = match headers.get("last-event-id") {
        Some(v) => Some(
            v.to_str()
                .ok()
                .and_then(|s| s.trim().parse::<u64>().ok())
                .ok_or_else(|| {
                    ApiError::bad_request("Last-Event-ID: not an event id of this stream")
                        .at("Last-Event-ID")
                })?,
        ),
        None => None,
    };
    let rx = st.jobs.store().subscribe();
    let first = st.jobs.get(&id).await?.ok_or_else(|| unknown(&id))?;
    // Without Last-Event-ID: the job as it is now (`end` when final), then what follows.
    let (initial, last) = match resume {
        Some(seq) => (None, seq),
        None => {
            let seq = first.meta.last_seq;
            let ev = if first.job.state.is_final() {
                ("end", job_json(&first))
            } else {
                (
                    "state",
                    serde_json::to_string(&first.job).unwrap_or_else(|_| "{}".into()),
                )
            };
            (
                Some((
                    Event::default().id(seq.to_string()).event(ev.0).data(ev.1),
                    first.job.state.is_final(),
                )),
                seq,
            )
        }
    };
    struct S {
        st: Arc<AppState>,
        id: String,
        rx: tokio::sync::broadcast::Receiver<super::store::Notice>,
        last: u64,
        pending: std::collections::VecDeque<EventRec>,
        initial: Option<(Event, bool)>,
        done: bool,
    }
    let s = S {
        st,
        id,
        rx,
        last,
        pending: Default::default(),
        initial,
        done: false,
    };
    let stream = futures_util::stream::unfold(s, |mut s| async move {
        if s.done {
            return None;
        }
        if let Some((ev, end)) = s.initial.take() {
            s.done = end;
            return Some((Ok(ev), s));
        }
        loop {
            if let Some(e) = s.pending.pop_front() {
                s.last = e.seq;
                let (ev, end) = sse_event(&s.st, &s.id, e).await?;
                s.done = end;
                return Some((Ok(ev), s));
            }
            match s.st.jobs.store().events_after(&s.id, s.last, 256).await {
                Ok(v) if !v.is_empty() => {
                    s.pending.extend(v);
                    continue;
                }
                Ok(_) => {}
                Err(e) => {
                    tracing::debug!(job = %s.id, error = %e, "event stream: store read failed")
                }
            }
            // Nothing new: wait for a notice of this job (or a second, in case one was missed).
            let until = tokio::time::Instant::now() + Duration::from_secs(1);
            loop {
                use super::store::Notice;
                use tokio::sync::broadcast::error::RecvError;
                match tokio::time::timeout_at(until, s.rx.recv()).await {
                    Err(_) => break,
                    Ok(Ok(Notice::Job { id })) if id == s.id => break,
                    Ok(Ok(Notice::Resync)) | Ok(Err(RecvError::Lagged(_))) => break,
                    Ok(Err(RecvError::Closed)) => {
                        tokio::time::sleep_until(until).await;
                        break;
                    }
                    Ok(Ok(_)) => {}
                }
            }
        }
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}
