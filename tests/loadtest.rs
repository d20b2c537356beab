//! `manyhands loadtest` against the real server: a short run with IK queries and planning jobs
//! reports throughput, only 2xx answers, and every accepted job in a final state.

mod common;
use common::server::start;
use serde_json::Value;

/// The load generator's own HTTP/1.1 client, compiled here from the command's source (the
/// command has no unit-test harness of its own: one compilation of the binary less).
#[allow(dead_code)]
#[path = "../src/cli/load_http.rs"]
mod load_http;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loadtest_drives_a_live_server_and_accounts_for_every_job() {
    let h = start("loadtest").await;
    let base = h.base.clone();
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(env!("CARGO_BIN_EXE_manyhands"))
            .args([
                "--json",
                "loadtest",
                "--url",
                &base,
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
    let r: Value = serde_json::from_str(&stdout).expect("JSON report");
    let ik = r["ik"]["count"].as_u64().expect("ik count");
    assert!(ik > 50, "only {ik} IK answers in 1.5 s");
    assert_eq!(r["errors_5xx"], 0);
    assert_eq!(r["transport_errors"], 0);
    assert_eq!(r["status"]["200"].as_u64(), Some(ik), "{r}");
    let accepted = r["jobs"]["accepted"].as_u64().expect("accepted");
    assert!(accepted > 0, "no job submitted: {r}");
    let finished: u64 = r["jobs"]["final"]
        .as_object()
        .expect("final")
        .values()
        .filter_map(Value::as_u64)
        .sum();
    assert_eq!(finished, accepted, "{r}");
    assert_eq!(r["jobs"]["lost"], 0);
    assert!(r["ik"]["p99_ms"].as_f64().expect("p99") > 0.0);
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
