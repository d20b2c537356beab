//! The CPU pools of synchronous queries, in two lanes so cheap queries never queue behind
//! expensive ones:
//!
//! * the **light** lane (FK, IK, collision checks, plan validation, deletions) — microseconds to
//!   milliseconds per request;
//! * the **heavy** lane (grasp quality, randomized grasp / dual-arm / base-placement IK, robot
//!   and scene uploads) — up to seconds per request, on its own threads at a lower scheduling
//!   priority (Linux nice, per thread), so it never takes the light lane's threads and yields
//!   the CPU to them.
//!
//! Each lane bounds the work queued or running in it; a full lane answers 503 with
//! `Retry-After` at once instead of growing a backlog that ends in client timeouts.

use std::sync::Arc;

use tokio::sync::{oneshot, Semaphore};

use super::error::{ApiError, ApiResult};

/// One lane: a rayon pool and a bound on the work in flight.
struct Lane {
    name: &'static str,
    pool: rayon::ThreadPool,
    permits: Arc<Semaphore>,
    max_in_flight: usize,
    /// `Retry-After` (s) of a full lane.
    retry_after: u64,
}

impl Lane {
    fn new(
        name: &'static str,
        threads: usize,
        max_in_flight: usize,
        nice: i32,
        retry_after: u64,
    ) -> Result<Lane, String> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .thread_name(move |i| format!("manyhands-{name}-{i}"))
            .start_handler(move |_| super::jobs::lower_thread_priority(nice))
            .build()
            .map_err(|e| e.to_string())?;
        Ok(Lane {
            name,
            pool,
            permits: Arc::new(Semaphore::new(max_in_flight.max(1))),
            max_in_flight: max_in_flight.max(1),
            retry_after,
        })
    }

    async fn run<T, F>(&self, f: F) -> ApiResult<T>
    where
        T: Send + 'static,
        F: FnOnce() -> ApiResult<T> + Send + 'static,
    {
        let permit = self.permits.clone().try_acquire_owned().map_err(|_| {
            ApiError::unavailable(
                "overloaded",
                format!(
                    "{} {} queries are queued or running (the bound of that lane); retry after {} s",
                    self.max_in_flight, self.name, self.retry_after
                ),
                self.retry_after,
            )
        })?;
        let (tx, rx) = oneshot::channel();
        self.pool.spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
            drop(permit);
            let _ = tx.send(r);
        });
        match rx.await {
            Ok(Ok(r)) => r,
            Ok(Err(panic)) => {
                let msg = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "panic".into());
                Err(ApiError::internal(format!("query panicked: {msg}")))
            }
            Err(_) => Err(ApiError::internal("query worker vanished")),
        }
    }
}

/// Sizes of the two lanes.
#[derive(Debug, Clone, Copy)]
pub struct PoolConfig {
    pub light_threads: usize,
    pub light_max_in_flight: usize,
    pub heavy_threads: usize,
    pub heavy_max_in_flight: usize,
    /// Nice levels of the heavy lane's threads above the process's own (0 = the light lane's
    /// priority).
    pub heavy_nice: i32,
}

pub struct CpuPool {
    light: Lane,
    heavy: Lane,
}

impl CpuPool {
    pub fn new(c: PoolConfig) -> Result<CpuPool, String> {
        Ok(CpuPool {
            light: Lane::new("query", c.light_threads, c.light_max_in_flight, 0, 1)?,
            heavy: Lane::new(
                "heavy",
                c.heavy_threads,
                c.heavy_max_in_flight,
                c.heavy_nice,
                2,
            )?,
        })
    }

    /// Runs a cheap query (FK, IK, check, validation) on the light lane and awaits its answer.
    /// A panic in `f` is a 500; a full lane a 503.
    pub async fn run<T, F>(&self, f: F) -> ApiResult<T>
    where
        T: Send + 'static,
        F: FnOnce() -> ApiResult<T> + Send + 'static,
    {
        self.light.run(f).await
    }

    /// Runs an expensive query (grasp quality, randomized IK searches, uploads) on the heavy
    /// lane. A panic in `f` is a 500; a full lane a 503 with `Retry-After`.
    pub async fn run_heavy<T, F>(&self, f: F) -> ApiResult<T>
    where
        T: Send + 'static,
        F: FnOnce() -> ApiResult<T> + Send + 'static,
    {
        self.heavy.run(f).await
    }
}
