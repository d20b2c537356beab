//! `manyhands serve`: the HTTP/JSON planning server (see `manyhands::server`).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::Args;

use manyhands::server::{self, Config};

use super::commands::Ctx;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// Address to listen on. A non-loopback address requires --token.
    #[arg(long, env = "MANYHANDS_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// Job store (jobs.redb) and uploaded robots/scenes.
    #[arg(long, env = "MANYHANDS_DATA_DIR", default_value = "./data")]
    pub data_dir: PathBuf,
    /// Planner worker threads (default: number of cores).
    #[arg(long, env = "MANYHANDS_WORKERS")]
    pub workers: Option<usize>,
    /// Threads for synchronous queries (FK, IK, check; default: number of cores).
    #[arg(long, env = "MANYHANDS_QUERY_THREADS")]
    pub query_threads: Option<usize>,
    /// Threads for expensive synchronous queries (grasp quality, randomized IK searches,
    /// uploads; default: half the cores), at a lower priority than --query-threads.
    #[arg(long, env = "MANYHANDS_HEAVY_THREADS")]
    pub heavy_threads: Option<usize>,
    /// Expensive queries queued or running before they are answered 503 + Retry-After
    /// (default: 2 × --heavy-threads).
    #[arg(long, env = "MANYHANDS_MAX_HEAVY")]
    pub max_heavy: Option<usize>,
    /// Nice levels 0–19 of the planner threads below the process's own priority (Linux; at
    /// most nice 19), so synchronous queries keep their latency while jobs run; 0 runs jobs
    /// at the queries' priority.
    #[arg(long, env = "MANYHANDS_PLANNER_NICE", default_value_t = 10)]
    pub planner_nice: i32,
    /// Jobs waiting for a worker before POST /v1/plans answers 429.
    #[arg(long, env = "MANYHANDS_MAX_QUEUE", default_value_t = 64)]
    pub max_queue: usize,
    /// Cap of every job's time limit, seconds.
    #[arg(long, env = "MANYHANDS_MAX_PLAN_SECONDS", default_value_t = 60.0)]
    pub max_plan_seconds: f64,
    /// Bearer token required on /v1 (health, readiness and metrics stay open).
    #[arg(long, env = "MANYHANDS_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Request body limit in bytes.
    #[arg(long, env = "MANYHANDS_MAX_BODY", default_value_t = 2 * 1024 * 1024)]
    pub max_body: usize,
    /// Seconds a client may take to send a request's headers (also the longest a kept-alive
    /// connection stays idle); then the connection is closed.
    #[arg(long, env = "MANYHANDS_HEADER_TIMEOUT", default_value_t = 15.0)]
    pub header_timeout: f64,
    /// Seconds a client may take to send a request's body after its headers; then the request
    /// is answered 408 and the connection closed.
    #[arg(long, env = "MANYHANDS_BODY_TIMEOUT", default_value_t = 20.0)]
    pub body_timeout: f64,
    /// Finished jobs older than this many hours are deleted.
    #[arg(long, env = "MANYHANDS_RETENTION_HOURS", default_value_t = 168.0)]
    pub retention_hours: f64,
    /// Seconds running jobs get to finish at shutdown before they are interrupted.
    #[arg(long, env = "MANYHANDS_SHUTDOWN_GRACE", default_value_t = 10.0)]
    pub shutdown_grace: f64,
    /// Seconds the listener stays open at shutdown at least (capped by --shutdown-grace), with
    /// /readyz answering 503, so a load balancer sees the drain before connections fail.
    #[arg(long, env = "MANYHANDS_DRAIN", default_value_t = 5.0)]
    pub drain: f64,
    /// The job store shared by every replica: a PostgreSQL URL (`postgres://user:pass@host:5432/db`).
    /// Without it, jobs, results, events and uploads live in the embedded store under --data-dir.
    #[arg(long, env = "MANYHANDS_STORE", hide_env_values = true)]
    pub store: Option<String>,
    /// This replica's name, the owner of the job leases it takes (default: host name and pid).
    /// Must differ between replicas sharing a store.
    #[arg(long, env = "MANYHANDS_REPLICA_ID")]
    pub replica_id: Option<String>,
    /// Seconds a claimed job stays this replica's without renewal (renewed every third of it).
    /// A replica that dies or stalls longer loses its jobs to the others.
    #[arg(long, env = "MANYHANDS_LEASE_SECONDS", default_value_t = 10.0)]
    pub lease_seconds: f64,
    /// Results of finished jobs kept at most, in MiB (oldest finished jobs removed first).
    #[arg(long, env = "MANYHANDS_MAX_RESULTS_MB", default_value_t = 4096)]
    pub max_results_mb: u64,
    /// Connections to the shared store (PostgreSQL) per replica.
    #[arg(long, env = "MANYHANDS_STORE_POOL", default_value_t = 8)]
    pub store_pool: usize,
    /// Log format: `text` or `json`.
    #[arg(long, env = "MANYHANDS_LOG_FORMAT", default_value = "text")]
    pub log_format: String,
    /// Log filter (tracing EnvFilter syntax, e.g. `info`, `manyhands=debug`).
    #[arg(long, env = "MANYHANDS_LOG", default_value = "info")]
    pub log: String,
    /// Print the OpenAPI spec and exit.
    #[arg(long)]
    pub print_openapi: bool,
    /// Check the configuration (flags and MANYHANDS_* environment) and the built-in robots and
    /// scenes, say what would be served (and whether this binary has the 3-D viewer), and exit
    /// without binding: 0 when `serve` would start, 2 when it would refuse.
    #[arg(long)]
    pub check: bool,
}

fn seconds(name: &str, v: f64) -> Result<Duration> {
    if !(v.is_finite() && v >= 0.0) {
        bail!("--{name}: '{v}' is not a number of seconds ≥ 0");
    }
    Ok(Duration::from_secs_f64(v))
}

pub fn init_tracing(format: &str, filter: &str) -> Result<()> {
    use tracing_subscriber::EnvFilter;
    let filter =
        EnvFilter::try_new(filter).with_context(|| format!("--log: bad filter '{filter}'"))?;
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    let r = match format {
        "json" => builder
            .json()
            .flatten_event(true)
            .with_current_span(false)
            .try_init(),
        // Colours only on a terminal (a redirected log stays plain text).
        "text" => builder
            .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
            .try_init(),
        f => bail!("--log-format: '{f}' is not 'text' or 'json'"),
    };
    // Already initialised (tests): keep the existing subscriber.
    let _ = r;
    Ok(())
}

/// `serve --check`: what `serve` would load and serve, without binding or writing.
fn check(cfg: &Config) -> Result<()> {
    let lib = manyhands::model::load_robot_dir(&cfg.robots_dir)
        .with_context(|| format!("robots in {}", cfg.robots_dir.display()))?;
    let (scenes, bad) = manyhands::model::load_scene_dir_lenient(&cfg.scenes_dir, &lib)
        .with_context(|| format!("scenes in {}", cfg.scenes_dir.display()))?;
    for (_, e) in &bad {
        eprintln!("scene not loaded (serve leaves it out): {e}");
    }
    let viewer = if server::viewer::built() {
        "built".to_string()
    } else {
        format!("NOT built ({})", server::viewer::not_built_reason())
    };
    println!(
        "ok: would serve on {} ({}), data in {}, {} robots from {}, {} scenes from {}, viewer {viewer}",
        cfg.bind,
        if cfg.token.is_some() { "token required" } else { "no token" },
        cfg.data_dir.display(),
        lib.len(),
        cfg.robots_dir.display(),
        scenes.len(),
        cfg.scenes_dir.display(),
    );
    Ok(())
}

pub fn run(ctx: &Ctx, a: &ServeArgs) -> Result<()> {
    if a.print_openapi {
        print!("{}", server::openapi::openapi_json());
        return Ok(());
    }
    init_tracing(&a.log_format, &a.log)?;
    let mut cfg = Config::new(a.bind, a.data_dir.clone());
    cfg.robots_dir = ctx.robots_dir.clone();
    cfg.scenes_dir = ctx.scenes_dir.clone();
    if let Some(w) = a.workers {
        cfg.workers = w;
    }
    if let Some(q) = a.query_threads {
        cfg.query_threads = q;
    }
    if let Some(h) = a.heavy_threads {
        cfg.heavy_threads = h;
        cfg.max_heavy = 2 * h;
    }
    if let Some(m) = a.max_heavy {
        cfg.max_heavy = m;
    }
    cfg.planner_nice = a.planner_nice;
    cfg.max_queue = a.max_queue;
    cfg.max_plan_seconds = a.max_plan_seconds;
    cfg.token = a.token.clone().filter(|t| !t.is_empty());
    cfg.max_body = a.max_body;
    cfg.header_timeout = seconds("header-timeout", a.header_timeout)?;
    cfg.body_timeout = seconds("body-timeout", a.body_timeout)?;
    cfg.retention = seconds("retention-hours", a.retention_hours * 3600.0)?;
    cfg.shutdown_grace = seconds("shutdown-grace", a.shutdown_grace)?;
    cfg.drain = seconds("drain", a.drain)?;
    cfg.store = a.store.clone().filter(|s| !s.is_empty());
    if let Some(r) = a.replica_id.clone().filter(|r| !r.is_empty()) {
        cfg.replica = r;
    }
    cfg.lease = seconds("lease-seconds", a.lease_seconds)?;
    cfg.max_result_bytes = a.max_results_mb.saturating_mul(1 << 20);
    if a.store_pool == 0 {
        bail!("--store-pool must be ≥ 1");
    }
    cfg.store_pool = a.store_pool;
    cfg.validate()?;
    if a.check {
        return check(&cfg);
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("manyhands-io")
        // An I/O thread going idle returns the memory it freed (at most once a second): large
        // results pass through these threads (database buffers, answers), and the allocator
        // would otherwise keep their pages on the thread.
        .on_thread_park(|| {
            thread_local!(static LAST: std::cell::Cell<Option<std::time::Instant>> =
                const { std::cell::Cell::new(None) });
            LAST.with(|l| {
                let now = std::time::Instant::now();
                if l.get()
                    .is_none_or(|t| now.duration_since(t) >= Duration::from_secs(1))
                {
                    l.set(Some(now));
                    server::store::release_freed_memory();
                }
            });
        })
        .build()
        .context("starting the async runtime")?;
    rt.block_on(server::run(cfg))?;
    Ok(())
}
