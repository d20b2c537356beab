//! The server's connection handling, seen from raw TCP clients: a refused oversized body says
//! `Connection: close` (so a keep-alive client opens a new connection instead of failing on a
//! dead one), a client stalled mid-body or mid-headers is cut off after the server's read
//! timeouts, a token made of blanks is refused at start-up; and scaling factors so small that
//! they would time a motion in 0 s are refused with 422 naming the field.

mod common;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use manyhands::server::{Config, Server};
use serde_json::{json, Value};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn config(name: &str) -> Config {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!(
        "manyhands-conn-{name}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("dir");
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir);
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.workers = 1;
    cfg.query_threads = 1;
    cfg.shutdown_grace = Duration::from_millis(200);
    cfg.drain = Duration::ZERO;
    cfg
}

/// Reads one HTTP/1.1 response (head and a `Content-Length` body) from `s`: the head's lines
/// and the body, or `None` when the connection closes first.
async fn read_response(s: &mut TcpStream, buf: &mut Vec<u8>) -> Option<(Vec<String>, Vec<u8>)> {
    loop {
        if let Some(end) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&buf[..end]).to_string();
            let lines: Vec<String> = head.split("\r\n").map(str::to_string).collect();
            let len = lines
                .iter()
                .find_map(|l| {
                    let (k, v) = l.split_once(':')?;
                    k.eq_ignore_ascii_case("content-length")
                        .then(|| v.trim().parse::<usize>().ok())?
                })
                .unwrap_or(0);
            while buf.len() < end + 4 + len {
                let mut chunk = [0u8; 65536];
                let n = s.read(&mut chunk).await.ok()?;
                if n == 0 {
                    return None;
                }
                buf.extend_from_slice(&chunk[..n]);
            }
            let body = buf[end + 4..end + 4 + len].to_vec();
            buf.drain(..end + 4 + len);
            return Some((lines, body));
        }
        let mut chunk = [0u8; 65536];
        let n = s.read(&mut chunk).await.ok()?;
        if n == 0 {
            return None;
        }
        buf.extend_from_slice(&chunk[..n]);
    }
}

fn header<'a>(lines: &'a [String], name: &str) -> Option<&'a str> {
    lines.iter().find_map(|l| {
        let (k, v) = l.split_once(':')?;
        k.eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

/// Whether the server closes `s` within `within` (reads until EOF or a reset).
async fn closed_within(s: &mut TcpStream, within: Duration) -> bool {
    let mut chunk = [0u8; 4096];
    let t0 = Instant::now();
    loop {
        let left = within.saturating_sub(t0.elapsed());
        match tokio::time::timeout(left, s.read(&mut chunk)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return true,
            Ok(Ok(_)) => continue,
            Err(_) => return false,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_body_is_answered_413_with_connection_close_and_a_keep_alive_client_goes_on() {
    let mut cfg = config("413");
    cfg.max_body = 64 * 1024;
    let server = Server::start(cfg).await.expect("server");
    let addr = server.addr();
    let mut s = TcpStream::connect(addr).await.expect("connect");
    let mut buf = Vec::new();
    // A keep-alive request first: answered, connection kept.
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .expect("write");
    let (lines, _) = read_response(&mut s, &mut buf).await.expect("healthz");
    assert!(lines[0].contains(" 200 "), "{lines:?}");
    assert_ne!(header(&lines, "connection"), Some("close"), "{lines:?}");
    // A body far over the limit (10 MB announced; the server answers before reading it).
    let big = 10 * 1024 * 1024;
    let head = format!(
        "POST /v1/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {big}\r\n\r\n"
    );
    // Only the head: bytes the server never reads could turn its close into a reset that
    // hides the answer, which is what `Connection: close` spares a client that waits for it.
    s.write_all(head.as_bytes()).await.expect("write head");
    let (lines, body) = read_response(&mut s, &mut buf).await.expect("413 answer");
    assert!(lines[0].contains(" 413 "), "{lines:?}");
    assert_eq!(
        header(&lines, "connection").map(str::to_ascii_lowercase),
        Some("close".to_string()),
        "a 413 that leaves the body unread must say Connection: close: {lines:?}"
    );
    let v: Value = serde_json::from_slice(&body).expect("JSON error body");
    assert_eq!(v["error"]["code"], "body_too_large", "{v}");
    // The client, told so, opens a new connection and goes on.
    let mut s2 = TcpStream::connect(addr).await.expect("connect again");
    let mut buf2 = Vec::new();
    s2.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .expect("write");
    let (lines, _) = read_response(&mut s2, &mut buf2).await.expect("healthz");
    assert!(lines[0].contains(" 200 "), "{lines:?}");
    // A refusal that did read the whole body (422) keeps the connection.
    let body = br#"{"robot": "no_such_robot", "config": {}}"#;
    let head = format!(
        "POST /v1/fk HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s2.write_all(head.as_bytes()).await.expect("write");
    s2.write_all(body).await.expect("write");
    let (lines, _) = read_response(&mut s2, &mut buf2).await.expect("answer");
    assert!(
        lines[0].contains(" 404 ") || lines[0].contains(" 422 "),
        "{lines:?}"
    );
    assert_ne!(header(&lines, "connection"), Some("close"), "{lines:?}");
    s2.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .expect("write");
    let (lines, _) = read_response(&mut s2, &mut buf2).await.expect("kept alive");
    assert!(lines[0].contains(" 200 "), "{lines:?}");
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clients_stalled_mid_body_or_mid_headers_are_cut_off() {
    let mut cfg = config("stall");
    cfg.body_timeout = Duration::from_millis(800);
    cfg.header_timeout = Duration::from_millis(800);
    let server = Server::start(cfg).await.expect("server");
    let addr = server.addr();
    // Mid-body: 100 bytes announced, 10 sent, then silence: 408 and the connection closed.
    let mut s = TcpStream::connect(addr).await.expect("connect");
    s.write_all(
        b"POST /v1/plans HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"kind\": ",
    )
    .await
    .expect("write");
    let t0 = Instant::now();
    let mut buf = Vec::new();
    let (lines, body) =
        tokio::time::timeout(Duration::from_secs(5), read_response(&mut s, &mut buf))
            .await
            .expect("answered within 5 s")
            .expect("an answer before the close");
    let took = t0.elapsed();
    assert!(lines[0].contains(" 408 "), "{lines:?}");
    assert_eq!(
        header(&lines, "connection").map(str::to_ascii_lowercase),
        Some("close".to_string()),
        "{lines:?}"
    );
    let v: Value = serde_json::from_slice(&body).expect("JSON");
    assert_eq!(v["error"]["code"], "body_timeout", "{v}");
    assert!(
        took >= Duration::from_millis(700) && took < Duration::from_secs(3),
        "{took:?}"
    );
    assert!(closed_within(&mut s, Duration::from_secs(2)).await);
    // Many of them at once: all cut off.
    let mut stalled = Vec::new();
    for _ in 0..50 {
        let mut s = TcpStream::connect(addr).await.expect("connect");
        s.write_all(b"PUT /v1/scenes/x HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n{")
            .await
            .expect("write");
        stalled.push(s);
    }
    for s in &mut stalled {
        assert!(closed_within(s, Duration::from_secs(5)).await);
    }
    // Mid-headers: a request head never finished: the connection is closed.
    let mut s = TcpStream::connect(addr).await.expect("connect");
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ")
        .await
        .expect("write");
    let t0 = Instant::now();
    assert!(closed_within(&mut s, Duration::from_secs(5)).await);
    assert!(t0.elapsed() < Duration::from_secs(3), "{:?}", t0.elapsed());
    // A prompt client is unaffected.
    let mut s = TcpStream::connect(addr).await.expect("connect");
    s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .expect("write");
    let (lines, _) = read_response(&mut s, &mut Vec::new())
        .await
        .expect("healthz");
    assert!(lines[0].contains(" 200 "), "{lines:?}");
    server.shutdown().await.expect("shutdown");
}

#[test]
fn blank_tokens_are_refused_at_start_up() {
    for bind in ["0.0.0.0:0", "127.0.0.1:0"] {
        for token in [" ".repeat(16), "\t".repeat(20), " abcdefghijklmnopq".into()] {
            let mut cfg = config("token");
            cfg.bind = bind.parse().expect("addr");
            cfg.token = Some(token.clone());
            let e = cfg.validate().expect_err("refused").to_string();
            assert!(
                e.contains("blank") || e.contains("whitespace"),
                "{bind} {token:?}: {e}"
            );
        }
    }
    let mut cfg = config("token");
    cfg.bind = "0.0.0.0:0".parse().expect("addr");
    cfg.token = Some("a-token-of-twenty-chars".into());
    assert!(cfg.validate().is_ok());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn scaling_factors_too_small_to_time_a_motion_are_refused() {
    let h = common::server::start("scaling").await;
    let traj = |scale: f64| {
        json!({"robot": "armar", "group": "right_arm",
            "waypoints": [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1]],
            "velocity_scaling": scale, "sample_period": 0.05})
    };
    for scale in [1e-300, 1e-100, 1e-5, 0.0009] {
        let (s, e) = h.post("/v1/trajectories", &traj(scale)).await;
        assert_eq!(s.as_u16(), 422, "{scale}: {e}");
        assert_eq!(common::server::field(&e), "velocity_scaling", "{e}");
    }
    let mut acc = traj(1.0);
    acc["acceleration_scaling"] = json!(1e-300);
    let (s, e) = h.post("/v1/trajectories", &acc).await;
    assert_eq!(s.as_u16(), 422, "{e}");
    assert_eq!(common::server::field(&e), "acceleration_scaling", "{e}");
    // At the smallest factor: a slow motion, finite and positive, more than one point.
    let (s, t) = h.post("/v1/trajectories", &traj(0.001)).await;
    assert_eq!(s.as_u16(), 200, "{t}");
    let d = t["duration"].as_f64().expect("duration");
    assert!(d.is_finite() && d > 1.0, "{d}");
    assert!(t["points"].as_array().expect("points").len() > 1);
    // A planning job: refused at submission, before any planning.
    let plan = json!({"kind": "joint_space", "scene": "empty", "velocity_scaling": 1e-300,
        "robots": [{"name": "armar", "group": "right_arm", "goal": {"right_elbow": -1.0}}]});
    let (s, e) = h.post("/v1/plans", &plan).await;
    assert_eq!(s.as_u16(), 422, "{e}");
    assert_eq!(common::server::field(&e), "velocity_scaling", "{e}");
    h.server.shutdown().await.expect("shutdown");
}
