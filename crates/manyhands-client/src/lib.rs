//! Rust client of the manyhands HTTP/JSON API (async, reqwest): typed requests and answers
//! (the [`manyhands_api`] types the server itself uses, re-exported as [`api`]), the error body
//! decoded into [`ClientError::Api`] with the offending field, [`Client::wait`] for a job's
//! final state and the job's Server-Sent Events ([`Client::events`]).
//!
//! ```text
//! let c = Client::new("http://127.0.0.1:8080")?.with_token("…");
//! let job = c.submit(&request, Some(30.0)).await?;        // POST /v1/plans?wait=30
//! let done = c.wait(&job.id, Duration::from_secs(60)).await?;
//! ```
//!
//! A controller that only talks to the server depends on this crate alone: it pulls in the API
//! types, reqwest, serde and thiserror — none of the planning core (no parry, nalgebra, axum;
//! `tests/dependencies.rs` fails if they appear). Calls must run inside a tokio runtime (the one
//! reqwest uses). Transport is plain HTTP: reqwest is built without TLS.

use std::time::{Duration, Instant};

use reqwest::{Method, StatusCode};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use thiserror::Error;

/// The request and response types of the API (the `manyhands-api` crate).
pub use manyhands_api as api;

use manyhands_api::{
    BasePlacementRequest, CheckRequest, CheckResponse, DualArmIkRequest, ErrorBody, ErrorDetail,
    FkRequest, FkResponse, GraspIkRequest, GraspIkResponse, GraspQualityRequest,
    GraspQualityResponse, Health, IkRequest, IkResponse, Job, JobList, JointTrajectory,
    PlanRequest, RobotDetail, RobotSummary, RobotUpload, SceneSummary, TrajectoryRequest,
    TwoHandIkResponse,
};

/// What a call can fail with.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The server answered 4xx/5xx with its error body (`field` names the request field).
    #[error("HTTP {status}: {}{}", .detail.message, .retry_after.map(|s| format!(" (retry after {s} s)")).unwrap_or_default())]
    Api {
        /// The HTTP status.
        status: StatusCode,
        /// The decoded error body (or, when the body was not one, its text as `message`).
        detail: ErrorDetail,
        /// `Retry-After` of a 429/503, seconds.
        retry_after: Option<u64>,
    },
    /// Connection, timeout or protocol failure.
    #[error("transport: {0}")]
    Transport(#[from] reqwest::Error),
    /// The answer was not the expected JSON.
    #[error("unexpected answer: {0}")]
    Decode(String),
    /// [`Client::wait`] ran out of time before the job's final state.
    #[error("job {id} not final after {waited:?} (state {state})")]
    WaitTimeout {
        /// The job.
        id: String,
        /// How long it was waited for.
        waited: Duration,
        /// Its last state (`queued` or `running`).
        state: String,
    },
    /// [`Client::new`] got a base URL that is not `http://…` or `https://…`.
    #[error("invalid base URL '{0}'")]
    BadUrl(String),
}

impl ClientError {
    /// The HTTP status of an API error.
    pub fn status(&self) -> Option<StatusCode> {
        match self {
            ClientError::Api { status, .. } => Some(*status),
            ClientError::Transport(e) => e.status(),
            _ => None,
        }
    }

    /// The request field an API error names.
    pub fn field(&self) -> Option<&str> {
        match self {
            ClientError::Api { detail, .. } => detail.field.as_deref(),
            _ => None,
        }
    }
}

/// The result of a client call.
pub type ClientResult<T> = Result<T, ClientError>;

/// One Server-Sent Event of `GET /v1/plans/{id}/events`: `state`, `progress` or `end`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobEvent {
    /// The `event:` field (`message` when the event had none).
    pub event: String,
    /// The `data:` lines joined, decoded as JSON (a JSON string when they are not JSON).
    pub data: Value,
}

/// `GET /v1/robots/{name}/visuals`: a robot's visual geometry (its URDF's `<visual>`
/// elements), what a viewer draws; planners never check it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RobotVisuals {
    pub robot: String,
    /// Every `<visual>` element of every link, links in tree order.
    pub visuals: Vec<VisualItem>,
}

/// One `<visual>` element of a link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VisualItem {
    /// The link it belongs to.
    pub link: String,
    /// Its index among the link's `<visual>` elements ([`Client::robot_visual_mesh`]'s `index`).
    pub index: usize,
    /// Pose of the geometry in the link frame.
    pub pose: VisualPose,
    /// The drawable geometry; `None` when the element cannot be drawn (see `problem`).
    #[serde(default)]
    pub shape: Option<VisualShape>,
    /// Why it cannot be drawn (an unreadable element, a mesh file the server does not have).
    #[serde(default)]
    pub problem: Option<String>,
}

/// Position (m) and unit quaternion (x, y, z, w).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VisualPose {
    pub position: [f64; 3],
    pub quat_xyzw: [f64; 4],
}

/// The geometry of a [`VisualItem`] in the scene format's shape fields.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VisualShape {
    /// `box`, `cylinder`, `capsule`, `sphere` or `mesh`.
    #[serde(rename = "type")]
    pub kind: String,
    /// A box's half extents (m).
    #[serde(default)]
    pub half_extents: Option<[f64; 3]>,
    /// A cylinder's, capsule's or sphere's radius (m).
    #[serde(default)]
    pub radius: Option<f64>,
    /// A cylinder's or capsule's length along z (m).
    #[serde(default)]
    pub length: Option<f64>,
    /// A mesh's file name as the URDF writes it.
    #[serde(default)]
    pub filename: Option<String>,
    /// A mesh's path on the server (its OBJ text: [`Client::robot_visual_mesh`]).
    #[serde(default)]
    pub url: Option<String>,
}

/// A connection to one server.
#[derive(Debug, Clone)]
pub struct Client {
    base: String,
    token: Option<String>,
    http: reqwest::Client,
    /// Without a total timeout: event streams last as long as their job.
    stream_http: reqwest::Client,
}

impl Client {
    /// A client of the server at `base_url` (e.g. `http://127.0.0.1:8080`), 60 s per request.
    pub fn new(base_url: &str) -> ClientResult<Client> {
        Self::with_timeout(base_url, Duration::from_secs(60))
    }

    /// As [`Client::new`] with another per-request timeout (not applied to event streams).
    pub fn with_timeout(base_url: &str, timeout: Duration) -> ClientResult<Client> {
        let base = base_url.trim_end_matches('/').to_string();
        if !(base.starts_with("http://") || base.starts_with("https://")) {
            return Err(ClientError::BadUrl(base_url.to_string()));
        }
        let builder = || reqwest::Client::builder().connect_timeout(Duration::from_secs(10));
        Ok(Client {
            base,
            token: None,
            http: builder().timeout(timeout).build()?,
            stream_http: builder().build()?,
        })
    }

    /// Sends `Authorization: Bearer token` with every request.
    pub fn with_token(mut self, token: impl Into<String>) -> Client {
        self.token = Some(token.into());
        self
    }

    /// The base URL, without a trailing `/`.
    pub fn base_url(&self) -> &str {
        &self.base
    }

    fn request(&self, method: Method, path: &str) -> reqwest::RequestBuilder {
        self.authorized(self.http.request(method, format!("{}{path}", self.base)))
    }

    fn authorized(&self, r: reqwest::RequestBuilder) -> reqwest::RequestBuilder {
        match &self.token {
            Some(t) => r.bearer_auth(t),
            None => r,
        }
    }

    /// `/v1/plans`, with `?wait=SECONDS` when given.
    fn plans_path(wait: Option<f64>) -> String {
        match wait {
            Some(w) => format!("/v1/plans?wait={w}"),
            None => "/v1/plans".to_string(),
        }
    }

    /// Decodes a 2xx answer as `T`, anything else as [`ClientError::Api`].
    async fn answer<T: DeserializeOwned>(resp: reqwest::Response) -> ClientResult<T> {
        let status = resp.status();
        if status.is_success() {
            let bytes = resp.bytes().await?;
            let body: &[u8] = if bytes.is_empty() { b"null" } else { &bytes };
            return serde_json::from_slice(body).map_err(|e| ClientError::Decode(e.to_string()));
        }
        let retry_after = resp
            .headers()
            .get(reqwest::header::RETRY_AFTER)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse().ok());
        let text = resp.text().await.unwrap_or_default();
        let detail = serde_json::from_str::<ErrorBody>(&text)
            .map(|b| b.error)
            .unwrap_or_else(|_| ErrorDetail {
                code: "http".into(),
                message: if text.is_empty() {
                    status.to_string()
                } else {
                    text
                },
                field: None,
            });
        Err(ClientError::Api {
            status,
            detail,
            retry_after,
        })
    }

    async fn get<T: DeserializeOwned>(&self, path: &str) -> ClientResult<T> {
        Self::answer(self.request(Method::GET, path).send().await?).await
    }

    async fn post<B: Serialize + ?Sized, T: DeserializeOwned>(
        &self,
        path: &str,
        body: &B,
    ) -> ClientResult<T> {
        Self::answer(self.request(Method::POST, path).json(body).send().await?).await
    }

    async fn put<B: Serialize + ?Sized, T: DeserializeOwned>(
        &self,
        path: &str,
        body: &B,
    ) -> ClientResult<T> {
        Self::answer(self.request(Method::PUT, path).json(body).send().await?).await
    }

    async fn delete(&self, path: &str) -> ClientResult<()> {
        Self::answer::<Value>(self.request(Method::DELETE, path).send().await?)
            .await
            .map(|_| ())
    }

    // --- operations ---------------------------------------------------------------------------

    /// `GET /healthz`.
    pub async fn health(&self) -> ClientResult<Health> {
        self.get("/healthz").await
    }

    /// `GET /readyz` (an error with status 503 while shutting down).
    pub async fn ready(&self) -> ClientResult<Health> {
        self.get("/readyz").await
    }

    /// `GET /metrics`: the Prometheus text.
    pub async fn metrics(&self) -> ClientResult<String> {
        let r = self.request(Method::GET, "/metrics").send().await?;
        if !r.status().is_success() {
            return Self::answer(r).await;
        }
        Ok(r.text().await?)
    }

    // --- resources ----------------------------------------------------------------------------

    /// `GET /v1/robots`: every robot model.
    pub async fn robots(&self) -> ClientResult<Vec<RobotSummary>> {
        self.get("/v1/robots").await
    }

    /// `GET /v1/robots/{name}`: joints, links, groups, end effectors of one model.
    pub async fn robot(&self, name: &str) -> ClientResult<RobotDetail> {
        self.get(&format!("/v1/robots/{}", segment(name))).await
    }

    /// `PUT /v1/robots/{name}`: URDF (+ SRDF, + MoveIt joint limits) text, validated by the
    /// server.
    pub async fn put_robot(&self, name: &str, upload: &RobotUpload) -> ClientResult<Value> {
        self.put(&format!("/v1/robots/{}", segment(name)), upload)
            .await
    }

    /// `DELETE /v1/robots/{name}` of an uploaded robot.
    pub async fn delete_robot(&self, name: &str) -> ClientResult<()> {
        self.delete(&format!("/v1/robots/{}", segment(name))).await
    }

    /// `GET /v1/robots/{name}/visuals`: the robot's visual geometry (URDF `<visual>`
    /// elements), each mesh with the URL of its OBJ text.
    pub async fn robot_visuals(&self, name: &str) -> ClientResult<RobotVisuals> {
        self.get(&format!("/v1/robots/{}/visuals", segment(name)))
            .await
    }

    /// `GET /v1/robots/{name}/visuals/{link}/{index}`: visual mesh `index` of `link` as
    /// Wavefront OBJ text, in the geometry frame with the URDF's scale applied.
    pub async fn robot_visual_mesh(
        &self,
        name: &str,
        link: &str,
        index: usize,
    ) -> ClientResult<String> {
        let path = format!(
            "/v1/robots/{}/visuals/{}/{index}",
            segment(name),
            segment(link)
        );
        let r = self.request(Method::GET, &path).send().await?;
        if !r.status().is_success() {
            return Self::answer(r).await;
        }
        Ok(r.text().await?)
    }

    /// `GET /v1/scenes`: every scene.
    pub async fn scenes(&self) -> ClientResult<Vec<SceneSummary>> {
        self.get("/v1/scenes").await
    }

    /// `GET /v1/scenes/{name}`: the scene JSON.
    pub async fn scene(&self, name: &str) -> ClientResult<Value> {
        self.get(&format!("/v1/scenes/{}", segment(name))).await
    }

    /// `PUT /v1/scenes/{name}` with a scene JSON (see `api/scene.schema.json`).
    pub async fn put_scene(&self, name: &str, scene: &Value) -> ClientResult<SceneSummary> {
        self.put(&format!("/v1/scenes/{}", segment(name)), scene)
            .await
    }

    /// `DELETE /v1/scenes/{name}` of an uploaded scene.
    pub async fn delete_scene(&self, name: &str) -> ClientResult<()> {
        self.delete(&format!("/v1/scenes/{}", segment(name))).await
    }

    // --- synchronous queries --------------------------------------------------------------------

    /// `POST /v1/fk`: link poses of a configuration.
    pub async fn fk(&self, req: &FkRequest) -> ClientResult<FkResponse> {
        self.post("/v1/fk", req).await
    }

    /// `POST /v1/ik`: IK of a chain group for a tip pose.
    pub async fn ik(&self, req: &IkRequest) -> ClientResult<IkResponse> {
        self.post("/v1/ik", req).await
    }

    /// `POST /v1/check`: collision check of a scene at given configurations.
    pub async fn check(&self, req: &CheckRequest) -> ClientResult<CheckResponse> {
        self.post("/v1/check", req).await
    }

    /// `POST /v1/ik/grasp`: randomized whole-body IK over a grasp set (000 §II-D).
    pub async fn grasp_ik(&self, req: &GraspIkRequest) -> ClientResult<GraspIkResponse> {
        self.post("/v1/ik/grasp", req).await
    }

    /// `POST /v1/ik/dual-arm`: dual-arm IK (000 §III).
    pub async fn dual_arm_ik(&self, req: &DualArmIkRequest) -> ClientResult<TwoHandIkResponse> {
        self.post("/v1/ik/dual-arm", req).await
    }

    /// `POST /v1/ik/base-placement`: IkDualArm with base placement (002 Alg. 1).
    pub async fn base_placement_ik(
        &self,
        req: &BasePlacementRequest,
    ) -> ClientResult<TwoHandIkResponse> {
        self.post("/v1/ik/base-placement", req).await
    }

    /// `POST /v1/grasp-quality`: force closure and Ferrari–Canny ε of contacts or scene grasps.
    pub async fn grasp_quality(
        &self,
        req: &GraspQualityRequest,
    ) -> ClientResult<GraspQualityResponse> {
        self.post("/v1/grasp-quality", req).await
    }

    /// `POST /v1/trajectories`: the time-optimal trajectory of a path of one robot (the
    /// `trajectory` every plan answer carries has the same shape).
    pub async fn time_path(&self, req: &TrajectoryRequest) -> ClientResult<JointTrajectory> {
        self.post("/v1/trajectories", req).await
    }

    // --- planning jobs --------------------------------------------------------------------------

    /// `POST /v1/plans` (with `?wait=SECONDS` when given): the job as accepted, or final.
    pub async fn submit(&self, req: &PlanRequest, wait: Option<f64>) -> ClientResult<Job> {
        self.post(&Self::plans_path(wait), req).await
    }

    /// `POST /v1/plans` with a raw JSON body (any job kind, including ones newer than this
    /// client's types).
    pub async fn submit_json(&self, req: &Value, wait: Option<f64>) -> ClientResult<Job> {
        self.post(&Self::plans_path(wait), req).await
    }

    /// `GET /v1/plans/{id}`: the job now.
    pub async fn job(&self, id: &str) -> ClientResult<Job> {
        self.get(&format!("/v1/plans/{}", segment(id))).await
    }

    /// `GET /v1/plans/{id}?wait=SECONDS`: the job once final, or as it is after `wait` seconds
    /// (the server honours at most 600; the request timeout must exceed `wait`).
    pub async fn job_wait(&self, id: &str, wait: f64) -> ClientResult<Job> {
        self.get(&format!("/v1/plans/{}?wait={wait}", segment(id)))
            .await
    }

    /// `GET /v1/plans`: the first page (newest first, 100 jobs; `next_cursor` when more follow).
    pub async fn jobs(&self) -> ClientResult<JobList> {
        self.get("/v1/plans").await
    }

    /// `GET /v1/plans?limit=&cursor=&state=&kind=`: one page of the job list (newest first).
    pub async fn jobs_page(
        &self,
        limit: Option<usize>,
        cursor: Option<&str>,
        state: Option<manyhands_api::JobState>,
        kind: Option<&str>,
    ) -> ClientResult<JobList> {
        let mut q = Vec::new();
        if let Some(l) = limit {
            q.push(format!("limit={l}"));
        }
        if let Some(c) = cursor {
            q.push(format!("cursor={}", segment(c)));
        }
        if let Some(s) = state {
            q.push(format!("state={}", s.name()));
        }
        if let Some(k) = kind {
            q.push(format!("kind={}", segment(k)));
        }
        let path = if q.is_empty() {
            "/v1/plans".to_string()
        } else {
            format!("/v1/plans?{}", q.join("&"))
        };
        self.get(&path).await
    }

    /// `DELETE /v1/plans/{id}`: the job after the cancel request.
    pub async fn cancel(&self, id: &str) -> ClientResult<Job> {
        Self::answer(
            self.request(Method::DELETE, &format!("/v1/plans/{}", segment(id)))
                .send()
                .await?,
        )
        .await
    }

    /// Polls the job until its state is final (succeeded, failed, cancelled, interrupted), at
    /// most `timeout`; long-polls with `?wait` would hold a connection, so this polls every
    /// 20–200 ms.
    pub async fn wait(&self, id: &str, timeout: Duration) -> ClientResult<Job> {
        let t0 = Instant::now();
        let mut pause = Duration::from_millis(20);
        loop {
            let job = self.job(id).await?;
            if job.state.is_final() {
                return Ok(job);
            }
            if t0.elapsed() >= timeout {
                return Err(ClientError::WaitTimeout {
                    id: id.to_string(),
                    waited: t0.elapsed(),
                    state: job.state.name().to_string(),
                });
            }
            tokio::time::sleep(pause.min(timeout.saturating_sub(t0.elapsed()))).await;
            pause = (pause * 2).min(Duration::from_millis(200));
        }
    }

    /// Every event of the job's stream (`GET /v1/plans/{id}/events`) up to and including `end`,
    /// handed to `on_event` as it arrives; returns them all.
    pub async fn events(
        &self,
        id: &str,
        mut on_event: impl FnMut(&JobEvent),
    ) -> ClientResult<Vec<JobEvent>> {
        let mut r = self
            .stream_http
            .get(format!("{}/v1/plans/{}/events", self.base, segment(id)));
        if let Some(t) = &self.token {
            r = r.bearer_auth(t);
        }
        let mut resp = r.send().await?;
        if !resp.status().is_success() {
            return Self::answer(resp).await;
        }
        let mut parser = SseParser::default();
        let mut out = Vec::new();
        while let Some(chunk) = resp.chunk().await? {
            for ev in parser.feed(&chunk) {
                on_event(&ev);
                let end = ev.event == "end";
                out.push(ev);
                if end {
                    return Ok(out);
                }
            }
        }
        Ok(out)
    }
}

/// `s` as one URL path segment: everything but the unreserved characters of RFC 3986
/// percent-encoded, so a name with `/`, `?` or `#` cannot change the route.
fn segment(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~') {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

/// Incremental parser of a `text/event-stream` (fields `event:` and `data:`, blank line ends an
/// event; comments and other fields ignored; `data` decoded as JSON, else kept as a string).
#[derive(Debug, Default)]
pub struct SseParser {
    buf: Vec<u8>,
    event: Option<String>,
    data: Vec<String>,
}

impl SseParser {
    /// Feeds bytes; returns the events completed by them.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<JobEvent> {
        self.buf.extend_from_slice(bytes);
        let mut out = Vec::new();
        while let Some(nl) = self.buf.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.buf.drain(..=nl).collect();
            let line = String::from_utf8_lossy(&line);
            let line = line.trim_end_matches(['\n', '\r']);
            if line.is_empty() {
                if self.event.is_some() || !self.data.is_empty() {
                    let text = self.data.join("\n");
                    let data = serde_json::from_str(&text).unwrap_or(Value::String(text));
                    out.push(JobEvent {
                        event: self.event.take().unwrap_or_else(|| "message".into()),
                        data,
                    });
                    self.data.clear();
                }
                continue;
            }
            if line.starts_with(':') {
                continue;
            }
            let (field, value) = match line.split_once(':') {
                Some((f, v)) => (f, v.strip_prefix(' ').unwrap_or(v)),
                None => (line, ""),
            };
            match field {
                "event" => self.event = Some(value.to_string()),
                "data" => self.data.push(value.to_string()),
                _ => {}
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn sse_parser_handles_split_chunks_comments_and_multiline_data() {
        let mut p = SseParser::default();
        let mut all = Vec::new();
        for chunk in [
            &b": keep-alive\n\nevent: sta"[..],
            b"te\ndata: {\"state\":",
            b"\"running\"}\n\n",
            b"data: line one\r\ndata: line two\r\n\r\n",
            b"event: end\ndata: {\"state\":\"succeeded\"}\n\n",
        ] {
            all.extend(p.feed(chunk));
        }
        assert_eq!(all.len(), 3, "{all:?}");
        assert_eq!(all[0].event, "state");
        assert_eq!(all[0].data, json!({"state": "running"}));
        assert_eq!(all[1].event, "message");
        assert_eq!(all[1].data, json!("line one\nline two"));
        assert_eq!(all[2].event, "end");
    }

    #[test]
    fn path_segments_are_percent_encoded() {
        assert_eq!(segment("armar_b-2.v~1"), "armar_b-2.v~1");
        assert_eq!(segment("../a b?c#d/é"), "..%2Fa%20b%3Fc%23d%2F%C3%A9");
    }

    #[test]
    fn base_urls_need_a_scheme() {
        assert!(matches!(
            Client::new("localhost:8080"),
            Err(ClientError::BadUrl(_))
        ));
        let c = Client::new("http://127.0.0.1:8080/").expect("client");
        assert_eq!(c.base_url(), "http://127.0.0.1:8080");
    }
}
