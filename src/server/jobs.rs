//! The job runner: a bounded queue, `workers` planner threads (never the async runtime's),
//! job records persisted at every state change, cancel through the planners' stop flag,
//! interrupted jobs at shutdown and after a crash, retention of old results.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, RwLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use rand::Rng;
use serde_json::Value;
use tokio::sync::watch;

use super::api::{Job, JobState};
use super::error::{ApiError, ApiResult, ErrorDetail};
use super::kinds::{JobContext, JobFailure, JobWork, Prepared};
use super::metrics::Metrics;
use super::store::{Store, StoreError};

pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Raises the calling thread's nice value to `nice` (Linux: the nice value is per thread), so
/// planner threads yield the CPU to the synchronous-query pool and the I/O threads. Threads it
/// spawns inherit it. A failure only costs the priority, so it is logged, not fatal.
pub(crate) fn lower_thread_priority(nice: i32) {
    if nice <= 0 {
        return;
    }
    #[cfg(target_os = "linux")]
    {
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
    tracing::debug!(nice, "planner thread priority is left as it is on this OS");
}

/// One job: its record (published through a watch channel to SSE and `?wait` readers), its
/// stop flag and, until a worker takes it, its work.
pub struct JobEntry {
    pub id: String,
    tx: watch::Sender<Job>,
    stop: Arc<AtomicBool>,
    /// Set at shutdown: a job stopped by its flag then ends `interrupted`, not `cancelled`.
    interrupt: AtomicBool,
    work: Mutex<Option<Box<dyn JobWork>>>,
}

impl JobEntry {
    fn new(job: Job, work: Option<Box<dyn JobWork>>) -> JobEntry {
        JobEntry {
            id: job.id.clone(),
            tx: watch::Sender::new(job),
            stop: Arc::new(AtomicBool::new(false)),
            interrupt: AtomicBool::new(false),
            work: Mutex::new(work),
        }
    }

    pub fn snapshot(&self) -> Job {
        self.tx.borrow().clone()
    }

    pub fn state(&self) -> JobState {
        self.tx.borrow().state
    }

    pub fn subscribe(&self) -> watch::Receiver<Job> {
        self.tx.subscribe()
    }
}

struct Queue {
    q: VecDeque<Arc<JobEntry>>,
    /// Slots taken by submissions being persisted.
    reserved: usize,
    closed: bool,
}

/// Settings of the runner.
#[derive(Debug, Clone)]
pub struct RunnerConfig {
    pub workers: usize,
    /// Nice value of the planner threads (see `Config::planner_nice`).
    pub planner_nice: i32,
    pub max_queue: usize,
    pub retention: Duration,
}

pub struct Jobs {
    cfg: RunnerConfig,
    entries: RwLock<HashMap<String, Arc<JobEntry>>>,
    queue: Mutex<Queue>,
    cv: Condvar,
    store: RwLock<Option<Store>>,
    metrics: Arc<Metrics>,
    running: AtomicUsize,
    threads: Mutex<Vec<JoinHandle<()>>>,
    /// Held while a job is made final (commit, then publish).
    finish_lock: Mutex<()>,
}

impl Jobs {
    /// Opens the runner on `store`: records of jobs that were queued or running when the
    /// previous process ended become `interrupted`. Starts the worker threads.
    pub fn start(
        cfg: RunnerConfig,
        store: Store,
        metrics: Arc<Metrics>,
    ) -> Result<Arc<Jobs>, StoreError> {
        let mut loaded = store.load_all()?;
        let now = now_ms();
        let mut changed = Vec::new();
        for j in loaded.iter_mut() {
            if !j.state.is_final() {
                let was = j.state.name();
                j.state = JobState::Interrupted;
                j.finished_ms = Some(now);
                j.error = Some(ErrorDetail {
                    code: "interrupted".into(),
                    message: format!("the server stopped while the job was {was}"),
                    field: None,
                });
                changed.push(j.clone());
            }
        }
        if !changed.is_empty() {
            tracing::warn!(
                count = changed.len(),
                "jobs interrupted by the previous shutdown"
            );
            store.put_all(&changed.iter().collect::<Vec<_>>())?;
        }
        let entries = loaded
            .into_iter()
            .map(|j| (j.id.clone(), Arc::new(JobEntry::new(j, None))))
            .collect();
        let jobs = Arc::new(Jobs {
            cfg: cfg.clone(),
            entries: RwLock::new(entries),
            queue: Mutex::new(Queue {
                q: VecDeque::new(),
                reserved: 0,
                closed: false,
            }),
            cv: Condvar::new(),
            store: RwLock::new(Some(store)),
            metrics,
            running: AtomicUsize::new(0),
            threads: Mutex::new(Vec::new()),
            finish_lock: Mutex::new(()),
        });
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
        Ok(jobs)
    }

    fn persist(&self, job: &Job) -> Result<(), StoreError> {
        match &*self.store.read().unwrap_or_else(|p| p.into_inner()) {
            Some(s) => s.put(job),
            None => Err(StoreError::Other("closed".into())),
        }
    }

    fn persist_logged(&self, job: &Job) {
        if let Err(e) = self.persist(job) {
            tracing::error!(job = %job.id, error = %e, "cannot persist job record");
        }
    }

    pub fn get(&self, id: &str) -> Option<Arc<JobEntry>> {
        self.entries
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .get(id)
            .cloned()
    }

    pub fn list(&self) -> Vec<Job> {
        let mut v: Vec<Job> = self
            .entries
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .values()
            .map(|e| e.snapshot())
            .collect();
        v.sort_by(|a, b| b.created_ms.cmp(&a.created_ms).then(a.id.cmp(&b.id)));
        v
    }

    pub fn queue_depth(&self) -> usize {
        lock(&self.queue).q.len()
    }

    pub fn config(&self) -> &RunnerConfig {
        &self.cfg
    }

    pub fn counts_by_state(&self) -> BTreeMap<&'static str, usize> {
        let mut m: BTreeMap<&'static str, usize> =
            JobState::ALL.iter().map(|s| (s.name(), 0)).collect();
        for e in self
            .entries
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .values()
        {
            *m.entry(e.state().name()).or_insert(0) += 1;
        }
        m
    }

    /// Accepts a prepared job: 429 when the queue is full, 503 when shutting down. The record is
    /// persisted before the job is queued. Blocking (store I/O): call off the async runtime.
    pub fn submit(
        &self,
        kind: &str,
        request: Value,
        prepared: Prepared,
    ) -> ApiResult<Arc<JobEntry>> {
        self.submit_with_warnings(kind, request, prepared, Vec::new())
    }

    /// [`Jobs::submit`] with the job's `warnings` (what the server changed in the request).
    pub fn submit_with_warnings(
        &self,
        kind: &str,
        request: Value,
        prepared: Prepared,
        warnings: Vec<String>,
    ) -> ApiResult<Arc<JobEntry>> {
        {
            let mut q = lock(&self.queue);
            if q.closed {
                return Err(ApiError::unavailable(
                    "shutting_down",
                    "the server is shutting down",
                    5,
                ));
            }
            if q.q.len() + q.reserved >= self.cfg.max_queue {
                return Err(ApiError::queue_full(
                    1 + (q.q.len() / self.cfg.workers.max(1)) as u64,
                ));
            }
            q.reserved += 1;
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
            attempt: None,
            max_attempts: None,
            priority: None,
            replica: None,
        };
        let persisted = self.persist(&job);
        let mut q = lock(&self.queue);
        q.reserved -= 1;
        persisted.map_err(|e| ApiError::internal(e.to_string()))?;
        if q.closed {
            drop(q);
            let entry = JobEntry::new(job, None);
            self.finish(
                &entry,
                JobState::Interrupted,
                None,
                Some(("interrupted", "the server is shutting down".into())),
                None,
            );
            return Err(ApiError::unavailable(
                "shutting_down",
                "the server is shutting down",
                5,
            ));
        }
        let entry = Arc::new(JobEntry::new(job, Some(prepared.work)));
        self.entries
            .write()
            .unwrap_or_else(|p| p.into_inner())
            .insert(id.clone(), entry.clone());
        q.q.push_back(entry.clone());
        drop(q);
        self.cv.notify_one();
        tracing::info!(job = %id, kind, "job queued");
        Ok(entry)
    }

    /// Cancels a queued or running job (a running planner sees its stop flag at its next
    /// iteration). Final jobs are left as they are.
    pub fn cancel(&self, entry: &Arc<JobEntry>) {
        let removed = {
            let mut q = lock(&self.queue);
            let before = q.q.len();
            q.q.retain(|e| e.id != entry.id);
            before != q.q.len()
        };
        if removed {
            lock(&entry.work).take();
            self.finish(
                entry,
                JobState::Cancelled,
                None,
                Some(("cancelled", "cancelled while queued".into())),
                None,
            );
        } else if !entry.state().is_final() {
            entry.stop.store(true, Ordering::Relaxed);
        }
    }

    /// Makes a job final: the record is committed to the store first, then published to
    /// waiters (`?wait=`, SSE, `GET`), so a client is never told a state that a crash right after
    /// the answer could lose. `finish_lock` serialises finishes, so no second one can slip in
    /// between the commit and the publication.
    /// Records a job that was asked to stop as `cancelled` at once, without waiting for its
    /// planner (whose later answer is then dropped). Final jobs are left as they are. Blocking.
    pub fn cancel_now(&self, entry: &Arc<JobEntry>) {
        entry.stop.store(true, Ordering::Relaxed);
        let interrupted = entry.interrupt.load(Ordering::SeqCst);
        self.finish(
            entry,
            if interrupted {
                JobState::Interrupted
            } else {
                JobState::Cancelled
            },
            None,
            Some(if interrupted {
                (
                    "interrupted",
                    "the server shut down while the job was running".into(),
                )
            } else {
                ("cancelled", "cancelled while running".into())
            }),
            None,
        );
    }

    fn finish(
        &self,
        entry: &JobEntry,
        state: JobState,
        result: Option<Value>,
        error: Option<(&str, String)>,
        stats: Option<Value>,
    ) {
        let _serial = lock(&self.finish_lock);
        let mut j = entry.snapshot();
        if j.state.is_final() {
            return;
        }
        j.state = state;
        j.finished_ms = Some(now_ms());
        j.result = result;
        j.error = error.map(|(c, m)| ErrorDetail {
            code: c.to_string(),
            message: m,
            field: None,
        });
        if let Some(s) = stats {
            j.progress = Some(s);
        }
        self.persist_logged(&j);
        let published = entry.tx.send_if_modified(|cur| {
            if cur.state.is_final() {
                return false;
            }
            *cur = j.clone();
            true
        });
        if published {
            let secs = match (j.started_ms, j.finished_ms) {
                (Some(a), Some(b)) => Some(b.saturating_sub(a) as f64 / 1e3),
                _ => None,
            };
            self.metrics.record_job(&j.kind, state.name(), secs);
            tracing::info!(job = %j.id, kind = %j.kind, state = state.name(), "job finished");
        }
    }

    fn next(&self) -> Option<Arc<JobEntry>> {
        let mut q = lock(&self.queue);
        loop {
            if let Some(e) = q.q.pop_front() {
                self.running.fetch_add(1, Ordering::SeqCst);
                return Some(e);
            }
            if q.closed {
                return None;
            }
            q = self.cv.wait(q).unwrap_or_else(|p| p.into_inner());
        }
    }

    fn worker(self: Arc<Self>) {
        while let Some(entry) = self.next() {
            self.run_one(&entry);
            self.running.fetch_sub(1, Ordering::SeqCst);
        }
    }

    fn run_one(&self, entry: &Arc<JobEntry>) {
        let Some(work) = lock(&entry.work).take() else {
            return;
        };
        let mut started = None;
        entry.tx.send_if_modified(|j| {
            if j.state != JobState::Queued {
                return false;
            }
            j.state = JobState::Running;
            j.started_ms = Some(now_ms());
            started = Some(j.clone());
            true
        });
        let Some(job) = started else { return };
        self.persist_logged(&job);
        tracing::info!(job = %job.id, kind = %job.kind, "job running");
        // Progress is published at most every 50 ms, except that a snapshot of a new `phase`
        // is published at once; a snapshot held back by the throttle is kept and published
        // when the next one is due or when the planner returns, so the last one is never lost.
        let tx = entry.tx.clone();
        let held: Arc<Mutex<Option<Value>>> = Arc::new(Mutex::new(None));
        let held_in = held.clone();
        let mut last = Instant::now() - Duration::from_secs(1);
        let mut last_phase: Option<Value> = None;
        let progress = Box::new(move |v: Value| {
            let now = Instant::now();
            let phase = v.get("phase").cloned();
            if now - last >= Duration::from_millis(50) || phase != last_phase {
                last = now;
                last_phase = phase;
                lock(&held_in).take();
                tx.send_modify(|j| j.progress = Some(v));
            } else {
                *lock(&held_in) = Some(v);
            }
        });
        let limit = Duration::from_secs_f64(job.time_limit.max(0.0));
        let mut ctx = JobContext::new(entry.stop.clone(), limit, progress);
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work.run(&mut ctx)));
        drop(ctx);
        if let Some(v) = lock(&held).take() {
            entry.tx.send_modify(|j| j.progress = Some(v));
        }
        match out {
            Ok(Ok(result)) => self.finish(entry, JobState::Succeeded, Some(result), None, None),
            Ok(Err(JobFailure {
                stopped,
                code,
                message,
                stats,
            })) => {
                if stopped && entry.interrupt.load(Ordering::SeqCst) {
                    self.finish(
                        entry,
                        JobState::Interrupted,
                        None,
                        Some((
                            "interrupted",
                            "the server shut down while the job was running".into(),
                        )),
                        stats,
                    );
                } else if stopped {
                    self.finish(
                        entry,
                        JobState::Cancelled,
                        None,
                        Some(("cancelled", message)),
                        stats,
                    );
                } else {
                    self.finish(entry, JobState::Failed, None, Some((code, message)), stats);
                }
            }
            Err(_) => {
                tracing::error!(job = %entry.id, "planner panicked");
                self.finish(
                    entry,
                    JobState::Failed,
                    None,
                    Some(("internal", "the planner failed unexpectedly".into())),
                    None,
                );
            }
        }
    }

    /// Stops taking jobs: queued ones become `interrupted`, running ones get `grace` to finish
    /// and are then stopped (`interrupted`); joins the workers and closes the store. Blocking.
    pub fn shutdown(&self, grace: Duration) {
        let queued: Vec<Arc<JobEntry>> = {
            let mut q = lock(&self.queue);
            q.closed = true;
            q.q.drain(..).collect()
        };
        self.cv.notify_all();
        for e in &queued {
            lock(&e.work).take();
            self.finish(
                e,
                JobState::Interrupted,
                None,
                Some((
                    "interrupted",
                    "the server shut down while the job was queued".into(),
                )),
                None,
            );
        }
        let deadline = Instant::now() + grace;
        while self.running.load(Ordering::SeqCst) > 0 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        if self.running.load(Ordering::SeqCst) > 0 {
            let active: Vec<Arc<JobEntry>> = self
                .entries
                .read()
                .unwrap_or_else(|p| p.into_inner())
                .values()
                .filter(|e| !e.state().is_final())
                .cloned()
                .collect();
            for e in active {
                e.interrupt.store(true, Ordering::SeqCst);
                e.stop.store(true, Ordering::SeqCst);
            }
        }
        let threads: Vec<JoinHandle<()>> = lock(&self.threads).drain(..).collect();
        for t in threads {
            let _ = t.join();
        }
        // Anything still not final (a worker that died) is recorded as interrupted.
        let left: Vec<Arc<JobEntry>> = self
            .entries
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .values()
            .filter(|e| !e.state().is_final())
            .cloned()
            .collect();
        for e in left {
            self.finish(
                &e,
                JobState::Interrupted,
                None,
                Some(("interrupted", "the server shut down".into())),
                None,
            );
        }
        *self.store.write().unwrap_or_else(|p| p.into_inner()) = None;
        tracing::info!("job runner stopped");
    }

    /// Removes final jobs older than the retention from memory and the store. Blocking.
    pub fn expire(&self) -> usize {
        let cutoff = now_ms().saturating_sub(self.cfg.retention.as_millis() as u64);
        let old: Vec<String> = self
            .entries
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .values()
            .filter_map(|e| {
                let j = e.tx.borrow();
                (j.state.is_final() && j.finished_ms.unwrap_or(j.created_ms) < cutoff)
                    .then(|| j.id.clone())
            })
            .collect();
        if old.is_empty() {
            return 0;
        }
        if let Some(s) = &*self.store.read().unwrap_or_else(|p| p.into_inner()) {
            if let Err(e) = s.remove(&old) {
                tracing::error!(error = %e, "cannot remove expired jobs");
                return 0;
            }
        }
        let mut m = self.entries.write().unwrap_or_else(|p| p.into_inner());
        for id in &old {
            m.remove(id);
        }
        tracing::info!(count = old.len(), "expired old jobs");
        old.len()
    }
}
