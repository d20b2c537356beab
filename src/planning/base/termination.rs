//! Termination conditions shared by all planners (OMPL's `PlannerTerminationCondition`): a time
//! limit, an iteration limit and an external stop flag, any of which ends the search.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Why a search was ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum StopReason {
    TimeLimit,
    IterationLimit,
    /// The external stop flag was set.
    Requested,
}

/// A termination condition. Planners call [`Termination::should_stop`] once per iteration; it
/// counts iterations, reads the stop flag (one relaxed atomic load) every call and the clock only
/// every `clock_every` calls, so it is cheap enough for the innermost loop.
#[derive(Debug, Clone)]
pub struct Termination {
    start: Instant,
    deadline: Option<Instant>,
    max_iterations: Option<u64>,
    stop: Option<Arc<AtomicBool>>,
    clock_every: u32,
    until_clock: u32,
    iterations: u64,
    reason: Option<StopReason>,
}

impl Default for Termination {
    fn default() -> Self {
        Termination::new()
    }
}

impl Termination {
    /// Never stops by itself; the clock starts now.
    pub fn new() -> Termination {
        Termination {
            start: Instant::now(),
            deadline: None,
            max_iterations: None,
            stop: None,
            clock_every: 16,
            until_clock: 0,
            iterations: 0,
            reason: None,
        }
    }

    /// Never stops by itself; the clock started at `start` (a job's start, so that the time
    /// limit and [`Termination::elapsed`] count the setup before the search too).
    pub fn since(start: Instant) -> Termination {
        Termination {
            start,
            ..Termination::new()
        }
    }

    /// Stops `limit` after the clock start (construction or [`Termination::restart`]).
    pub fn with_time_limit(mut self, limit: Duration) -> Termination {
        self.deadline = self.start.checked_add(limit);
        self
    }

    /// Stops after `n` calls of [`Termination::should_stop`].
    pub fn with_iteration_limit(mut self, n: u64) -> Termination {
        self.max_iterations = Some(n);
        self
    }

    /// Stops as soon as `flag` is true (set it from another thread).
    pub fn with_stop_flag(mut self, flag: Arc<AtomicBool>) -> Termination {
        self.stop = Some(flag);
        self
    }

    /// Reads the clock every `n` calls (at least 1; default 16).
    pub fn with_clock_every(mut self, n: u32) -> Termination {
        self.clock_every = n.max(1);
        self
    }

    /// Restarts the clock (the time limit counts from now) and the iteration count.
    pub fn restart(&mut self) {
        let now = Instant::now();
        if let Some(d) = self.deadline {
            self.deadline = now.checked_add(d.saturating_duration_since(self.start));
        }
        self.start = now;
        self.iterations = 0;
        self.until_clock = 0;
        self.reason = None;
    }

    /// Counts one iteration and tells whether the search must end now. Once it has returned
    /// true it keeps returning true (see [`Termination::reason`]).
    #[inline]
    pub fn should_stop(&mut self) -> bool {
        if self.reason.is_some() {
            return true;
        }
        self.iterations += 1;
        if let Some(f) = &self.stop {
            if f.load(Ordering::Relaxed) {
                self.reason = Some(StopReason::Requested);
                return true;
            }
        }
        if let Some(m) = self.max_iterations {
            if self.iterations > m {
                self.reason = Some(StopReason::IterationLimit);
                return true;
            }
        }
        if let Some(d) = self.deadline {
            if self.until_clock == 0 {
                self.until_clock = self.clock_every;
                if Instant::now() >= d {
                    self.reason = Some(StopReason::TimeLimit);
                    return true;
                }
            }
            self.until_clock -= 1;
        }
        false
    }

    /// How many more iterations [`Termination::count_quiet`] may count at once: those whose
    /// [`Termination::should_stop`] would neither read the clock nor reach the iteration
    /// limit (at most 64, so a planner that counts this way still reads the stop flag at
    /// least every 65 iterations). 0 once the condition has fired.
    #[inline]
    pub fn quiet_iterations(&self) -> u64 {
        if self.reason.is_some() {
            return 0;
        }
        let mut n: u64 = 64;
        if let Some(m) = self.max_iterations {
            n = n.min(m.saturating_sub(self.iterations));
        }
        if self.deadline.is_some() {
            n = n.min(u64::from(self.until_clock));
        }
        n
    }

    /// Counts `n` iterations (at most [`Termination::quiet_iterations`]) as that many calls of
    /// [`Termination::should_stop`] returning false would, without reading the stop flag:
    /// for loops that skip many cheap iterations in a row.
    #[inline]
    pub fn count_quiet(&mut self, n: u64) {
        let n = n.min(self.quiet_iterations());
        self.iterations += n;
        if self.deadline.is_some() {
            // n ≤ until_clock here.
            self.until_clock -= n as u32;
        }
    }

    /// Checks the clock and the flag now, without counting an iteration (for slow steps).
    pub fn should_stop_now(&mut self) -> bool {
        if self.reason.is_some() {
            return true;
        }
        if self
            .stop
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
        {
            self.reason = Some(StopReason::Requested);
        } else if self.deadline.is_some_and(|d| Instant::now() >= d) {
            self.reason = Some(StopReason::TimeLimit);
        }
        self.reason.is_some()
    }

    /// Why the condition fired, once it has.
    pub fn reason(&self) -> Option<StopReason> {
        self.reason
    }

    /// Calls of [`Termination::should_stop`] that counted an iteration.
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    /// Time left before the time limit (`None` without one).
    pub fn remaining(&self) -> Option<Duration> {
        self.deadline
            .map(|d| d.saturating_duration_since(Instant::now()))
    }

    /// Time since the clock start.
    pub fn elapsed(&self) -> Duration {
        self.start.elapsed()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iteration_limit_counts_calls() {
        let mut t = Termination::new().with_iteration_limit(3);
        assert!(!t.should_stop());
        assert!(!t.should_stop());
        assert!(!t.should_stop());
        assert!(t.should_stop());
        assert_eq!(t.reason(), Some(StopReason::IterationLimit));
        assert!(t.should_stop());
    }

    #[test]
    fn time_limit_fires_within_clock_period() {
        let mut t = Termination::new()
            .with_time_limit(Duration::from_millis(5))
            .with_clock_every(4);
        let s = Instant::now();
        while !t.should_stop() {
            std::hint::spin_loop();
        }
        assert_eq!(t.reason(), Some(StopReason::TimeLimit));
        assert!(s.elapsed() < Duration::from_millis(50));
    }

    /// A condition whose clock started earlier counts that time against its limit.
    #[test]
    fn since_counts_from_the_given_start() {
        let start = Instant::now() - Duration::from_secs(2);
        let mut t = Termination::since(start).with_time_limit(Duration::from_secs(1));
        assert!(t.should_stop_now());
        assert_eq!(t.reason(), Some(StopReason::TimeLimit));
        assert!(t.elapsed() >= Duration::from_secs(2));
        let mut t = Termination::since(start).with_time_limit(Duration::from_secs(60));
        assert!(!t.should_stop_now());
        assert!(t.remaining().expect("limit") <= Duration::from_secs(58));
    }

    #[test]
    fn stop_flag() {
        let f = Arc::new(AtomicBool::new(false));
        let mut t = Termination::new().with_stop_flag(f.clone());
        assert!(!t.should_stop());
        f.store(true, Ordering::Relaxed);
        assert!(t.should_stop());
        assert_eq!(t.reason(), Some(StopReason::Requested));
    }

    /// Counting quietly never skips a clock reading or the iteration limit: a loop that calls
    /// `should_stop` and then counts what `quiet_iterations` allows stops at the same
    /// iteration as one that calls `should_stop` every time, and reads the clock as often.
    #[test]
    fn quiet_counting_keeps_limits() {
        for limit in [1u64, 7, 16, 17, 100, 1000] {
            let mut t = Termination::new()
                .with_iteration_limit(limit)
                .with_time_limit(Duration::from_secs(3600));
            let mut counted = 0u64;
            let mut clock_reads = 0u64;
            while !t.should_stop() {
                counted += 1;
                if t.until_clock == t.clock_every - 1 {
                    clock_reads += 1;
                }
                let q = t.quiet_iterations();
                assert!(q <= 64);
                let n = q.min(1 + counted % 40);
                t.count_quiet(n);
                counted += n;
                assert!(t.iterations() <= limit);
            }
            assert_eq!(t.reason(), Some(StopReason::IterationLimit));
            assert_eq!(counted, limit);
            assert_eq!(t.iterations(), limit + 1);
            // One clock reading per 16 counted iterations, as with plain calls.
            assert_eq!(clock_reads, limit.div_ceil(16), "limit {limit}");
        }
        let mut t = Termination::new().with_iteration_limit(2);
        assert!(!t.should_stop());
        assert_eq!(t.quiet_iterations(), 1);
        t.count_quiet(5);
        assert_eq!(t.iterations(), 2);
        assert!(t.should_stop());
        assert_eq!(t.quiet_iterations(), 0);
    }
}
