//! The CPU pool of synchronous queries (FK, IK, collision checks, upload validation): a rayon
//! pool with a bound on the work in flight, so the async runtime threads only do I/O and an
//! overload is answered with 503 instead of an ever-growing backlog.

use std::sync::Arc;

use tokio::sync::{oneshot, Semaphore};

use super::error::{ApiError, ApiResult};

pub struct CpuPool {
    pool: rayon::ThreadPool,
    permits: Arc<Semaphore>,
}

impl CpuPool {
    /// `threads` workers; at most `max_in_flight` queries queued or running.
    pub fn new(threads: usize, max_in_flight: usize) -> Result<CpuPool, String> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads.max(1))
            .thread_name(|i| format!("manyhands-query-{i}"))
            .build()
            .map_err(|e| e.to_string())?;
        Ok(CpuPool {
            pool,
            permits: Arc::new(Semaphore::new(max_in_flight.max(1))),
        })
    }

    /// Runs `f` on the pool and awaits its answer. A panic in `f` is a 500; a full pool a 503.
    pub async fn run<T, F>(&self, f: F) -> ApiResult<T>
    where
        T: Send + 'static,
        F: FnOnce() -> ApiResult<T> + Send + 'static,
    {
        let permit = self.permits.clone().try_acquire_owned().map_err(|_| {
            ApiError::unavailable("overloaded", "too many queries in flight; retry shortly", 1)
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
