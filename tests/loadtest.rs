//! `manyhands loadtest` against the real server: a short run with IK queries and planning jobs
//! reports throughput, only 2xx answers, and every accepted job in a final state with its
//! submit-to-running and end-to-end times and the replica that ran it; with several URLs the
//! clients are spread round-robin over them.

mod common;
use common::server::start;
use serde_json::Value;

/// The load generator's own HTTP/1.1 client, compiled here from the command's source (the
/// command has no unit-test harness of its own: one compilation of the binary less).
#[allow(dead_code)]
#[path = "../src/cli/load_http.rs"]
mod load_http;

/// Runs `manyhands --json loadtest --url URLS` for 1.5 s with 4 clients; the JSON report.
async fn loadtest(urls: String) -> Value {
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
            .args([
                "--json",
                "loadtest",
                "--url",
                &urls,
                "--clients",
                "4",
                "--duration",
                "1.5",
                "--plan-fraction",
                "0.05",
                "--threads",
                "1",
            ])
            .output()
    })
    .await
    .expect("join")
    .expect("run loadtest");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "loadtest failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&stdout).expect("JSON report")
}

/// Every answer a 2xx, every accepted job final with its times and replica on record.
fn check_report(r: &Value) {
    let ik = r["ik"]["count"].as_u64().expect("ik count");
    assert!(ik > 50, "only {ik} IK answers in 1.5 s");
    assert_eq!(r["errors_5xx"], 0);
    assert_eq!(r["transport_errors"], 0);
    assert_eq!(r["status"]["200"].as_u64(), Some(ik), "{r}");
    let accepted = r["jobs"]["accepted"].as_u64().expect("accepted");
    assert!(accepted > 0, "no job submitted: {r}");
    let sum = |v: &Value| -> u64 {
        v.as_object()
            .expect("map")
            .values()
            .filter_map(Value::as_u64)
            .sum()
    };
    assert_eq!(sum(&r["jobs"]["final"]), accepted, "{r}");
    assert_eq!(r["jobs"]["lost"], 0);
    assert!(r["ik"]["p99_ms"].as_f64().expect("p99") > 0.0);
    // Every job ran (a sweep of 2000 samples ends well within its limit) on this one replica.
    let jobs = &r["jobs"];
    assert_eq!(
        jobs["submit_to_running"]["count"].as_u64(),
        Some(accepted),
        "{r}"
    );
    assert_eq!(jobs["end_to_end"]["count"].as_u64(), Some(accepted), "{r}");
    let p99 = |k: &str| jobs[k]["p99_ms"].as_u64().expect("p99");
    assert!(p99("submit_to_running") <= p99("end_to_end"), "{r}");
    assert!(jobs["end_to_end"]["max_ms"].as_u64() >= Some(p99("end_to_end")));
    let replicas = jobs["replicas"].as_object().expect("replicas");
    assert_eq!(replicas.len(), 1, "{r}");
    assert!(!replicas.contains_key("(none)"), "{r}");
    assert_eq!(sum(&jobs["replicas"]), accepted, "{r}");
    assert_eq!(jobs["attempts"]["1"].as_u64(), Some(accepted), "{r}");
    // Per URL: the requests add up to the total.
    let urls = r["urls"].as_array().expect("urls");
    let requests: u64 = urls
        .iter()
        .map(|u| u["requests"].as_u64().expect("requests"))
        .sum();
    assert_eq!(Some(requests), r["requests"].as_u64(), "{r}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loadtest_drives_a_live_server_and_accounts_for_every_job() {
    let h = start("loadtest").await;
    let r = loadtest(h.base.clone()).await;
    check_report(&r);
    assert_eq!(r["url"].as_str(), Some(h.base.as_str()));
    let urls = r["urls"].as_array().expect("urls");
    assert_eq!(urls.len(), 1, "{r}");
    assert_eq!(urls[0]["clients"], 4);
}

/// Two URLs (two names of one server: the store is its own, so any URL reads any job): two
/// clients on each, both carrying load.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loadtest_spreads_clients_over_several_urls() {
    let h = start("loadtest-urls").await;
    let port = h.base.rsplit_once(':').expect("port").1.to_string();
    let second = format!("http://localhost:{port}");
    let r = loadtest(format!("{}, {second}/", h.base)).await;
    check_report(&r);
    assert_eq!(
        r["url"].as_str(),
        Some(format!("{},{second}", h.base).as_str())
    );
    let urls = r["urls"].as_array().expect("urls");
    assert_eq!(urls.len(), 2, "{r}");
    for (u, want) in urls.iter().zip([&h.base, &second]) {
        assert_eq!(u["url"].as_str(), Some(want.as_str()), "{r}");
        assert_eq!(u["clients"], 2, "{r}");
        assert!(u["ik"].as_u64().expect("ik") > 10, "{r}");
        assert_eq!(u["transport_errors"], 0, "{r}");
    }
}

#[test]
fn loadtest_refuses_non_loopback_urls() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args([
            "loadtest",
            "--url",
            "http://example.com:8080",
            "--duration",
            "1",
        ])
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("loopback"));
}

// The URL list: loopback only, each URL once, clients round-robin.

use load_http::{parse_targets, target_of, Target};

#[test]
fn url_lists_parse_into_loopback_targets() {
    let t = parse_targets("http://127.0.0.1:18101, http://localhost:18102/api/ ,http://[::1]")
        .expect("three URLs");
    let want = |base: &str, addr: &str, prefix: &str| Target {
        base: base.into(),
        addr: addr.into(),
        prefix: prefix.into(),
    };
    assert_eq!(
        t,
        vec![
            want("http://127.0.0.1:18101", "127.0.0.1:18101", ""),
            want("http://localhost:18102/api", "localhost:18102", "/api"),
            want("http://[::1]", "[::1]:80", ""),
        ]
    );
    assert_eq!(
        parse_targets("http://[::1]:9/").expect("one")[0],
        want("http://[::1]:9", "[::1]:9", "")
    );
    for (bad, why) in [
        ("http://127.0.0.1:1,http://10.0.0.1:1", "loopback"),
        ("http://127.0.0.1:1,,http://127.0.0.1:2", "empty"),
        ("http://127.0.0.1:1,", "empty"),
        ("https://127.0.0.1:1", "http://"),
        ("http://127.0.0.1:1,http://127.0.0.1:1/", "twice"),
        ("http://127.0.0.1:port", "port"),
        ("", "empty"),
    ] {
        let e = parse_targets(bad).expect_err(bad);
        assert!(e.contains(why), "{bad}: {e}");
    }
}

#[test]
fn clients_go_round_robin_over_the_urls() {
    let spread = |clients: usize, n: usize| {
        let mut per = vec![0; n];
        for i in 0..clients {
            per[target_of(i, n)] += 1;
        }
        per
    };
    assert_eq!(spread(16, 1), vec![16]);
    assert_eq!(spread(16, 2), vec![8, 8]);
    assert_eq!(spread(5, 3), vec![2, 2, 1]);
    assert_eq!(
        (0..4).map(|i| target_of(i, 2)).collect::<Vec<_>>(),
        vec![0, 1, 0, 1]
    );
}

// The client against canned answers: framing, reconnection, malformed answers.

use load_http::{encode_post, Conn};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpListener;

/// A server answering each request (read up to its blank line + body) with the next canned
/// answer, on one connection per entry of `conns`.
async fn canned(conns: Vec<Vec<&'static [u8]>>) -> String {
    let l = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = l.local_addr().expect("addr").to_string();
    tokio::spawn(async move {
        for answers in conns {
            let (mut s, _) = l.accept().await.expect("accept");
            for a in answers {
                let mut got = Vec::new();
                let mut chunk = [0u8; 1024];
                while !got.windows(4).any(|w| w == b"\r\n\r\n") {
                    let n = s.read(&mut chunk).await.expect("read");
                    assert!(n > 0);
                    got.extend_from_slice(&chunk[..n]);
                }
                let head = String::from_utf8_lossy(&got).to_string();
                assert!(head.starts_with("POST /v1/ik HTTP/1.1\r\n"), "{head}");
                assert!(head.contains("content-length: 2\r\n"), "{head}");
                s.write_all(a).await.expect("write");
            }
        }
    });
    addr
}

#[tokio::test]
async fn frames_by_length_chunks_and_close_and_reconnects() {
    let addr = canned(vec![
        vec![
            b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello",
            b"HTTP/1.1 422 Unprocessable Entity\r\ntransfer-encoding: chunked\r\n\r\n3;x=y\r\nabc\r\n2\r\nde\r\n0\r\n\r\n",
            b"HTTP/1.1 503 Service Unavailable\r\nconnection: close\r\ncontent-length: 2\r\n\r\nno",
        ],
        vec![b"HTTP/1.1 200 OK\r\n\r\nuntil-close"],
    ])
    .await;
    let req = encode_post(&addr, "/v1/ik", None, b"{}");
    let mut c = Conn::new(&addr);
    let (s, b) = c.send(&req).await.expect("first");
    assert_eq!((s, b), (200, &b"hello"[..]));
    let (s, b) = c.send(&req).await.expect("chunked");
    assert_eq!((s, b), (422, &b"abcde"[..]));
    let (s, b) = c.send(&req).await.expect("close");
    assert_eq!((s, b), (503, &b"no"[..]));
    // The server closed: the next request opens a new connection.
    let (s, b) = c.send(&req).await.expect("reconnected");
    assert_eq!((s, b), (200, &b"until-close"[..]));
    // Nobody listens any more: an error, not a hang or a panic.
    assert!(c.send(&req).await.is_err());
}

#[tokio::test]
async fn malformed_answers_are_errors() {
    let addr = canned(vec![
        vec![b"garbage\r\n\r\n"],
        vec![b"HTTP/1.1 200 OK\r\ncontent-length: x\r\n\r\n"],
    ])
    .await;
    let req = encode_post(&addr, "/v1/ik", Some("Bearer t"), b"{}");
    assert!(String::from_utf8_lossy(&req).contains("authorization: Bearer t\r\n"));
    let mut c = Conn::new(&addr);
    assert!(c.send(&req).await.is_err());
    assert!(c.send(&req).await.is_err());
}
