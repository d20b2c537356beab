//! Rust client of the manyhands HTTP/JSON API (async, reqwest): typed requests and answers (the
//! server's own [`crate::server::api`] types), the error body decoded into [`ClientError::Api`]
//! with the offending field, `wait` for a job's final state and the job's Server-Sent Events.
//!
//! ```text
//! let c = Client::new("http://127.0.0.1:8080")?;
//! let job = c.submit(&request, Some(30.0)).await?;        // POST /v1/plans?wait=30
//! let done = c.wait(&job.id, Duration::from_secs(60)).await?;
//! ```
//!
//! Owns nothing of the planning core; it is a thin adapter over HTTP like the server.

use std::time::{Duration, Instant};

use reqwest::{Method, StatusCode};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use thiserror::Error;

use crate::server::api::{
    BasePlacementRequest, CheckRequest, CheckResponse, DualArmIkRequest, FkRequest, FkResponse,
    GraspIkRequest, GraspIkResponse, GraspQualityRequest, GraspQualityResponse, Health, IkRequest,
    IkResponse, Job, JobList, PlanRequest, RobotDetail, RobotSummary, RobotUpload, SceneSummary,
    TwoHandIkResponse,
};
use crate::server::error::{ErrorBody, ErrorDetail};

/// What a call can fail with.
#[derive(Debug, Error)]
pub enum ClientError {
    /// The server answered 4xx/5xx with its error body (`field` names the request field).
    #[error("HTTP {status}: {}{}", .detail.message, .retry_after.map(|s| format!(" (retry after {s} s)")).unwrap_or_default())]
    Api {
        status: StatusCode,
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
        id: String,
        waited: Duration,
        state: String,
    },
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

pub type ClientResult<T> = Result<T, ClientError>;

/// One Server-Sent Event of `GET /v1/plans/{id}/events`: `state`, `progress` or `end`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobEvent {
    pub event: String,
    pub data: Value,
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

    pub async fn robots(&self) -> ClientResult<Vec<RobotSummary>> {
        self.get("/v1/robots").await
    }

    pub async fn robot(&self, name: &str) -> ClientResult<RobotDetail> {
        self.get(&format!("/v1/robots/{name}")).await
    }

    /// `PUT /v1/robots/{name}`: URDF (+ SRDF) text, validated by the server.
    pub async fn put_robot(&self, name: &str, upload: &RobotUpload) -> ClientResult<Value> {
        self.put(&format!("/v1/robots/{name}"), upload).await
    }

    pub async fn delete_robot(&self, name: &str) -> ClientResult<()> {
        self.delete(&format!("/v1/robots/{name}")).await
    }

    pub async fn scenes(&self) -> ClientResult<Vec<SceneSummary>> {
        self.get("/v1/scenes").await
    }

    /// `GET /v1/scenes/{name}`: the scene JSON.
    pub async fn scene(&self, name: &str) -> ClientResult<Value> {
        self.get(&format!("/v1/scenes/{name}")).await
    }

    /// `PUT /v1/scenes/{name}` with a scene JSON (see `api/scene.schema.json`).
    pub async fn put_scene(&self, name: &str, scene: &Value) -> ClientResult<SceneSummary> {
        self.put(&format!("/v1/scenes/{name}"), scene).await
    }

    pub async fn delete_scene(&self, name: &str) -> ClientResult<()> {
        self.delete(&format!("/v1/scenes/{name}")).await
    }

    // --- synchronous queries --------------------------------------------------------------------

    pub async fn fk(&self, req: &FkRequest) -> ClientResult<FkResponse> {
        self.post("/v1/fk", req).await
    }

    pub async fn ik(&self, req: &IkRequest) -> ClientResult<IkResponse> {
        self.post("/v1/ik", req).await
    }

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

    pub async fn grasp_quality(
        &self,
        req: &GraspQualityRequest,
    ) -> ClientResult<GraspQualityResponse> {
        self.post("/v1/grasp-quality", req).await
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

    pub async fn job(&self, id: &str) -> ClientResult<Job> {
        self.get(&format!("/v1/plans/{id}")).await
    }

    pub async fn jobs(&self) -> ClientResult<JobList> {
        self.get("/v1/plans").await
    }

    /// `DELETE /v1/plans/{id}`: the job after the cancel request.
    pub async fn cancel(&self, id: &str) -> ClientResult<Job> {
        Self::answer(
            self.request(Method::DELETE, &format!("/v1/plans/{id}"))
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
            .get(format!("{}/v1/plans/{id}/events", self.base));
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
