//! The HTTP/JSON server (`manyhands serve`).
//!
//! The server is a thin adapter: routes parse and validate a request (errors name the field),
//! hand it to the library (synchronous queries on a bounded CPU pool) or to the job runner
//! (planners on dedicated worker threads), and serialise the answer. The async runtime only
//! does I/O. The planning core must not depend on this module (no tokio/axum/HTTP types in
//! `model`, `kinematics`, `collision`, `planning`).
//!
//! Modules: [`api`] request/response types (the `manyhands-api` crate, re-exported), [`error`] the one error type, [`extract`] the
//! strict JSON extractor, [`catalog`] robots and scenes, [`queries`] FK/IK/check, [`kinds`] job
//! kinds, [`jobs`] the runner, [`store`] persistence, [`metrics`] Prometheus, [`openapi`] the
//! spec.

pub mod api;
pub mod builds;
pub mod catalog;
pub mod dual_arm_ik;
pub mod error;
pub mod extract;
pub mod grasp_ik;
pub mod grasp_lists;
pub mod grasp_quality;
pub mod jobs;
pub mod kinds;
pub mod meshes;
pub mod metrics;
pub mod multi_arm;
pub mod multi_robot;
pub mod openapi;
pub mod pick_place;
pub mod plans;
pub mod pool;
pub mod queries;
pub mod resources;
pub mod shared;
pub mod store;
pub mod trajectories;
pub mod viewer;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::future::BoxFuture;
use tokio::sync::watch;

use self::api::Health;
use self::catalog::Catalog;
use self::error::ApiError;
use self::jobs::{Jobs, RunnerConfig};
use self::metrics::{Gauges, Metrics};
use self::pool::{CpuPool, PoolConfig};
use self::store::embedded::EmbeddedStore;
use self::store::postgres::{PgOptions, PgStore};
use self::store::{JobStore, StoreError};

/// Nice levels of the heavy query lane's threads below the process's own priority: below the
/// light lane (the process's own), above the planner threads (`planner_nice`, default 10).
pub const HEAVY_NICE: i32 = 5;

/// Shortest bearer token accepted when the bind address is not loopback.
pub const MIN_TOKEN_CHARS: usize = 16;

/// Settings of `manyhands serve`.
#[derive(Debug, Clone)]
pub struct Config {
    pub bind: SocketAddr,
    /// Job store and uploaded robots/scenes.
    pub data_dir: PathBuf,
    /// Built-in (read-only) robots and scenes.
    pub robots_dir: PathBuf,
    pub scenes_dir: PathBuf,
    /// Planner worker threads.
    pub workers: usize,
    /// Threads of the synchronous-query pool's light lane (FK, IK, check).
    pub query_threads: usize,
    /// Threads of its heavy lane (grasp quality, randomized IK searches, uploads), which run at
    /// a lower priority than the light lane and never take its threads.
    pub heavy_threads: usize,
    /// Heavy queries queued or running before the heavy lane answers 503 + `Retry-After`.
    pub max_heavy: usize,
    /// Nice levels (0–19) of the planner threads above the process's own nice value (at most
    /// 19): jobs are background work, so on a busy machine the synchronous queries (IK, FK,
    /// checks) get the CPU first. 0 = same priority.
    pub planner_nice: i32,
    /// Jobs waiting for a worker before 429.
    pub max_queue: usize,
    /// Cap of any job's time limit, seconds.
    pub max_plan_seconds: f64,
    /// Bearer token; required when `bind` is not a loopback address.
    pub token: Option<String>,
    /// Request body limit in bytes.
    pub max_body: usize,
    /// Longest a client may take to send a request's headers (from the first byte, or from the
    /// end of the previous request on a kept-alive connection); then the connection is closed.
    pub header_timeout: Duration,
    /// Longest a client may take to send a request's body, from the end of its headers; then
    /// the request is answered 408 and the connection closed.
    pub body_timeout: Duration,
    /// Final jobs older than this are deleted.
    pub retention: Duration,
    /// Running jobs get this long to finish at shutdown.
    pub shutdown_grace: Duration,
    /// At shutdown the listener stays open at least this long (capped by `shutdown_grace`),
    /// `/readyz` answering 503, so a load balancer sees the drain before connections fail.
    pub drain: Duration,
    /// The shared job store (`postgres://…`); `None`: the embedded store under `data_dir`.
    pub store: Option<String>,
    /// This replica's name, the owner of the leases it takes (default: host name and pid).
    pub replica: String,
    /// How long a claimed job stays this replica's without a renewal.
    pub lease: Duration,
    /// Results of finished jobs kept at most (bytes); the oldest finished jobs go first.
    pub max_result_bytes: u64,
    /// Connections to a shared store (PostgreSQL).
    pub store_pool: usize,
}

/// The default replica name: the host name and the process id.
pub fn default_replica() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "manyhands".into());
    format!("{host}-{}", std::process::id())
}

impl Config {
    /// Defaults for `bind` and `data_dir`, built-in models from `data_root()`.
    pub fn new(bind: SocketAddr, data_dir: PathBuf) -> Config {
        let root = crate::model::data_root();
        let cores = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(2);
        Config {
            bind,
            data_dir,
            robots_dir: root.join("robots"),
            scenes_dir: root.join("scenes"),
            workers: cores,
            query_threads: cores,
            heavy_threads: (cores / 2).max(1),
            max_heavy: 2 * (cores / 2).max(1),
            planner_nice: 10,
            max_queue: 64,
            max_plan_seconds: 60.0,
            token: None,
            max_body: 2 * 1024 * 1024,
            header_timeout: Duration::from_secs(15),
            body_timeout: Duration::from_secs(20),
            retention: Duration::from_secs(7 * 24 * 3600),
            shutdown_grace: Duration::from_secs(10),
            drain: Duration::from_secs(5),
            store: None,
            replica: default_replica(),
            lease: Duration::from_secs(10),
            max_result_bytes: 4 << 30,
            store_pool: 8,
        }
    }

    pub fn validate(&self) -> Result<(), ServerError> {
        if let Some(t) = self.token.as_deref().filter(|t| !t.is_empty()) {
            // The bearer check compares the header's token after trimming it, and a header
            // cannot carry control characters: such a token would refuse every request.
            if t.trim().is_empty() {
                return Err(ServerError::Config(
                    "the token is blank (only whitespace): no request could ever match it; give a token of visible characters".into(),
                ));
            }
            if t.trim() != t {
                return Err(ServerError::Config(
                    "the token starts or ends with whitespace, which an Authorization header cannot carry; remove it".into(),
                ));
            }
            if t.chars().any(char::is_control) {
                return Err(ServerError::Config(
                    "the token contains control characters, which an Authorization header cannot carry".into(),
                ));
            }
        }
        if !self.bind.ip().is_loopback() && self.token.as_deref().is_none_or(str::is_empty) {
            return Err(ServerError::Config(format!(
                "binding {} (not loopback) requires a token (--token or MANYHANDS_TOKEN)",
                self.bind
            )));
        }
        if let Some(t) = self.token.as_deref() {
            if !self.bind.ip().is_loopback() && t.chars().count() < MIN_TOKEN_CHARS {
                return Err(ServerError::Config(format!(
                    "binding {} (not loopback) requires a token of at least {MIN_TOKEN_CHARS} characters",
                    self.bind
                )));
            }
        }
        if self.workers == 0
            || self.query_threads == 0
            || self.heavy_threads == 0
            || self.max_heavy == 0
            || self.max_queue == 0
        {
            return Err(ServerError::Config(
                "workers, query threads, heavy threads, max heavy and max queue must be ≥ 1".into(),
            ));
        }
        if !(0..=19).contains(&self.planner_nice) {
            return Err(ServerError::Config(format!(
                "planner nice {} is outside 0..=19",
                self.planner_nice
            )));
        }
        if let Some(url) = self.store.as_deref() {
            if !(url.starts_with("postgres://") || url.starts_with("postgresql://")) {
                return Err(ServerError::Config(
                    "the store must be a postgres:// (or postgresql://) URL; without one the embedded store under the data directory is used".into(),
                ));
            }
        }
        if self.lease < Duration::from_millis(300) {
            return Err(ServerError::Config(
                "the lease must be at least 0.3 s".into(),
            ));
        }
        if self.replica.is_empty() || self.replica.len() > 128 {
            return Err(ServerError::Config(
                "the replica id must be 1-128 characters".into(),
            ));
        }
        if self.header_timeout.is_zero() || self.body_timeout.is_zero() {
            return Err(ServerError::Config(
                "the header and body read timeouts must be positive".into(),
            ));
        }
        if !(self.max_plan_seconds.is_finite() && self.max_plan_seconds > 0.0) {
            return Err(ServerError::Config(
                "max plan seconds must be a positive number".into(),
            ));
        }
        Ok(())
    }
}

/// Why the server could not start or stop cleanly.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    #[error("configuration: {0}")]
    Config(String),
    #[error("cannot bind {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        source: std::io::Error,
    },
    /// (Not a `source`: the message already holds it, and `{:#}` would print it twice.)
    #[error("loading models: {0}")]
    Model(crate::model::ModelError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error("server: {0}")]
    Io(#[from] std::io::Error),
}

impl From<crate::model::ModelError> for ServerError {
    fn from(e: crate::model::ModelError) -> ServerError {
        ServerError::Model(e)
    }
}

/// State shared by all handlers.
pub struct AppState {
    pub cfg: Config,
    pub catalog: Catalog,
    pub jobs: Arc<Jobs>,
    pub metrics: Arc<Metrics>,
    pub pool: CpuPool,
    pub shutting_down: AtomicBool,
    /// Uploads of other replicas loaded into `catalog` (shared store only).
    pub applied: shared::Applied,
}

impl AppState {
    fn gauges(&self) -> Gauges {
        let (robots, scenes) = self.catalog.counts();
        Gauges {
            queue_depth: self.jobs.queue_depth(),
            queue_capacity: self.cfg.max_queue,
            workers: self.cfg.workers,
            jobs_by_state: self.jobs.counts_by_state(),
            robots,
            scenes,
            result_bytes: self.jobs.result_bytes(),
            store_up: self.jobs.store_reachable(),
            store_backend: self.jobs.store().backend(),
            running_here: self.jobs.running_here(),
        }
    }

    fn health(&self) -> Health {
        let g = self.gauges();
        Health {
            status: if self.shutting_down.load(Ordering::Relaxed) {
                "shutting_down"
            } else if !self.jobs.store_reachable() {
                "store_unreachable"
            } else {
                "ok"
            }
            .into(),
            version: env!("CARGO_PKG_VERSION").into(),
            robots: g.robots,
            scenes: g.scenes,
            queue_depth: g.queue_depth,
            queue_capacity: g.queue_capacity,
            workers: g.workers,
        }
    }
}

#[utoipa::path(get, path = "/healthz", tag = "operations", security(()), responses((status = 200, body = Health, description = "the process is alive")))]
async fn healthz(State(st): State<Arc<AppState>>) -> Json<Health> {
    Json(st.health())
}

#[utoipa::path(get, path = "/readyz", tag = "operations", security(()),
    responses((status = 200, body = Health, description = "accepting work"), (status = 503, body = Health, description = "shutting down, or the job store is unreachable")))]
async fn readyz(State(st): State<Arc<AppState>>) -> Response {
    let h = st.health();
    let code = if h.status == "ok" {
        StatusCode::OK
    } else {
        StatusCode::SERVICE_UNAVAILABLE
    };
    (code, Json(h)).into_response()
}

#[utoipa::path(get, path = "/metrics", tag = "operations", security(()),
    responses((status = 200, content_type = "text/plain", description = "Prometheus text format")))]
async fn metrics_handler(State(st): State<Arc<AppState>>) -> Response {
    let text = st.metrics.render(&st.gauges());
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

async fn openapi_handler() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        openapi::openapi_json(),
    )
        .into_response()
}

async fn not_found() -> ApiError {
    ApiError::not_found("", "no such endpoint")
}

async fn method_not_allowed() -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        "method_not_allowed",
        "method not allowed on this endpoint",
    )
}

/// Bearer-token check (all routes except health, readiness, metrics and the spec).
async fn auth(State(st): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    if let Some(token) = st.cfg.token.as_deref().filter(|t| !t.is_empty()) {
        let open = matches!(
            req.uri().path(),
            "/healthz" | "/readyz" | "/metrics" | "/openapi.json" | "/viewer" | "/viewer/viewer.js"
        );
        if !open {
            let ok = req
                .headers()
                .get(header::AUTHORIZATION)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.trim().split_once(' '))
                // The auth scheme is case-insensitive (RFC 7235 §2.1).
                .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
                .is_some_and(|(_, t)| constant_time_eq(t.trim().as_bytes(), token.as_bytes()));
            if !ok {
                return ApiError::unauthorized().into_response();
            }
        }
    }
    next.run(req).await
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The time left to read a request's body ([`Config::body_timeout`] from the end of its
/// headers), and whether it was read to its end; set per request by [`connection_hygiene`],
/// used by the JSON extractor ([`extract::ApiJson`]).
#[derive(Clone)]
pub struct BodyRead {
    /// [`Config::max_body`].
    pub limit: usize,
    pub deadline: tokio::time::Instant,
    pub complete: Arc<AtomicBool>,
}

/// Closes the connection after an answer given without reading the whole request body (a
/// refusal before the body: 401, 404, 413, 415, …; a body that timed out): the unread rest of
/// the body would otherwise be taken for the next request, so the server closes the
/// connection anyway, and says so (`Connection: close`) for a keep-alive client to open a new
/// one instead of failing its next request on a dead socket.
async fn connection_hygiene(
    State(st): State<Arc<AppState>>,
    mut req: Request,
    next: Next,
) -> Response {
    let has_body = req.headers().contains_key(header::TRANSFER_ENCODING)
        || req
            .headers()
            .get(header::CONTENT_LENGTH)
            .is_some_and(|v| v.as_bytes().iter().any(|b| (b'1'..=b'9').contains(b)));
    let read = BodyRead {
        limit: st.cfg.max_body,
        deadline: tokio::time::Instant::now() + st.cfg.body_timeout,
        complete: Arc::new(AtomicBool::new(false)),
    };
    req.extensions_mut().insert(read.clone());
    let mut resp = next.run(req).await;
    if has_body && !read.complete.load(Ordering::SeqCst) {
        resp.headers_mut().insert(
            header::CONNECTION,
            header::HeaderValue::from_static("close"),
        );
    }
    resp
}

/// Request metrics and a debug log line per request (errors at warn/error).
async fn observe(State(st): State<Arc<AppState>>, req: Request, next: Next) -> Response {
    let t0 = Instant::now();
    let method = req.method().as_str().to_string();
    let route = req
        .extensions()
        .get::<MatchedPath>()
        .map(|m| m.as_str().to_string())
        .unwrap_or_else(|| "unmatched".into());
    let path = req.uri().path().to_string();
    let resp = next.run(req).await;
    let secs = t0.elapsed().as_secs_f64();
    let status = resp.status().as_u16();
    st.metrics.record_request(&method, &route, status, secs);
    if status >= 500 {
        tracing::error!(%method, %path, status, ms = secs * 1e3, "request failed");
    } else {
        tracing::debug!(%method, %path, status, ms = secs * 1e3, "request");
    }
    resp
}

/// The router of the API over `state`.
pub fn router(state: Arc<AppState>) -> Router {
    let max_body = state.cfg.max_body;
    Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(metrics_handler))
        .route("/openapi.json", get(openapi_handler))
        .route("/v1/robots", get(resources::list_robots))
        .route(
            "/v1/robots/{name}",
            get(resources::get_robot)
                .put(resources::put_robot)
                .delete(resources::delete_robot),
        )
        .route("/v1/robots/{name}/urdf", get(resources::get_robot_urdf))
        .route("/v1/robots/{name}/visuals", get(meshes::robot_visuals))
        .route(
            "/v1/robots/{name}/visuals/{link}/{index}",
            get(meshes::robot_visual_mesh),
        )
        .route("/v1/scenes", get(resources::list_scenes))
        .route(
            "/v1/scenes/{name}/meshes/{list}/{index}/{shape}",
            get(meshes::scene_mesh),
        )
        .route("/v1/meshes", get(meshes::list_meshes))
        .route(
            "/v1/meshes/{name}",
            get(meshes::get_mesh)
                .put(meshes::put_mesh)
                .delete(meshes::delete_mesh)
                // A mesh file may be larger than a JSON request (its own bound, checked again
                // by the catalog).
                .layer(DefaultBodyLimit::max(catalog::MAX_MESH_BYTES)),
        )
        .route(
            "/v1/scenes/{name}",
            get(resources::get_scene)
                .put(resources::put_scene)
                .delete(resources::delete_scene),
        )
        .route("/v1/fk", post(queries::fk))
        .route("/v1/ik", post(queries::ik))
        .route("/v1/check", post(queries::check))
        .route("/v1/trajectories", post(trajectories::time_path))
        .route("/v1/ik/grasp", post(grasp_ik::grasp_ik))
        .route("/v1/ik/dual-arm", post(dual_arm_ik::dual_arm_ik))
        .route("/v1/ik/base-placement", post(dual_arm_ik::base_placement))
        .route("/v1/grasp-quality", post(grasp_quality::grasp_quality))
        .route("/v1/grasp-lists", get(grasp_lists::list_index))
        .route("/v1/grasp-lists/{id}", get(grasp_lists::get_list))
        .route("/v1/plans", post(plans::submit).get(plans::list))
        .route("/v1/plans/{id}", get(plans::get).delete(plans::cancel))
        .route("/v1/plans/{id}/events", get(plans::events))
        .route("/viewer", get(viewer::page))
        .route("/viewer/viewer.js", get(viewer::script))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(middleware::from_fn_with_state(state.clone(), auth))
        .route_layer(middleware::from_fn_with_state(state.clone(), observe))
        .layer(DefaultBodyLimit::max(max_body))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            connection_hygiene,
        ))
        .layer(tower_http::catch_panic::CatchPanicLayer::custom(|_| {
            ApiError::internal("handler panicked").into_response()
        }))
        .with_state(state)
}

/// Accepts connections and serves HTTP/1.1 on each (keep-alive) — what `axum::serve` does,
/// plus hyper's header read timeout ([`Config::header_timeout`]): a client that opens a
/// connection, or keeps one open, without sending a whole request head in time is
/// disconnected. Once `stop` turns true no connection is accepted any more; each open one
/// finishes the request in flight and is closed (graceful shutdown).
async fn serve_http1(
    listener: tokio::net::TcpListener,
    app: Router,
    header_timeout: Duration,
    mut stop: watch::Receiver<bool>,
) -> std::io::Result<()> {
    use hyper_util::rt::{TokioIo, TokioTimer};
    use hyper_util::service::TowerToHyperService;
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
    loop {
        let accepted = tokio::select! {
            r = listener.accept() => r,
            _ = stop.wait_for(|s| *s) => break,
        };
        let stream = match accepted {
            Ok((stream, _)) => stream,
            Err(e) => {
                // Out of file descriptors and the like: wait for connections to close.
                tracing::warn!(error = %e, "cannot accept a connection");
                tokio::time::sleep(Duration::from_millis(100)).await;
                continue;
            }
        };
        let conn = hyper::server::conn::http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(header_timeout)
            .serve_connection(TokioIo::new(stream), TowerToHyperService::new(app.clone()));
        let conn = graceful.watch(conn);
        tokio::spawn(async move {
            if let Err(e) = conn.await {
                tracing::debug!(error = %e, "connection ended with an error");
            }
        });
    }
    drop(listener);
    graceful.shutdown().await;
    Ok(())
}

/// A running server.
pub struct Server {
    addr: SocketAddr,
    state: Arc<AppState>,
    stop_tx: watch::Sender<bool>,
    serve: tokio::task::JoinHandle<std::io::Result<()>>,
    uploads: Option<tokio::task::JoinHandle<()>>,
}

impl Server {
    /// Loads the models, opens the job store (jobs left running become `interrupted`), starts
    /// the workers and binds. Port 0 picks a free port (see [`Server::addr`]).
    ///
    /// A boxed future, made here: an `async fn`'s body (and every task it spawns) is compiled
    /// again in each crate that awaits it; behind `dyn Future` it is compiled once, in this
    /// library (measured with `cargo llvm-lines`: a test crate that starts a server, 256 771 →
    /// 7 858 lines of LLVM IR, 8.9 → 1.1 s to compile at opt-level 3).
    pub fn start(cfg: Config) -> BoxFuture<'static, Result<Server, ServerError>> {
        Box::pin(Self::start_here(cfg))
    }

    async fn start_here(cfg: Config) -> Result<Server, ServerError> {
        cfg.validate()?;
        std::fs::create_dir_all(&cfg.data_dir)?;
        let c2 = cfg.clone();
        let catalog = tokio::task::spawn_blocking(move || -> Result<_, ServerError> {
            Ok(Catalog::load(&c2.robots_dir, &c2.scenes_dir, &c2.data_dir)?)
        })
        .await
        .map_err(|e| ServerError::Config(format!("start-up task: {e}")))??;
        let store: Arc<dyn JobStore> = match cfg.store.as_deref() {
            Some(url) => Arc::new(
                PgStore::connect(
                    url,
                    PgOptions {
                        pool_size: cfg.store_pool,
                        ..PgOptions::default()
                    },
                )
                .await?,
            ),
            None => {
                let path = cfg.data_dir.join("jobs.redb");
                Arc::new(
                    tokio::task::spawn_blocking(move || EmbeddedStore::open(&path))
                        .await
                        .map_err(|e| ServerError::Config(format!("start-up task: {e}")))??,
                )
            }
        };
        if store.backend() != "embedded" {
            catalog.set_cache_tier(Arc::new(shared::StoreTier {
                store: store.clone(),
                rt: tokio::runtime::Handle::current(),
            }));
        }
        let metrics = Arc::new(Metrics::default());
        // Jobs claimed here that another replica accepted (or that a restart left queued) are
        // prepared again from their stored request, against this replica's catalog.
        let state_cell: Arc<std::sync::OnceLock<std::sync::Weak<AppState>>> =
            Arc::new(std::sync::OnceLock::new());
        let cell = state_cell.clone();
        let rt = tokio::runtime::Handle::current();
        let preparer: jobs::Preparer = Arc::new(move |req| {
            let st = cell
                .get()
                .and_then(std::sync::Weak::upgrade)
                .ok_or_else(|| {
                    ApiError::unavailable("shutting_down", "the server is stopping", 5)
                })?;
            match kinds::prepare(req, &st.catalog, st.cfg.max_plan_seconds) {
                // A robot or scene uploaded through another replica whose notice has not
                // arrived yet: read the store, then try again.
                Err(e)
                    if e.status == StatusCode::NOT_FOUND
                        && st.jobs.store().backend() != "embedded" =>
                {
                    let _ = rt.block_on(shared::sync_all(&st));
                    kinds::prepare(req, &st.catalog, st.cfg.max_plan_seconds)
                }
                r => r,
            }
        });
        let jobs = Jobs::start(
            RunnerConfig {
                workers: cfg.workers,
                planner_nice: cfg.planner_nice,
                max_queue: cfg.max_queue,
                retention: cfg.retention,
                max_result_bytes: cfg.max_result_bytes,
                replica: cfg.replica.clone(),
                lease: cfg.lease,
            },
            store,
            preparer,
            metrics.clone(),
        )
        .await?;
        let pool = CpuPool::new(PoolConfig {
            light_threads: cfg.query_threads,
            light_max_in_flight: cfg.query_threads * 256,
            heavy_threads: cfg.heavy_threads,
            heavy_max_in_flight: cfg.max_heavy,
            heavy_nice: cfg.planner_nice.min(HEAVY_NICE),
        })
        .map_err(ServerError::Config)?;
        let listener = tokio::net::TcpListener::bind(cfg.bind)
            .await
            .map_err(|source| ServerError::Bind {
                addr: cfg.bind,
                source,
            })?;
        let addr = listener.local_addr()?;
        let state = Arc::new(AppState {
            cfg,
            catalog,
            jobs,
            metrics,
            pool,
            shutting_down: AtomicBool::new(false),
            applied: shared::Applied::default(),
        });
        if let Err(e) = shared::sync_all(&state).await {
            tracing::warn!(error = %e.message, "cannot load the shared uploads now; they load as notices arrive");
        }
        let uploads = shared::spawn_listener(&state);
        let _ = state_cell.set(Arc::downgrade(&state));
        let (robots, scenes) = state.catalog.counts();
        tracing::info!(%addr, robots, scenes, workers = state.cfg.workers, max_queue = state.cfg.max_queue,
            data_dir = %state.cfg.data_dir.display(), store = state.jobs.store().backend(),
            replica = %state.cfg.replica, "manyhands server listening");
        let (stop_tx, stop_rx) = watch::channel(false);
        let app = router(state.clone());
        let serve = tokio::spawn(serve_http1(
            listener,
            app,
            state.cfg.header_timeout,
            stop_rx,
        ));
        Ok(Server {
            addr,
            state,
            stop_tx,
            serve,
            uploads,
        })
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn state(&self) -> &Arc<AppState> {
        &self.state
    }

    /// Graceful shutdown (drain): `/readyz` answers 503 and new jobs 503 + `Retry-After` at once,
    /// queued jobs stay queued in the store, running ones get the grace period to finish while the
    /// listener stays open (`/healthz`, `GET`, the jobs' event streams keep working) for at least
    /// the drain time; then the listener closes, open connections get 5 s, the store is closed.
    ///
    /// A boxed future, as [`Server::start`]'s.
    pub fn shutdown(self) -> BoxFuture<'static, Result<(), ServerError>> {
        Box::pin(self.shutdown_here())
    }

    async fn shutdown_here(self) -> Result<(), ServerError> {
        tracing::info!("shutting down: draining");
        let t0 = tokio::time::Instant::now();
        self.state.shutting_down.store(true, Ordering::SeqCst);
        if let Some(u) = &self.uploads {
            u.abort();
        }
        let jobs = self.state.jobs.clone();
        let grace = self.state.cfg.shutdown_grace;
        jobs.shutdown(grace).await;
        tokio::time::sleep_until(t0 + self.state.cfg.drain.min(grace)).await;
        tracing::info!("closing the listener");
        let _ = self.stop_tx.send(true);
        match tokio::time::timeout(Duration::from_secs(5), self.serve).await {
            Ok(Ok(r)) => r?,
            Ok(Err(e)) => tracing::error!(error = %e, "server task failed"),
            Err(_) => tracing::warn!("connections still open after 5 s; closing"),
        }
        tracing::info!("stopped");
        Ok(())
    }
}

/// Runs until SIGINT or SIGTERM, then shuts down gracefully.
pub async fn run(cfg: Config) -> Result<(), ServerError> {
    let server = Server::start(cfg).await?;
    shutdown_signal().await;
    server.shutdown().await
}

async fn shutdown_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => tracing::info!("SIGINT received"),
        _ = term => tracing::info!("SIGTERM received"),
    }
}
