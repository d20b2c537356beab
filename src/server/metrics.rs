//! A small Prometheus registry (text exposition format 0.0.4): request counters, latency
//! histograms, queue depth, jobs by state and planner time. Kept per server instance (no global
//! recorder), so several servers can run in one process (tests).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};

/// Upper bounds (seconds) of the latency buckets.
const HTTP_BUCKETS: [f64; 14] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0,
];
/// Upper bounds (seconds) of the planner-time buckets.
const PLAN_BUCKETS: [f64; 10] = [0.001, 0.01, 0.05, 0.1, 0.5, 1.0, 5.0, 10.0, 30.0, 120.0];

/// A histogram with fixed buckets; lock-free observation.
pub struct Histogram {
    bounds: &'static [f64],
    counts: Vec<AtomicU64>,
    sum_us: AtomicU64,
    count: AtomicU64,
}

impl Histogram {
    fn new(bounds: &'static [f64]) -> Histogram {
        Histogram {
            bounds,
            counts: (0..bounds.len()).map(|_| AtomicU64::new(0)).collect(),
            sum_us: AtomicU64::new(0),
            count: AtomicU64::new(0),
        }
    }

    pub fn observe(&self, seconds: f64) {
        if let Some(i) = self.bounds.iter().position(|&b| seconds <= b) {
            self.counts[i].fetch_add(1, Ordering::Relaxed);
        }
        self.sum_us
            .fetch_add((seconds * 1e6).max(0.0) as u64, Ordering::Relaxed);
        self.count.fetch_add(1, Ordering::Relaxed);
    }

    fn render(&self, out: &mut String, name: &str, labels: &str) {
        let mut cum = 0;
        let sep = if labels.is_empty() { "" } else { "," };
        for (b, c) in self.bounds.iter().zip(&self.counts) {
            cum += c.load(Ordering::Relaxed);
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {cum}");
        }
        let n = self.count.load(Ordering::Relaxed);
        let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {n}");
        let sum = self.sum_us.load(Ordering::Relaxed) as f64 / 1e6;
        let _ = writeln!(out, "{name}_sum{{{labels}}} {sum}");
        let _ = writeln!(out, "{name}_count{{{labels}}} {n}");
    }
}

/// The server's metrics.
#[derive(Default)]
pub struct Metrics {
    /// (method, route, status) → count.
    requests: Mutex<HashMap<(String, String, u16), u64>>,
    /// route → latency histogram.
    latency: RwLock<HashMap<String, Arc<Histogram>>>,
    /// (kind, final state) → count.
    jobs_finished: Mutex<BTreeMap<(String, String), u64>>,
    /// kind → planner wall time histogram.
    planner: RwLock<HashMap<String, Arc<Histogram>>>,
    /// reason (`age`, `size`) → finished jobs removed by retention.
    expired: Mutex<BTreeMap<String, u64>>,
}

/// Gauges read at scrape time.
pub struct Gauges {
    pub queue_depth: usize,
    pub queue_capacity: usize,
    pub workers: usize,
    pub jobs_by_state: BTreeMap<&'static str, usize>,
    pub robots: usize,
    pub scenes: usize,
    /// Bytes of stored results (all finished jobs).
    pub result_bytes: u64,
    /// Is the job store reachable (1) or not (0)?
    pub store_up: bool,
    /// `embedded` or `postgres`.
    pub store_backend: &'static str,
    /// Jobs running on this replica.
    pub running_here: usize,
}

fn histogram(
    map: &RwLock<HashMap<String, Arc<Histogram>>>,
    key: &str,
    bounds: &'static [f64],
) -> Arc<Histogram> {
    if let Some(h) = map.read().unwrap_or_else(|p| p.into_inner()).get(key) {
        return h.clone();
    }
    map.write()
        .unwrap_or_else(|p| p.into_inner())
        .entry(key.to_string())
        .or_insert_with(|| Arc::new(Histogram::new(bounds)))
        .clone()
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

impl Metrics {
    pub fn record_request(&self, method: &str, route: &str, status: u16, seconds: f64) {
        *self
            .requests
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry((method.to_string(), route.to_string(), status))
            .or_insert(0) += 1;
        histogram(&self.latency, route, &HTTP_BUCKETS).observe(seconds);
    }

    pub fn record_job(&self, kind: &str, state: &str, planner_seconds: Option<f64>) {
        *self
            .jobs_finished
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry((kind.to_string(), state.to_string()))
            .or_insert(0) += 1;
        if let Some(s) = planner_seconds {
            histogram(&self.planner, kind, &PLAN_BUCKETS).observe(s);
        }
    }

    /// Finished jobs removed by retention (`age`) or the size cap (`size`).
    pub fn record_expired(&self, reason: &str, n: u64) {
        if n == 0 {
            return;
        }
        *self
            .expired
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry(reason.to_string())
            .or_insert(0) += n;
    }

    /// The Prometheus text exposition.
    pub fn render(&self, g: &Gauges) -> String {
        let mut out = String::new();
        out += "# HELP manyhands_http_requests_total HTTP requests by method, route and status.\n";
        out += "# TYPE manyhands_http_requests_total counter\n";
        let mut reqs: Vec<_> = self
            .requests
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .map(|(k, v)| (k.clone(), *v))
            .collect();
        reqs.sort();
        for ((m, r, s), v) in reqs {
            let _ = writeln!(
                out,
                "manyhands_http_requests_total{{method=\"{}\",route=\"{}\",status=\"{s}\"}} {v}",
                escape(&m),
                escape(&r)
            );
        }
        out += "# HELP manyhands_http_request_duration_seconds Request latency by route.\n";
        out += "# TYPE manyhands_http_request_duration_seconds histogram\n";
        let mut lat: Vec<_> = self
            .latency
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        lat.sort_by(|a, b| a.0.cmp(&b.0));
        for (route, h) in lat {
            h.render(
                &mut out,
                "manyhands_http_request_duration_seconds",
                &format!("route=\"{}\"", escape(&route)),
            );
        }
        out += "# HELP manyhands_jobs_queue_depth Jobs waiting for a worker.\n";
        out += "# TYPE manyhands_jobs_queue_depth gauge\n";
        let _ = writeln!(out, "manyhands_jobs_queue_depth {}", g.queue_depth);
        out += "# HELP manyhands_jobs_queue_capacity Maximum number of waiting jobs.\n";
        out += "# TYPE manyhands_jobs_queue_capacity gauge\n";
        let _ = writeln!(out, "manyhands_jobs_queue_capacity {}", g.queue_capacity);
        out += "# HELP manyhands_workers Planner worker threads.\n";
        out += "# TYPE manyhands_workers gauge\n";
        let _ = writeln!(out, "manyhands_workers {}", g.workers);
        out += "# HELP manyhands_jobs Jobs known to the server by state.\n";
        out += "# TYPE manyhands_jobs gauge\n";
        for (s, n) in &g.jobs_by_state {
            let _ = writeln!(out, "manyhands_jobs{{state=\"{s}\"}} {n}");
        }
        out +=
            "# HELP manyhands_jobs_finished_total Jobs that reached a final state since start.\n";
        out += "# TYPE manyhands_jobs_finished_total counter\n";
        for ((k, s), n) in self
            .jobs_finished
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
        {
            let _ = writeln!(
                out,
                "manyhands_jobs_finished_total{{kind=\"{}\",state=\"{}\"}} {n}",
                escape(k),
                escape(s)
            );
        }
        out += "# HELP manyhands_planner_seconds Wall time of job execution by kind.\n";
        out += "# TYPE manyhands_planner_seconds histogram\n";
        let mut pl: Vec<_> = self
            .planner
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        pl.sort_by(|a, b| a.0.cmp(&b.0));
        for (kind, h) in pl {
            h.render(
                &mut out,
                "manyhands_planner_seconds",
                &format!("kind=\"{}\"", escape(&kind)),
            );
        }
        out += "# HELP manyhands_jobs_expired_total Finished jobs removed by retention (age) or the result size cap (size).\n";
        out += "# TYPE manyhands_jobs_expired_total counter\n";
        for reason in ["age", "size"] {
            let n = self
                .expired
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .get(reason)
                .copied()
                .unwrap_or(0);
            let _ = writeln!(
                out,
                "manyhands_jobs_expired_total{{reason=\"{reason}\"}} {n}"
            );
        }
        out += "# HELP manyhands_job_result_bytes Bytes of stored results of finished jobs.\n";
        out += "# TYPE manyhands_job_result_bytes gauge\n";
        let _ = writeln!(out, "manyhands_job_result_bytes {}", g.result_bytes);
        out += "# HELP manyhands_store_up Whether the job store is reachable (1) or not (0).\n";
        out += "# TYPE manyhands_store_up gauge\n";
        let _ = writeln!(
            out,
            "manyhands_store_up{{backend=\"{}\"}} {}",
            g.store_backend,
            u8::from(g.store_up)
        );
        out +=
            "# HELP manyhands_jobs_running_here Jobs running on this replica's planner threads.\n";
        out += "# TYPE manyhands_jobs_running_here gauge\n";
        let _ = writeln!(out, "manyhands_jobs_running_here {}", g.running_here);
        out += "# HELP manyhands_models Robots and scenes loaded.\n";
        out += "# TYPE manyhands_models gauge\n";
        let _ = writeln!(out, "manyhands_models{{type=\"robot\"}} {}", g.robots);
        let _ = writeln!(out, "manyhands_models{{type=\"scene\"}} {}", g.scenes);
        out
    }
}
