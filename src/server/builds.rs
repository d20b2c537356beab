//! First-use builds of the expensive caches (reachability grids, grasp lists, super-graph
//! roadmaps) as jobs meet them.
//!
//! The rule, the same for every job kind: a job's time limit counts from the job's start and
//! includes the builds it waits for; a job whose time limit or cancel comes while it waits is
//! answered at once (`timeout` naming the build and the real elapsed time, or `cancelled`), and
//! its planner thread is free again within a poll period ([`POLL`]). What was built is not
//! wasted: a build a job left because of its time limit goes on on a background thread, at the
//! planner threads' priority, and fills its cache (memory, the data folder and the shared tier),
//! so a later job with the same robot, hand or object finds it; a job that asks while it is
//! still running waits for that same build rather than starting another. A build that no job
//! waits for any more because every waiting job was cancelled is stopped and discarded, and so
//! is every build when the server shuts down (after the grace period of its running jobs).

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use super::kinds::{JobContext, JobFailure};

/// How often a job waiting for a build reads its stop flag and the clock.
pub const POLL: Duration = Duration::from_millis(10);

/// The outcome of a build: `Ok(())` built (or found), `Err(None)` stopped, `Err(Some(reason))` failed.
type Done = Result<(), Option<String>>;

struct Slot {
    done: Mutex<Option<Done>>,
    cv: Condvar,
    /// Jobs waiting for the build.
    waiters: AtomicUsize,
    /// A job left the build because of its time limit: it runs to its end for later jobs.
    keep: AtomicBool,
    /// The build is to stop (no job waits for it and none asked to keep it, or shutdown).
    stop: Arc<AtomicBool>,
}

/// What a build polls: true once it is to stop (then it returns `Err(None)`).
#[derive(Clone)]
pub struct BuildStop(Arc<AtomicBool>);

impl BuildStop {
    pub fn stopped(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// The flag itself (for a planner [`crate::planning::Termination`]).
    pub fn flag(&self) -> Arc<AtomicBool> {
        self.0.clone()
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The builds running for the jobs of this process (module docs).
pub struct Builds {
    running: Arc<Mutex<HashMap<String, Arc<Slot>>>>,
    /// Set at shutdown: every build stops.
    halt: Arc<AtomicBool>,
    /// Nice levels of the build threads below the process's own (the planner threads').
    nice: i32,
}

impl Default for Builds {
    fn default() -> Self {
        Builds::new(0)
    }
}

impl Builds {
    pub fn new(nice: i32) -> Builds {
        Builds {
            running: Arc::new(Mutex::new(HashMap::new())),
            halt: Arc::new(AtomicBool::new(false)),
            nice,
        }
    }

    /// Stops every build (shutdown).
    pub fn halt(&self) {
        self.halt.store(true, Ordering::SeqCst);
        for s in lock(&self.running).values() {
            s.stop.store(true, Ordering::SeqCst);
        }
    }

    /// Builds running now (started by a job, whether a job still waits for them or not).
    pub fn running(&self) -> usize {
        lock(&self.running).len()
    }

    /// Makes sure the cache entry `key` exists: runs `build` (which fills the cache and polls
    /// the [`BuildStop`] it is given) on a build thread unless a build of `key` is running
    /// already, and waits for it within `ctx`'s time limit and stop flag. `what` names the
    /// build in answers ("the reachability grid of 'armar' 'torso_left_arm'"). A build that
    /// fails is a `failed` answer with its reason.
    pub fn ensure<F>(
        &self,
        ctx: &mut JobContext,
        key: String,
        what: &str,
        build: F,
    ) -> Result<(), JobFailure>
    where
        F: FnOnce(&BuildStop) -> Result<(), Option<String>> + Send + 'static,
    {
        self.ensure_reporting(ctx, key, what, build, &|| None)
    }

    /// [`Builds::ensure`] that publishes `report()` as the job's progress (at most every
    /// 100 ms) while it waits.
    pub fn ensure_reporting<F>(
        &self,
        ctx: &mut JobContext,
        key: String,
        what: &str,
        build: F,
        report: &dyn Fn() -> Option<serde_json::Value>,
    ) -> Result<(), JobFailure>
    where
        F: FnOnce(&BuildStop) -> Result<(), Option<String>> + Send + 'static,
    {
        let slot = {
            let mut running = lock(&self.running);
            match running.get(&key) {
                Some(s) => {
                    s.waiters.fetch_add(1, Ordering::SeqCst);
                    s.clone()
                }
                None => {
                    let s = Arc::new(Slot {
                        done: Mutex::new(None),
                        cv: Condvar::new(),
                        waiters: AtomicUsize::new(1),
                        keep: AtomicBool::new(false),
                        stop: Arc::new(AtomicBool::new(self.halt.load(Ordering::SeqCst))),
                    });
                    running.insert(key.clone(), s.clone());
                    if let Err(e) = self.spawn(key.clone(), s.clone(), build) {
                        running.remove(&key);
                        return Err(JobFailure {
                            stopped: false,
                            code: "internal",
                            message: format!("cannot start building {what}: {e}"),
                            stats: None,
                        });
                    }
                    s
                }
            }
        };
        let mut last_report = Instant::now();
        let mut done = lock(&slot.done);
        loop {
            if let Some(d) = done.as_ref() {
                let d = d.clone();
                drop(done);
                slot.waiters.fetch_sub(1, Ordering::SeqCst);
                return match d {
                    Ok(()) => Ok(()),
                    Err(Some(reason)) => Err(JobFailure {
                        stopped: false,
                        code: "failed",
                        message: format!("{what}: {reason}"),
                        stats: None,
                    }),
                    // Stopped: by shutdown, or every waiting job was cancelled.
                    Err(None) => Err(JobFailure {
                        stopped: true,
                        code: "cancelled",
                        message: format!("stopped while building {what}"),
                        stats: None,
                    }),
                };
            }
            if ctx.stopped() {
                drop(done);
                self.leave(&slot, false);
                return Err(JobFailure {
                    stopped: true,
                    code: "cancelled",
                    message: format!(
                        "stopped on request {:.3} s after the job started, while building {what}",
                        ctx.elapsed().as_secs_f64()
                    ),
                    stats: None,
                });
            }
            let left = ctx.remaining();
            if left.is_zero() {
                drop(done);
                self.leave(&slot, true);
                return Err(ctx.build_timeout(what));
            }
            done = slot
                .cv
                .wait_timeout(done, left.min(POLL))
                .unwrap_or_else(|p| p.into_inner())
                .0;
            if done.is_none() && last_report.elapsed() >= Duration::from_millis(100) {
                last_report = Instant::now();
                if let Some(v) = report() {
                    drop(done);
                    ctx.progress(v);
                    done = lock(&slot.done);
                }
            }
        }
    }

    /// A job stops waiting for `slot`: by its time limit (`keep`: the build goes on) or by its
    /// cancel (the build stops when no job waits for it and none asked to keep it).
    fn leave(&self, slot: &Slot, keep: bool) {
        if keep {
            slot.keep.store(true, Ordering::SeqCst);
        }
        if slot.waiters.fetch_sub(1, Ordering::SeqCst) == 1 && !slot.keep.load(Ordering::SeqCst) {
            slot.stop.store(true, Ordering::SeqCst);
        }
    }

    fn spawn<F>(&self, key: String, slot: Arc<Slot>, build: F) -> std::io::Result<()>
    where
        F: FnOnce(&BuildStop) -> Result<(), Option<String>> + Send + 'static,
    {
        let nice = self.nice;
        let running = self.running.clone();
        std::thread::Builder::new()
            .name("manyhands-build".into())
            .spawn(move || {
                super::jobs::lower_thread_priority(nice);
                let t = Instant::now();
                let stop = BuildStop(slot.stop.clone());
                let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| build(&stop)))
                    .unwrap_or_else(|_| Err(Some("the build failed unexpectedly".into())));
                match &out {
                    Ok(()) => tracing::info!(
                        build = %key,
                        secs = t.elapsed().as_secs_f64(),
                        "first-use build finished"
                    ),
                    Err(None) => tracing::info!(build = %key, "first-use build stopped"),
                    Err(Some(e)) => {
                        tracing::warn!(build = %key, error = %e, "first-use build failed")
                    }
                }
                // Out of the map first: a job asking after this starts a fresh lookup (which
                // finds the cache filled, or builds again after a stop or failure).
                lock(&running).remove(&key);
                *lock(&slot.done) = Some(out);
                slot.cv.notify_all();
            })
            .map(|_| ())
    }
}
