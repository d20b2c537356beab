//! Planner threads run at a lower scheduling priority than the query pool, so synchronous
//! queries keep their latency while jobs run (Linux: the nice value is per thread). The
//! priorities are relative to the process's own: the suite passes under `nice -n 10` too.

mod common;

use manyhands::server::Config;

/// `(thread name, nice value)` of every thread of this process.
#[cfg(target_os = "linux")]
fn thread_nice_values() -> Vec<(String, i64)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc/self/task").expect("task dir") {
        let dir = entry.expect("task").path();
        let (Ok(comm), Ok(stat)) = (
            std::fs::read_to_string(dir.join("comm")),
            std::fs::read_to_string(dir.join("stat")),
        ) else {
            continue; // the thread ended meanwhile
        };
        // Fields after the parenthesised name: state is field 3, nice is field 19.
        let rest = &stat[stat.rfind(')').expect("stat name") + 2..];
        let nice: i64 = rest
            .split_whitespace()
            .nth(16)
            .expect("nice field")
            .parse()
            .expect("nice value");
        out.push((comm.trim().to_string(), nice));
    }
    out
}

#[cfg(target_os = "linux")]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn planner_threads_yield_to_queries() {
    let h = common::server::start("priority").await;
    // The pools start their threads asynchronously, and each planner thread sets its own
    // nice value once running: wait (bounded) until both workers show it and the query pool's
    // threads exist.
    let named = |threads: &[(String, i64)], prefix: &str| -> Vec<i64> {
        threads
            .iter()
            .filter(|(n, _)| n.starts_with(prefix))
            .map(|(_, v)| *v)
            .collect()
    };
    // The process's own nice value (its main thread's: `nice -n 10 cargo test` gives 10).
    let base = {
        let stat = std::fs::read_to_string("/proc/self/stat").expect("stat");
        let rest = &stat[stat.rfind(')').expect("stat name") + 2..];
        rest.split_whitespace()
            .nth(16)
            .expect("nice field")
            .parse::<i64>()
            .expect("nice value")
    };
    let planner_nice = (base + 10).min(19);
    let heavy_nice = (base + 5).min(19);
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    let mut threads = thread_nice_values();
    while std::time::Instant::now() < deadline {
        let p = named(&threads, "manyhands-plann");
        let q = named(&threads, "manyhands-query");
        if p.len() >= 2 && p.iter().all(|&n| n == planner_nice) && !q.is_empty() {
            break;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
        threads = thread_nice_values();
    }
    let planners = named(&threads, "manyhands-plann");
    let queries = named(&threads, "manyhands-query");
    let heavy = named(&threads, "manyhands-heavy");
    assert_eq!(planners.len(), 2, "two planner workers: {threads:?}");
    assert!(
        planners.iter().all(|&n| n == planner_nice),
        "base {base}: {threads:?}"
    );
    assert!(
        !queries.is_empty() && queries.iter().all(|&n| n == base),
        "base {base}: {threads:?}"
    );
    // Cheap queries first, then the heavy lane, then planners, whatever the base.
    assert!(
        heavy.iter().all(|&n| n == heavy_nice),
        "base {base}: {threads:?}"
    );
    // A job still runs to its end at the lower priority.
    let (s, v) = h
        .post(
            "/v1/plans?wait=30",
            &serde_json::json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 200}),
        )
        .await;
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["state"], "succeeded", "{v}");
    h.server.shutdown().await.expect("shutdown");
}

#[test]
fn planner_nice_outside_0_to_19_is_refused() {
    let dir = common::tmp::run_root();
    for bad in [-1, 20, 40] {
        let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.clone());
        cfg.planner_nice = bad;
        let e = cfg.validate().expect_err("refused");
        assert!(e.to_string().contains("planner nice"), "{e}");
    }
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir);
    for ok in [0, 10, 19] {
        cfg.planner_nice = ok;
        cfg.validate().expect("accepted");
    }
}
