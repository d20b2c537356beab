//! `manyhands loadtest`: N concurrent clients drive one or more running servers (replicas
//! sharing a job store) on the loopback interface for a bounded time with a mix of IK queries
//! and planning jobs, then print throughput, latency percentiles, answers by status and by
//! server, and, from every accepted job's final record, whether it reached a final state, how
//! long it waited for a planner thread (submit to running), how long it took end to end and
//! which replica ran it.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::Args;
use manyhands_client::Client;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use super::commands::Ctx;
use super::load_http::{encode_post, parse_targets, target_of, Conn};

#[derive(Args, Debug)]
pub struct LoadtestArgs {
    /// Base URL of the server (loopback only); a comma-separated list drives several replicas,
    /// client i going to URL i mod n (final job states are read through the first).
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// Concurrent clients.
    #[arg(long, default_value_t = 64)]
    pub clients: usize,
    /// Seconds of load.
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Fraction of requests that submit a planning job (the rest are IK queries).
    #[arg(long, default_value_t = 0.01)]
    pub plan_fraction: f64,
    /// Robot, group and target of the IK queries (x,y,z,roll,pitch,yaw; jittered by ±2 cm).
    #[arg(long, default_value = "armar")]
    pub robot: String,
    #[arg(long, default_value = "right_arm")]
    pub group: String,
    #[arg(
        long,
        default_value = "0.4512,-0.2613,1.0767,-2.7037,-1.4125,1.0834",
        allow_hyphen_values = true
    )]
    pub pose: String,
    /// Scene of the planning jobs (`collision_sweep` of its robots, 2000 samples).
    #[arg(long, default_value = "kitchen")]
    pub scene: String,
    /// Bearer token of the server.
    #[arg(long, env = "MANYHANDS_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Client runtime threads (default: number of cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

#[derive(Default)]
struct ClientStats {
    /// Index of the client's server in `--url`.
    target: usize,
    ik_lat_us: Vec<u32>,
    plan_lat_us: Vec<u32>,
    status: BTreeMap<u16, u64>,
    transport_errors: u64,
    accepted: Vec<String>,
}

/// What went to one server of `--url`.
#[derive(Default, Clone)]
struct UrlStats {
    clients: u64,
    status: BTreeMap<u16, u64>,
    transport_errors: u64,
    ik: u64,
    plans: u64,
}

fn percentile(sorted: &[u32], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((p / 100.0) * (sorted.len() - 1) as f64).round() as usize;
    sorted[i.min(sorted.len() - 1)] as f64 / 1e3
}

fn lat_json(mut v: Vec<u32>, secs: f64) -> Value {
    v.sort_unstable();
    json!({
        "count": v.len(),
        "per_second": v.len() as f64 / secs,
        "p50_ms": percentile(&v, 50.0),
        "p90_ms": percentile(&v, 90.0),
        "p99_ms": percentile(&v, 99.0),
        "p99_9_ms": percentile(&v, 99.9),
        "max_ms": v.last().map(|&x| x as f64 / 1e3).unwrap_or(0.0),
    })
}

/// Percentiles of whole-millisecond durations (the jobs' timestamps are Unix milliseconds).
fn ms_json(mut v: Vec<u64>) -> Value {
    v.sort_unstable();
    let at = |p: f64| {
        if v.is_empty() {
            return 0;
        }
        v[(((p / 100.0) * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)]
    };
    json!({
        "count": v.len(),
        "p50_ms": at(50.0),
        "p90_ms": at(90.0),
        "p99_ms": at(99.0),
        "max_ms": v.last().copied().unwrap_or(0),
    })
}

/// One simulated client: a keep-alive connection sending pre-encoded requests until the
/// deadline.
async fn client(
    addr: Arc<String>,
    ik_requests: Arc<Vec<Vec<u8>>>,
    plan_request: Arc<Vec<u8>>,
    plan_fraction: f64,
    deadline: Instant,
    seed: u64,
    target: usize,
) -> ClientStats {
    let mut st = ClientStats {
        target,
        ..ClientStats::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut conn = Conn::new(&addr);
    while Instant::now() < deadline {
        let plan = rng.random::<f64>() < plan_fraction;
        let request = if plan {
            plan_request.as_slice()
        } else {
            ik_requests[rng.random_range(0..ik_requests.len())].as_slice()
        };
        let t0 = Instant::now();
        match conn.send(request).await {
            Ok((code, body)) => {
                let us = t0.elapsed().as_micros().min(u32::MAX as u128) as u32;
                *st.status.entry(code).or_insert(0) += 1;
                if plan {
                    st.plan_lat_us.push(us);
                    if code == 202 || code == 200 {
                        if let Some(id) = serde_json::from_slice::<Value>(body)
                            .ok()
                            .and_then(|v| v.get("id").and_then(|i| i.as_str()).map(str::to_string))
                        {
                            st.accepted.push(id);
                        }
                    }
                } else {
                    st.ik_lat_us.push(us);
                }
            }
            Err(_) => st.transport_errors += 1,
        }
    }
    st
}

pub fn run(ctx: &Ctx, a: &LoadtestArgs) -> Result<()> {
    let targets = parse_targets(&a.url).map_err(anyhow::Error::msg)?;
    if a.clients == 0 || !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 3600.0) {
        bail!("--clients must be ≥ 1 and --duration in (0, 3600] seconds");
    }
    let pose: Vec<f64> = a
        .pose
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .context("--pose: six numbers x,y,z,roll,pitch,yaw")?;
    if pose.len() != 6 || pose.iter().any(|v| !v.is_finite()) {
        bail!("--pose: six finite numbers x,y,z,roll,pitch,yaw");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let ik_bodies: Vec<Vec<u8>> = (0..64)
        .map(|_| {
            let j = |rng: &mut ChaCha8Rng| rng.random_range(-0.02..0.02);
            serde_json::to_vec(&json!({
                "robot": a.robot, "group": a.group,
                "pose": {"position": [pose[0] + j(&mut rng), pose[1] + j(&mut rng), pose[2] + j(&mut rng)],
                         "rpy": [pose[3], pose[4], pose[5]]},
                "max_solutions": 4,
            }))
            .unwrap_or_default()
        })
        .collect();
    let plan_body = serde_json::to_vec(&json!({
        "kind": "collision_sweep", "scene": a.scene, "samples": 2000, "time_limit": 5.0,
    }))?;
    let threads = a.threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(2)
    });
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads.max(1))
        .enable_all()
        .build()?;
    let report = rt.block_on(async {
        // Health and the final states go through the Rust client; the load itself through
        // pre-encoded requests on raw keep-alive connections (load_http).
        let mut apis = Vec::with_capacity(targets.len());
        for t in &targets {
            let mut api = Client::with_timeout(&t.base, Duration::from_secs(70))?;
            if let Some(tok) = &a.token {
                api = api.with_token(tok.clone());
            }
            if let Err(e) = api.health().await {
                bail!(
                    "no healthy server at {} (start one with `manyhands serve`): {e}",
                    t.base
                );
            }
            apis.push(api);
        }
        let auth = a.token.as_ref().map(|t| format!("Bearer {t}"));
        // Per server: its address and its requests (host header and path prefix are its own).
        type Encoded = (Arc<String>, Arc<Vec<Vec<u8>>>, Arc<Vec<u8>>);
        let encoded: Vec<Encoded> = targets
            .iter()
            .map(|t| {
                let encode = |path: &str, body: &[u8]| {
                    encode_post(
                        &t.addr,
                        &format!("{}{path}", t.prefix),
                        auth.as_deref(),
                        body,
                    )
                };
                (
                    Arc::new(t.addr.clone()),
                    Arc::new(ik_bodies.iter().map(|b| encode("/v1/ik", b)).collect()),
                    Arc::new(encode("/v1/plans", &plan_body)),
                )
            })
            .collect();
        let started = Instant::now();
        let deadline = started + Duration::from_secs_f64(a.duration);
        let tasks: Vec<_> = (0..a.clients)
            .map(|i| {
                let k = target_of(i, encoded.len());
                let (addr, ik, plan) = &encoded[k];
                tokio::spawn(client(
                    addr.clone(),
                    ik.clone(),
                    plan.clone(),
                    a.plan_fraction.clamp(0.0, 1.0),
                    deadline,
                    i as u64 + 1,
                    k,
                ))
            })
            .collect();
        let mut all = ClientStats::default();
        let mut per_url = vec![UrlStats::default(); targets.len()];
        for t in tasks {
            let s = t.await?;
            let u = &mut per_url[s.target];
            u.clients += 1;
            for (k, v) in &s.status {
                *u.status.entry(*k).or_insert(0) += v;
            }
            u.transport_errors += s.transport_errors;
            u.ik += s.ik_lat_us.len() as u64;
            u.plans += s.plan_lat_us.len() as u64;
            all.ik_lat_us.extend(s.ik_lat_us);
            all.plan_lat_us.extend(s.plan_lat_us);
            for (k, v) in s.status {
                *all.status.entry(k).or_insert(0) += v;
            }
            all.transport_errors += s.transport_errors;
            all.accepted.extend(s.accepted);
        }
        let secs = started.elapsed().as_secs_f64();
        // Every accepted job must reach a final state; its final record (read through the
        // first server: any replica answers for any job) says when it was claimed and ended,
        // and by which replica.
        let api = &apis[0];
        let mut final_states: BTreeMap<String, u64> = BTreeMap::new();
        let mut replicas: BTreeMap<String, u64> = BTreeMap::new();
        let mut attempts: BTreeMap<String, u64> = BTreeMap::new();
        let (mut to_running, mut end_to_end) = (Vec::new(), Vec::new());
        let mut lost = 0u64;
        for id in &all.accepted {
            match api.job_wait(id, 60.0).await {
                Ok(job) if job.state.is_final() => {
                    *final_states
                        .entry(job.state.name().to_string())
                        .or_insert(0) += 1;
                    let replica = job.replica.clone().unwrap_or_else(|| "(none)".into());
                    *replicas.entry(replica).or_insert(0) += 1;
                    *attempts
                        .entry(job.attempt.unwrap_or(0).to_string())
                        .or_insert(0) += 1;
                    if let Some(s) = job.started_ms {
                        to_running.push(s.saturating_sub(job.created_ms));
                    }
                    if let Some(f) = job.finished_ms {
                        end_to_end.push(f.saturating_sub(job.created_ms));
                    }
                }
                _ => lost += 1,
            }
        }
        let count_map = |m: &BTreeMap<u16, u64>| {
            m.iter()
                .map(|(k, v)| (k.to_string(), json!(v)))
                .collect::<serde_json::Map<_, _>>()
        };
        let urls: Vec<Value> = targets
            .iter()
            .zip(&per_url)
            .map(|(t, u)| {
                let requests: u64 = u.status.values().sum();
                json!({
                    "url": t.base, "clients": u.clients, "requests": requests,
                    "requests_per_second": requests as f64 / secs,
                    "ik": u.ik, "plan_submit": u.plans,
                    "status": count_map(&u.status), "transport_errors": u.transport_errors,
                })
            })
            .collect();
        let total: u64 = all.status.values().sum();
        let errors_5xx: u64 = all
            .status
            .iter()
            .filter(|(k, _)| **k >= 500)
            .map(|(_, v)| v)
            .sum();
        let url = targets
            .iter()
            .map(|t| t.base.as_str())
            .collect::<Vec<_>>()
            .join(",");
        Ok::<Value, anyhow::Error>(json!({
            "url": url, "clients": a.clients, "seconds": secs,
            "requests": total, "requests_per_second": total as f64 / secs,
            "ik": lat_json(all.ik_lat_us, secs),
            "plan_submit": lat_json(all.plan_lat_us, secs),
            "status": count_map(&all.status),
            "errors_5xx": errors_5xx,
            "transport_errors": all.transport_errors,
            "urls": urls,
            "jobs": {
                "accepted": all.accepted.len(), "final": final_states, "lost": lost,
                "per_second": all.accepted.len() as f64 / secs,
                "submit_to_running": ms_json(to_running),
                "end_to_end": ms_json(end_to_end),
                "replicas": replicas, "attempts": attempts,
            },
        }))
    })?;
    ctx.print(&report, || {
        let ik = &report["ik"];
        let pl = &report["plan_submit"];
        let jobs = &report["jobs"];
        let f = |v: &Value| v.as_f64().unwrap_or(0.0);
        let ms = |v: &Value| {
            format!(
                "{} jobs  p50 {} ms  p90 {} ms  p99 {} ms  max {} ms",
                v["count"], v["p50_ms"], v["p90_ms"], v["p99_ms"], v["max_ms"]
            )
        };
        let mut out = format!(
            "{} clients, {:.1} s against {}\n\
             requests: {} ({:.0}/s), 5xx: {}, transport errors: {}, by status: {}\n\
             IK:   {} ({:.0}/s)  p50 {:.3} ms  p90 {:.3} ms  p99 {:.3} ms  p99.9 {:.3} ms  max {:.3} ms\n\
             plan: {} submitted  p50 {:.3} ms  p99 {:.3} ms; jobs accepted {} ({:.2}/s), final {}, lost {}\n\
             jobs, submit to running: {}\n\
             jobs, end to end:        {}\n\
             jobs by replica: {}, by attempt: {}",
            report["clients"], f(&report["seconds"]), report["url"].as_str().unwrap_or(""),
            report["requests"], f(&report["requests_per_second"]), report["errors_5xx"],
            report["transport_errors"], report["status"],
            ik["count"], f(&ik["per_second"]), f(&ik["p50_ms"]),
            f(&ik["p90_ms"]), f(&ik["p99_ms"]),
            f(&ik["p99_9_ms"]), f(&ik["max_ms"]),
            pl["count"], f(&pl["p50_ms"]), f(&pl["p99_ms"]),
            jobs["accepted"], f(&jobs["per_second"]), jobs["final"], jobs["lost"],
            ms(&jobs["submit_to_running"]), ms(&jobs["end_to_end"]),
            jobs["replicas"], jobs["attempts"],
        );
        if let Some(urls) = report["urls"].as_array().filter(|u| u.len() > 1) {
            for u in urls {
                out.push_str(&format!(
                    "\n  {}: {} clients, {} requests ({:.0}/s; IK {}, plans {}), by status {}, transport errors {}",
                    u["url"].as_str().unwrap_or(""), u["clients"], u["requests"],
                    f(&u["requests_per_second"]), u["ik"], u["plan_submit"], u["status"],
                    u["transport_errors"],
                ));
            }
        }
        out
    });
    let lost = report["jobs"]["lost"].as_u64().unwrap_or(0);
    let e5 = report["errors_5xx"].as_u64().unwrap_or(0);
    if lost > 0 || e5 > 0 {
        bail!("{e5} server errors, {lost} lost jobs");
    }
    Ok(())
}
