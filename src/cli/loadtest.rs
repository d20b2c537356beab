//! `manyhands loadtest`: N concurrent clients drive a running server on the loopback interface
//! for a bounded time with a mix of IK queries and planning jobs, then print throughput,
//! latency percentiles, answers by status and whether every accepted job reached a final state.

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
use super::load_http::{encode_post, Conn};

#[derive(Args, Debug)]
pub struct LoadtestArgs {
    /// Base URL of the server (loopback only).
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
    ik_lat_us: Vec<u32>,
    plan_lat_us: Vec<u32>,
    status: BTreeMap<u16, u64>,
    transport_errors: u64,
    accepted: Vec<String>,
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

/// One simulated client: a keep-alive connection sending pre-encoded requests until the
/// deadline.
async fn client(
    addr: Arc<String>,
    ik_requests: Arc<Vec<Vec<u8>>>,
    plan_request: Arc<Vec<u8>>,
    plan_fraction: f64,
    deadline: Instant,
    seed: u64,
) -> ClientStats {
    let mut st = ClientStats::default();
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

/// `host:port` and path prefix of an `http://` base URL.
fn split_url(base: &str) -> Result<(String, String)> {
    let rest = base
        .strip_prefix("http://")
        .context("--url: only http:// URLs of a local server")?;
    let (host, path) = rest.split_once('/').unwrap_or((rest, ""));
    let addr = if host
        .rsplit_once(':')
        .is_some_and(|(_, p)| p.parse::<u16>().is_ok())
    {
        host.to_string()
    } else {
        format!("{host}:80")
    };
    let prefix = path.trim_end_matches('/');
    let prefix = if prefix.is_empty() {
        String::new()
    } else {
        format!("/{prefix}")
    };
    Ok((addr, prefix))
}

fn check_loopback(url: &str) -> Result<()> {
    let rest = url
        .strip_prefix("http://")
        .context("--url: only http:// URLs of a local server")?;
    let host = rest.split('/').next().unwrap_or("");
    let host = host.rsplit_once(':').map(|(h, _)| h).unwrap_or(host);
    if !matches!(host, "127.0.0.1" | "localhost" | "[::1]") {
        bail!("--url: the load test only drives a server on the loopback interface (got host '{host}')");
    }
    Ok(())
}

pub fn run(ctx: &Ctx, a: &LoadtestArgs) -> Result<()> {
    check_loopback(&a.url)?;
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
    let base = a.url.trim_end_matches('/').to_string();
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
        let mut api = Client::with_timeout(&base, Duration::from_secs(70))?;
        if let Some(t) = &a.token {
            api = api.with_token(t.clone());
        }
        if let Err(e) = api.health().await {
            bail!("no healthy server at {base} (start one with `manyhands serve`): {e}");
        }
        let auth = a.token.as_ref().map(|t| Arc::new(format!("Bearer {t}")));
        let (addr, prefix) = split_url(&base)?;
        let host = addr.clone();
        let encode = |path: &str, body: &[u8]| {
            encode_post(&host, &format!("{prefix}{path}"), auth.as_deref().map(|a| a.as_str()), body)
        };
        let ik_requests = Arc::new(ik_bodies.iter().map(|b| encode("/v1/ik", b)).collect::<Vec<_>>());
        let plan_request = Arc::new(encode("/v1/plans", &plan_body));
        let addr = Arc::new(addr);
        let base = Arc::new(base.clone());
        let started = Instant::now();
        let deadline = started + Duration::from_secs_f64(a.duration);
        let tasks: Vec<_> = (0..a.clients)
            .map(|i| {
                tokio::spawn(client(
                    addr.clone(),
                    ik_requests.clone(),
                    plan_request.clone(),
                    a.plan_fraction.clamp(0.0, 1.0),
                    deadline,
                    i as u64 + 1,
                ))
            })
            .collect();
        let mut all = ClientStats::default();
        for t in tasks {
            let s = t.await?;
            all.ik_lat_us.extend(s.ik_lat_us);
            all.plan_lat_us.extend(s.plan_lat_us);
            for (k, v) in s.status {
                *all.status.entry(k).or_insert(0) += v;
            }
            all.transport_errors += s.transport_errors;
            all.accepted.extend(s.accepted);
        }
        let secs = started.elapsed().as_secs_f64();
        // Every accepted job must reach a final state.
        let mut final_states: BTreeMap<String, u64> = BTreeMap::new();
        let mut lost = 0u64;
        for id in &all.accepted {
            match api.job_wait(id, 60.0).await {
                Ok(job) if job.state.is_final() => *final_states.entry(job.state.name().to_string()).or_insert(0) += 1,
                _ => lost += 1,
            }
        }
        let total: u64 = all.status.values().sum();
        let errors_5xx: u64 = all.status.iter().filter(|(k, _)| **k >= 500).map(|(_, v)| v).sum();
        Ok::<Value, anyhow::Error>(json!({
            "url": *base, "clients": a.clients, "seconds": secs,
            "requests": total, "requests_per_second": total as f64 / secs,
            "ik": lat_json(all.ik_lat_us, secs),
            "plan_submit": lat_json(all.plan_lat_us, secs),
            "status": all.status.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "errors_5xx": errors_5xx,
            "transport_errors": all.transport_errors,
            "jobs": {"accepted": all.accepted.len(), "final": final_states, "lost": lost},
        }))
    })?;
    ctx.print(&report, || {
        let ik = &report["ik"];
        let pl = &report["plan_submit"];
        format!(
            "{} clients, {:.1} s against {}\n\
             requests: {} ({:.0}/s), 5xx: {}, transport errors: {}, by status: {}\n\
             IK:   {} ({:.0}/s)  p50 {:.3} ms  p90 {:.3} ms  p99 {:.3} ms  p99.9 {:.3} ms  max {:.3} ms\n\
             plan: {} submitted  p50 {:.3} ms  p99 {:.3} ms; jobs accepted {}, final {}, lost {}",
            report["clients"], report["seconds"].as_f64().unwrap_or(0.0), report["url"].as_str().unwrap_or(""),
            report["requests"], report["requests_per_second"].as_f64().unwrap_or(0.0), report["errors_5xx"],
            report["transport_errors"], report["status"],
            ik["count"], ik["per_second"].as_f64().unwrap_or(0.0), ik["p50_ms"].as_f64().unwrap_or(0.0),
            ik["p90_ms"].as_f64().unwrap_or(0.0), ik["p99_ms"].as_f64().unwrap_or(0.0),
            ik["p99_9_ms"].as_f64().unwrap_or(0.0), ik["max_ms"].as_f64().unwrap_or(0.0),
            pl["count"], pl["p50_ms"].as_f64().unwrap_or(0.0), pl["p99_ms"].as_f64().unwrap_or(0.0),
            report["jobs"]["accepted"], report["jobs"]["final"], report["jobs"]["lost"],
        )
    });
    let lost = report["jobs"]["lost"].as_u64().unwrap_or(0);
    let e5 = report["errors_5xx"].as_u64().unwrap_or(0);
    if lost > 0 || e5 > 0 {
        bail!("{e5} server errors, {lost} lost jobs");
    }
    Ok(())
}
