//! The job runner: `workers` planner threads (never the async runtime's) that claim jobs from
//! the job store's queue, run them under a lease they renew, and write progress and the final
//! state through the job's fence. The store is the single source of truth: this module keeps
//! in memory only what the jobs running here need (stop flags, fences) and, until a planner
//! thread here claims it, the work a submission through this replica already prepared.
//!
//! With a shared store (PostgreSQL) any replica's thread may claim a job another replica
//! accepted: it prepares the work again from the stored request. A replica that dies leaves
//! its leases to run out; any replica's reaper then queues those jobs again (while the request
//! allows another attempt) or records them `interrupted`.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use rand::Rng;
use serde_json::value::RawValue;
use serde_json::Value;
use tokio::runtime::Handle;
use tokio::sync::broadcast;

use super::api::{Job, JobState, PlanRequest};
use super::builds::Builds;
use super::error::{ApiError, ApiResult};
use super::kinds::{JobContext, JobFailure, Prepared};
use super::metrics::Metrics;
use super::store::{
    CancelResult, Claimed, Counts, Enqueued, Fence, JobStore, NewJob, Notice, Outcome, Renewal,
    RetentionPolicy, StoreError, StoredJob,
};
use manyhands_api::ErrorDetail;

pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The process's own nice value (its main thread's: `nice -n 10 manyhands serve` gives 10),
/// the base the lanes' and planner threads' priorities are relative to.
pub(crate) fn process_nice() -> i32 {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: getpid and getpriority take no pointers. getpriority may return -1 as a
        // value, so errno is cleared before and read after.
        unsafe {
            *libc::__errno_location() = 0;
            let n = libc::getpriority(libc::PRIO_PROCESS, libc::getpid() as libc::id_t);
            if n == -1 && *libc::__errno_location() != 0 {
                return 0;
            }
            n
        }
    }
    #[cfg(not(target_os = "linux"))]
    0
}

/// Sets the calling thread's nice value to the process's own plus `delta` (at most 19; Linux:
/// the nice value is per thread), so planner threads yield the CPU to the synchronous-query
/// pool and the I/O threads whatever nice value the server was started with. Threads it
/// spawns inherit it. A failure only costs the priority, so it is logged, not fatal.
pub(crate) fn lower_thread_priority(delta: i32) {
    if delta <= 0 {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let nice = process_nice().saturating_add(delta).min(19);
        // SAFETY: gettid and setpriority take no pointers; raising one's own nice value needs
        // no privilege.
        let r = unsafe {
            let tid = libc::gettid();
            libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, nice)
        };
        if r != 0 {
            tracing::warn!(
                nice,
                error = %std::io::Error::last_os_error(),
                "cannot lower the planner thread's priority"
            );
        }
    }
    #[cfg(not(target_os = "linux"))]
    tracing::debug!(delta, "planner thread priority is left as it is on this OS");
}

/// Prepares the work of a stored request again (a job claimed on a replica other than the one
/// that accepted it, or after a restart).
pub type Preparer = Arc<dyn Fn(&PlanRequest) -> ApiResult<Prepared> + Send + Sync>;

/// Settings of the runner.
#[derive(Debug, Clone)]
pub struct RunnerConfig {
    pub workers: usize,
    /// Nice value of the planner threads above the process's own (see `Config::planner_nice`).
    pub planner_nice: i32,
    /// Queued jobs (cluster-wide) before 429.
    pub max_queue: usize,
    pub retention: Duration,
    /// Results kept at most (bytes, all finished jobs); the oldest go first.
    pub max_result_bytes: u64,
    /// This replica's name (the owner of the leases it takes).
    pub replica: String,
    /// How long a claim holds without renewal.
    pub lease: Duration,
}

/// A job running on this replica.
struct Local {
    fence: Fence,
    kind: String,
    stop: Arc<AtomicBool>,
    /// Set at shutdown: a job stopped by its flag then ends `interrupted`, not `cancelled`.
    interrupt: AtomicBool,
    /// The lease was lost: nothing more is written.
    lost: AtomicBool,
    /// The planner returned and its end is being written: a renewal that finds the job no
    /// longer running raced that write, and is not a lost lease.
    finishing: AtomicBool,
}

/// Gauges kept fresh by the maintenance task (health and readiness never wait on the store).
#[derive(Default)]
struct Cached {
    counts: Counts,
    queue_depth: usize,
}

pub struct Jobs {
    cfg: RunnerConfig,
    store: Arc<dyn JobStore>,
    rt: Handle,
    prepare: Preparer,
    metrics: Arc<Metrics>,
    /// Work prepared at submission on this replica, until a thread claims the job.
    prepared: Mutex<HashMap<String, Prepared>>,
    local: Mutex<HashMap<String, Arc<Local>>>,
    /// Bumped when there may be queued work (local submit, a notice, a reaped lease).
    wake: Mutex<u64>,
    wake_cv: Condvar,
    closed: AtomicBool,
    running: AtomicUsize,
    threads: Mutex<Vec<JoinHandle<()>>>,
    cached: Mutex<Cached>,
    /// Was the store reachable at the last check?
    reachable: AtomicBool,
    /// Unix ms of the last successful store call of the maintenance task.
    last_ok_ms: AtomicU64,
    tasks: Mutex<Vec<tokio::task::JoinHandle<()>>>,
    /// First-use builds (grids, grasp lists, roadmaps) the jobs here wait for.
    builds: Arc<Builds>,
}

impl Jobs {
    /// Starts the runner on `store`: the planner threads, the lease keeper, the notice listener
    /// and the maintenance task (reaper, retention, gauges). With an embedded store, every job
    /// left running by the previous process is reaped at once (queued again while attempts
    /// remain, else `interrupted`); jobs left queued run.
    pub async fn start(
        cfg: RunnerConfig,
        store: Arc<dyn JobStore>,
        prepare: Preparer,
        metrics: Arc<Metrics>,
    ) -> Result<Arc<Jobs>, StoreError> {
        if store.backend() == "embedded" {
            let r = store.reap(now_ms(), true).await?;
            if !r.interrupted.is_empty() || !r.requeued.is_empty() {
                tracing::warn!(
                    interrupted = r.interrupted.len(),
                    requeued = r.requeued.len(),
                    "jobs left running by the previous process"
                );
            }
        }
        let jobs = Arc::new(Jobs {
            cfg: cfg.clone(),
            store,
            rt: Handle::current(),
            prepare,
            metrics,
            prepared: Mutex::new(HashMap::new()),
            local: Mutex::new(HashMap::new()),
            wake: Mutex::new(0),
            wake_cv: Condvar::new(),
            closed: AtomicBool::new(false),
            running: AtomicUsize::new(0),
            threads: Mutex::new(Vec::new()),
            cached: Mutex::new(Cached::default()),
            reachable: AtomicBool::new(true),
            last_ok_ms: AtomicU64::new(now_ms()),
            tasks: Mutex::new(Vec::new()),
            builds: Arc::new(Builds::new(cfg.planner_nice)),
        });
        jobs.refresh_gauges().await;
        let mut threads = lock(&jobs.threads);
        for i in 0..cfg.workers.max(1) {
            let j = jobs.clone();
            let nice = cfg.planner_nice;
            let h = std::thread::Builder::new()
                .name(format!("manyhands-planner-{i}"))
                .spawn(move || {
                    lower_thread_priority(nice);
                    j.worker()
                })
                .map_err(|e| StoreError::Other(format!("cannot start a planner thread: {e}")))?;
            threads.push(h);
        }
        drop(threads);
        let mut tasks = lock(&jobs.tasks);
        tasks.push(tokio::spawn(jobs.clone().listen()));
        tasks.push(tokio::spawn(jobs.clone().keep_leases()));
        tasks.push(tokio::spawn(jobs.clone().maintain()));
        drop(tasks);
        Ok(jobs)
    }

    pub fn store(&self) -> &Arc<dyn JobStore> {
        &self.store
    }

    pub fn config(&self) -> &RunnerConfig {
        &self.cfg
    }

    /// Queued jobs (cluster-wide) at the last refresh.
    pub fn queue_depth(&self) -> usize {
        lock(&self.cached).queue_depth
    }

    pub fn counts_by_state(&self) -> BTreeMap<&'static str, usize> {
        let c = lock(&self.cached);
        if c.counts.by_state.is_empty() {
            return JobState::ALL.iter().map(|s| (s.name(), 0)).collect();
        }
        c.counts.by_state.clone()
    }

    pub fn result_bytes(&self) -> u64 {
        lock(&self.cached).counts.result_bytes
    }

    /// Was the store reachable at the last check (at most a second ago)?
    pub fn store_reachable(&self) -> bool {
        self.reachable.load(Ordering::SeqCst)
    }

    /// First-use builds running in this process (see [`super::builds`]).
    pub fn builds_running(&self) -> usize {
        self.builds.running()
    }

    /// Jobs running on this replica.
    pub fn running_here(&self) -> usize {
        self.running.load(Ordering::SeqCst)
    }

    fn wake_workers(&self, all: bool) {
        *lock(&self.wake) += 1;
        if all {
            self.wake_cv.notify_all();
        } else {
            self.wake_cv.notify_one();
        }
    }

    /// Accepts a prepared job: the record is committed to the store before this returns (the
    /// client's 202 comes after); 429 when the queue (cluster-wide) is full, 503 when shutting
    /// down or when the store cannot be reached.
    pub async fn submit(
        &self,
        kind: &str,
        request: Value,
        prepared: Prepared,
        warnings: Vec<String>,
        priority: i32,
        max_attempts: u32,
    ) -> ApiResult<Job> {
        if self.closed.load(Ordering::SeqCst) {
            return Err(shutting_down());
        }
        let id = format!("j{:016x}", rand::rng().random::<u64>());
        let job = Job {
            id: id.clone(),
            kind: kind.to_string(),
            state: JobState::Queued,
            created_ms: now_ms(),
            started_ms: None,
            finished_ms: None,
            time_limit: prepared.time_limit,
            request,
            progress: None,
            result: None,
            error: None,
            warnings,
            attempt: Some(0),
            max_attempts: Some(max_attempts),
            priority: Some(priority),
            replica: None,
        };
        // Kept before the enqueue: a thread here may claim the job as soon as it is committed.
        lock(&self.prepared).insert(id.clone(), prepared);
        let r = self
            .store
            .enqueue(
                &NewJob {
                    job: job.clone(),
                    priority,
                    max_attempts,
                },
                self.cfg.max_queue,
            )
            .await;
        match r {
            Ok(Enqueued::Accepted) => {
                self.wake_workers(false);
                tracing::info!(job = %id, kind, "job queued");
                Ok(job)
            }
            Ok(Enqueued::QueueFull { depth }) => {
                lock(&self.prepared).remove(&id);
                Err(ApiError::queue_full(
                    1 + (depth / self.cfg.workers.max(1)) as u64,
                ))
            }
            Err(e) => {
                lock(&self.prepared).remove(&id);
                Err(store_error(e))
            }
        }
    }

    /// The job as stored.
    pub async fn get(&self, id: &str) -> ApiResult<Option<StoredJob>> {
        self.store.get(id).await.map_err(store_error)
    }

    /// Waits until the job is final or `d` passes; the job as stored then. `None`: no such job.
    pub async fn wait_final(&self, id: &str, d: Duration) -> ApiResult<Option<StoredJob>> {
        let deadline = tokio::time::Instant::now() + d;
        let mut rx = self.store.subscribe();
        loop {
            let Some(j) = self.get(id).await? else {
                return Ok(None);
            };
            if j.job.state.is_final() || tokio::time::Instant::now() >= deadline {
                return Ok(Some(j));
            }
            wait_notice(&mut rx, id, deadline).await;
        }
    }

    /// Cancels a job: a queued one at once; a running one is stopped by the replica that runs
    /// it (told through the store), and recorded `cancelled` here if it has not ended within
    /// `wait`. Final jobs are left as they are. `None`: no such job.
    pub async fn cancel(&self, id: &str, wait: Duration) -> ApiResult<Option<StoredJob>> {
        let r = self.store.cancel(id, now_ms()).await.map_err(store_error)?;
        match r {
            None => return Ok(None),
            Some(CancelResult::CancelledQueued) => {
                lock(&self.prepared).remove(id);
                let j = self.get(id).await?;
                let kind = j.as_ref().map(|j| j.job.kind.as_str()).unwrap_or("");
                self.metrics.record_job(kind, "cancelled", None);
                tracing::info!(job = %id, state = "cancelled", "job finished");
                return Ok(j);
            }
            Some(CancelResult::Requested { .. }) => {
                let here = lock(&self.local).get(id).cloned();
                if let Some(l) = &here {
                    l.stop.store(true, Ordering::SeqCst);
                }
                let j = self.wait_final(id, wait).await?;
                if j.is_some_and(|j| !j.job.state.is_final()) {
                    let interrupted = here
                        .as_ref()
                        .is_some_and(|l| l.interrupt.load(Ordering::SeqCst));
                    let outcome = if interrupted {
                        interrupted_outcome("the server shut down while the job was running")
                    } else {
                        super::store::embedded::cancelled_running(now_ms())
                    };
                    if self
                        .store
                        .finish(id, None, &outcome)
                        .await
                        .map_err(store_error)?
                    {
                        let kind = here.as_ref().map(|l| l.kind.clone()).unwrap_or_default();
                        self.metrics.record_job(&kind, outcome.state.name(), None);
                        tracing::info!(job = %id, state = outcome.state.name(), "job finished");
                    }
                }
            }
            Some(CancelResult::AlreadyFinal) => {}
        }
        self.get(id).await
    }

    fn worker(self: Arc<Self>) {
        let mut failures = 0u32;
        loop {
            if self.closed.load(Ordering::SeqCst) {
                return;
            }
            let seen = *lock(&self.wake);
            let (store, owner, lease) =
                (self.store.clone(), self.cfg.replica.clone(), self.cfg.lease);
            let claimed = self.on_runtime(async move { store.claim(&owner, lease).await });
            match claimed {
                Ok(Some(c)) => {
                    failures = 0;
                    self.running.fetch_add(1, Ordering::SeqCst);
                    self.run_one(c);
                    self.running.fetch_sub(1, Ordering::SeqCst);
                    super::store::release_freed_memory();
                }
                Ok(None) => {
                    failures = 0;
                    // Sleep until woken (local submit, a notice) or a second passes (notices
                    // can be missed while a shared store's listener reconnects).
                    let g = lock(&self.wake);
                    if *g == seen && !self.closed.load(Ordering::SeqCst) {
                        let _ = self
                            .wake_cv
                            .wait_timeout(g, Duration::from_secs(1))
                            .unwrap_or_else(|p| p.into_inner());
                    }
                }
                Err(e) => {
                    failures += 1;
                    if failures == 1 || failures % 20 == 0 {
                        tracing::warn!(error = %e, "cannot claim a job; retrying");
                    }
                    let g = lock(&self.wake);
                    if !self.closed.load(Ordering::SeqCst) {
                        let _ = self
                            .wake_cv
                            .wait_timeout(g, Duration::from_millis(250))
                            .unwrap_or_else(|p| p.into_inner());
                    }
                }
            }
        }
    }

    /// Runs a store call of a planner thread as a task of the async runtime and waits for it.
    /// The call's work (the embedded store's blocking section, PostgreSQL's round trips) then
    /// runs on the runtime's threads, at their priority: polled here, each step would wait for
    /// this lower-priority thread to be scheduled, and a thread the blocking pool starts for it
    /// would inherit this thread's nice value and keep it for every later request it serves.
    fn on_runtime<T: Send + 'static>(
        &self,
        call: impl std::future::Future<Output = Result<T, StoreError>> + Send + 'static,
    ) -> Result<T, StoreError> {
        self.rt
            .block_on(self.rt.spawn(call))
            .unwrap_or_else(|e| Err(StoreError::Other(format!("store task: {e}"))))
    }

    fn run_one(&self, c: Claimed) {
        let Claimed { job, fence, .. } = c;
        let id = job.id.clone();
        let local = Arc::new(Local {
            fence: fence.clone(),
            kind: job.kind.clone(),
            stop: Arc::new(AtomicBool::new(false)),
            interrupt: AtomicBool::new(false),
            lost: AtomicBool::new(false),
            finishing: AtomicBool::new(false),
        });
        lock(&self.local).insert(id.clone(), local.clone());
        if self.closed.load(Ordering::SeqCst) {
            local.interrupt.store(true, Ordering::SeqCst);
            local.stop.store(true, Ordering::SeqCst);
        }
        tracing::info!(job = %id, kind = %job.kind, attempt = fence.attempt, "job running");
        let prepared = match lock(&self.prepared).remove(&id) {
            Some(p) => Ok(p),
            None => serde_json::from_value::<PlanRequest>(job.request.clone())
                .map_err(|e| ApiError::invalid("", e.to_string()))
                .and_then(|req| (self.prepare)(&req)),
        };
        let outcome = match prepared {
            Err(e) => {
                let d = e.detail();
                Outcome {
                    state: JobState::Failed,
                    result: None,
                    error: Some(d),
                    progress: None,
                    finished_ms: now_ms(),
                }
            }
            Ok(p) => self.execute(&job, &local, p),
        };
        let secs = job
            .started_ms
            .map(|s| outcome.finished_ms.saturating_sub(s) as f64 / 1e3);
        local.finishing.store(true, Ordering::SeqCst);
        // Stopped by this replica's shutdown: the job goes back to the queue (another replica,
        // or this one after its restart, runs it again), unless its cancel was asked for.
        if outcome.state == JobState::Interrupted && local.interrupt.load(Ordering::SeqCst) {
            let (store, fence) = (self.store.clone(), local.fence.clone());
            match self.on_runtime(async move { store.release(&fence).await }) {
                Ok(true) => {
                    tracing::info!(job = %id, "job given back to the queue at shutdown");
                    lock(&self.local).remove(&id);
                    return;
                }
                Ok(false) => {}
                Err(e) => tracing::warn!(job = %id, error = %e, "cannot give the job back"),
            }
        }
        self.finish_fenced(&local, &Arc::new(outcome), secs);
        lock(&self.local).remove(&id);
    }

    /// Runs the work with its stop flag, time limit and progress going to the store.
    fn execute(&self, job: &Job, local: &Arc<Local>, p: Prepared) -> Outcome {
        // Progress: at most every 50 ms, except that a snapshot of a new `phase` goes at once;
        // a snapshot held back by the throttle is written when the next one is due or when the
        // planner returns, so the last one is never lost. A writer task writes the latest
        // snapshot (older ones not yet written are skipped), so the planner never waits on the
        // store.
        let (ptx, mut prx) = tokio::sync::watch::channel::<Option<Value>>(None);
        let store = self.store.clone();
        let fence = local.fence.clone();
        let writer = self.rt.spawn(async move {
            // `changed` still yields a value sent just before the sender went away.
            while prx.changed().await.is_ok() {
                let v = prx.borrow_and_update().clone();
                if let Some(v) = v {
                    if let Err(e) = store.progress(&fence, &v).await {
                        tracing::debug!(job = %fence.id, error = %e, "progress not stored");
                    }
                }
            }
        });
        let held: Arc<Mutex<Option<Value>>> = Arc::new(Mutex::new(None));
        let held_in = held.clone();
        let ptx_in = ptx.clone();
        let mut last = Instant::now() - Duration::from_secs(1);
        let mut last_phase: Option<Value> = None;
        let progress = Box::new(move |v: Value| {
            let now = Instant::now();
            let phase = v.get("phase").cloned();
            if now - last >= Duration::from_millis(50) || phase != last_phase {
                last = now;
                last_phase = phase;
                lock(&held_in).take();
                ptx_in.send_replace(Some(v));
            } else {
                *lock(&held_in) = Some(v);
            }
        });
        let limit = Duration::from_secs_f64(job.time_limit.max(0.0));
        let mut ctx =
            JobContext::new(local.stop.clone(), limit, progress).with_builds(self.builds.clone());
        let started = ctx.started;
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| p.work.run(&mut ctx)));
        drop(ctx);
        if let Some(v) = lock(&held).take() {
            ptx.send_replace(Some(v));
        }
        drop(ptx);
        // The last progress is written before the final state (nothing is written after it).
        let _ = self
            .rt
            .block_on(async { tokio::time::timeout(Duration::from_secs(5), writer).await });
        let finished_ms = now_ms();
        let fail = |state: JobState, code: &str, message: String, stats: Option<Value>| Outcome {
            state,
            result: None,
            error: Some(ErrorDetail {
                code: code.to_string(),
                message,
                field: None,
            }),
            progress: stats,
            finished_ms,
        };
        match out {
            Ok(Ok(result)) => match serde_json::to_string(&result)
                .map_err(|e| e.to_string())
                .and_then(|t| RawValue::from_string(t).map_err(|e| e.to_string()))
            {
                Ok(raw) => Outcome {
                    state: JobState::Succeeded,
                    result: Some(raw),
                    error: None,
                    progress: None,
                    finished_ms,
                },
                Err(e) => fail(JobState::Failed, "internal", e, None),
            },
            Ok(Err(JobFailure {
                stopped,
                code,
                message,
                stats,
            })) => {
                if stopped && local.interrupt.load(Ordering::SeqCst) {
                    fail(
                        JobState::Interrupted,
                        "interrupted",
                        "the server shut down while the job was running".into(),
                        stats,
                    )
                } else if stopped {
                    fail(JobState::Cancelled, "cancelled", message, stats)
                } else if code == "timeout" && !message.starts_with("time limit ") {
                    // The real time since the job's start (a planner's own figures count
                    // only its step).
                    let message = format!(
                        "time limit {} s reached {:.3} s after the job started; {message}",
                        limit.as_secs_f64(),
                        started.elapsed().as_secs_f64()
                    );
                    fail(JobState::Failed, code, message, stats)
                } else {
                    fail(JobState::Failed, code, message, stats)
                }
            }
            Err(_) => {
                tracing::error!(job = %job.id, "planner panicked");
                fail(
                    JobState::Failed,
                    "internal",
                    "the planner failed unexpectedly".into(),
                    None,
                )
            }
        }
    }

    /// Writes the final state through the job's fence, retrying while the store is
    /// unreachable (the job's lease keeps it ours meanwhile); gives up when the lease is lost.
    fn finish_fenced(&self, local: &Local, outcome: &Arc<Outcome>, secs: Option<f64>) {
        let id = &local.fence.id;
        let mut wait = Duration::from_millis(50);
        let mut tries = 0u32;
        loop {
            if local.lost.load(Ordering::SeqCst) {
                tracing::warn!(job = %id, "lease lost: the job's result is not written");
                return;
            }
            let (store, fence, out) = (self.store.clone(), local.fence.clone(), outcome.clone());
            match self.on_runtime(async move { store.finish(&fence.id, Some(&fence), &out).await })
            {
                Ok(true) => {
                    self.metrics
                        .record_job(&local.kind, outcome.state.name(), secs);
                    tracing::info!(job = %id, kind = %local.kind, state = outcome.state.name(), "job finished");
                    return;
                }
                Ok(false) => {
                    tracing::info!(job = %id, "job already final or owned by another attempt; result dropped");
                    return;
                }
                Err(e) => {
                    tries += 1;
                    if tries == 1 || tries % 20 == 0 {
                        tracing::warn!(job = %id, error = %e, "cannot store the job's end; retrying");
                    }
                    std::thread::sleep(wait);
                    wait = (wait * 2).min(Duration::from_secs(1));
                }
            }
        }
    }

    /// Hears the store's notices: wakes the planner threads for queued work and stops jobs
    /// running here that another replica was asked to cancel.
    async fn listen(self: Arc<Self>) {
        let mut rx = self.store.subscribe();
        loop {
            match rx.recv().await {
                Ok(Notice::Queued) | Ok(Notice::Resync) => self.wake_workers(true),
                Ok(Notice::Cancel { id, owner }) if owner == self.cfg.replica => {
                    if let Some(l) = lock(&self.local).get(&id) {
                        l.stop.store(true, Ordering::SeqCst);
                    }
                }
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(_)) => self.wake_workers(true),
                Err(broadcast::error::RecvError::Closed) => return,
            }
        }
    }

    /// Renews the leases of the jobs running here (a third of the lease apart); a lost lease
    /// stops the job, a cancel asked for meanwhile too.
    async fn keep_leases(self: Arc<Self>) {
        let period = (self.cfg.lease / 3).max(Duration::from_millis(50));
        let mut tick = tokio::time::interval(period);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            let locals: Vec<Arc<Local>> = lock(&self.local).values().cloned().collect();
            for l in locals {
                match self.store.renew(&l.fence, self.cfg.lease).await {
                    Ok(Renewal::Held { cancel }) => {
                        if cancel {
                            l.stop.store(true, Ordering::SeqCst);
                        }
                    }
                    Ok(Renewal::Lost) if l.finishing.load(Ordering::SeqCst) => {}
                    Ok(Renewal::Lost) => {
                        if !l.lost.swap(true, Ordering::SeqCst) {
                            tracing::warn!(job = %l.fence.id, "lease lost: stopping the job");
                        }
                        l.stop.store(true, Ordering::SeqCst);
                    }
                    Err(e) => tracing::debug!(job = %l.fence.id, error = %e, "lease not renewed"),
                }
            }
        }
    }

    /// Once a second: the reaper (leases that ran out), the gauges and the store's
    /// reachability; every tenth of the retention (at most a minute): retention and size cap.
    async fn maintain(self: Arc<Self>) {
        let expire_every =
            (self.cfg.retention / 10).clamp(Duration::from_millis(100), Duration::from_secs(60));
        let mut tick = tokio::time::interval(expire_every.min(Duration::from_secs(1)));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        let mut last_expire = tokio::time::Instant::now() - expire_every;
        loop {
            tick.tick().await;
            match self.store.reap(now_ms(), false).await {
                Ok(r) => {
                    if !r.requeued.is_empty() || !r.interrupted.is_empty() {
                        tracing::warn!(requeued = ?r.requeued, ended = ?r.interrupted,
                            "leases ran out: jobs of a stopped or stalled replica");
                        self.wake_workers(true);
                    }
                }
                Err(e) => tracing::debug!(error = %e, "reaper"),
            }
            if last_expire.elapsed() >= expire_every {
                last_expire = tokio::time::Instant::now();
                self.expire().await;
            }
            self.refresh_gauges().await;
        }
    }

    async fn refresh_gauges(&self) {
        let ok = match tokio::time::timeout(Duration::from_secs(2), async {
            let c = self.store.counts().await?;
            let q = self.store.queue_depth().await?;
            Ok::<_, StoreError>((c, q))
        })
        .await
        {
            Ok(Ok((counts, queue_depth))) => {
                *lock(&self.cached) = Cached {
                    counts,
                    queue_depth,
                };
                true
            }
            _ => false,
        };
        if ok {
            self.last_ok_ms.store(now_ms(), Ordering::SeqCst);
        }
        let was = self.reachable.swap(ok, Ordering::SeqCst);
        if was != ok {
            if ok {
                tracing::info!("job store reachable again");
            } else {
                tracing::error!("job store unreachable: not ready");
            }
        }
    }

    /// Applies retention and the size cap now; what was removed.
    pub async fn expire(&self) -> usize {
        let policy = RetentionPolicy {
            retention: self.cfg.retention,
            max_result_bytes: self.cfg.max_result_bytes,
        };
        match self.store.expire(&policy, now_ms()).await {
            Ok(e) => {
                if e.by_age + e.by_size > 0 {
                    self.metrics.record_expired("age", e.by_age as u64);
                    self.metrics.record_expired("size", e.by_size as u64);
                    tracing::info!(
                        by_age = e.by_age,
                        by_size = e.by_size,
                        bytes = e.bytes,
                        "expired finished jobs (oldest first)"
                    );
                }
                e.by_age + e.by_size
            }
            Err(e) => {
                tracing::error!(error = %e, "cannot expire old jobs");
                0
            }
        }
    }

    /// Stops taking jobs; jobs running here get `grace` to finish and are then stopped and given
    /// back to the queue (another replica, or this one at its next start, runs them again; the
    /// attempt given back does not count against `max_attempts`). Queued jobs stay queued.
    /// Joins the planner threads.
    pub async fn shutdown(self: &Arc<Self>, grace: Duration) {
        self.closed.store(true, Ordering::SeqCst);
        self.wake_workers(true);
        let deadline = tokio::time::Instant::now() + grace;
        while self.running.load(Ordering::SeqCst) > 0 && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        for l in lock(&self.local).values() {
            l.interrupt.store(true, Ordering::SeqCst);
            l.stop.store(true, Ordering::SeqCst);
        }
        // First-use builds stop too (those a job left for later jobs included).
        self.builds.halt();
        let threads: Vec<JoinHandle<()>> = lock(&self.threads).drain(..).collect();
        let _ = tokio::task::spawn_blocking(move || {
            for t in threads {
                let _ = t.join();
            }
        })
        .await;
        for t in lock(&self.tasks).drain(..) {
            t.abort();
        }
        lock(&self.prepared).clear();
        self.store.close().await;
        tracing::info!("job runner stopped");
    }
}

async fn wait_notice(
    rx: &mut broadcast::Receiver<Notice>,
    id: &str,
    deadline: tokio::time::Instant,
) {
    let until = deadline.min(tokio::time::Instant::now() + Duration::from_secs(1));
    loop {
        match tokio::time::timeout_at(until, rx.recv()).await {
            Err(_) => return,
            Ok(Ok(Notice::Job { id: j })) if j == id => return,
            Ok(Ok(Notice::Resync)) => return,
            Ok(Err(broadcast::error::RecvError::Lagged(_))) => return,
            Ok(Err(broadcast::error::RecvError::Closed)) => {
                tokio::time::sleep_until(until).await;
                return;
            }
            Ok(Ok(_)) => {}
        }
    }
}

fn interrupted_outcome(message: &str) -> Outcome {
    Outcome {
        state: JobState::Interrupted,
        result: None,
        error: Some(ErrorDetail {
            code: "interrupted".into(),
            message: message.into(),
            field: None,
        }),
        progress: None,
        finished_ms: now_ms(),
    }
}

fn shutting_down() -> ApiError {
    ApiError::unavailable("shutting_down", "the server is shutting down", 5)
}

/// A store failure as the client sees it: 503 + `Retry-After` while the store is unreachable.
pub fn store_error(e: StoreError) -> ApiError {
    match e {
        StoreError::Unavailable(m) => ApiError::unavailable(
            "store_unavailable",
            format!("the job store cannot be reached: {m}"),
            2,
        ),
        StoreError::Other(m) => ApiError::internal(m),
    }
}
