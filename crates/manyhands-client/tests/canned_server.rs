//! The client against a canned HTTP/1.1 server on a loopback port (no manyhands server): the
//! bearer token and percent-encoded path it sends, a 2xx body decoded into the API types, an
//! error body decoded with its field and `Retry-After`, a non-JSON error kept as text, and a
//! job's event stream read up to `end`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::sync::mpsc;
use std::thread;

use manyhands_client::api::JobState;
use manyhands_client::{Client, ClientError};
use serde_json::json;

/// Serves one canned answer per connection, in order, and sends each request's head (request
/// line and headers) to the returned receiver.
fn canned(answers: Vec<String>) -> (String, mpsc::Receiver<String>) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let base = format!("http://{}", listener.local_addr().expect("addr"));
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        for answer in answers {
            let Ok((stream, _)) = listener.accept() else {
                return;
            };
            let mut reader = BufReader::new(stream);
            let mut head = String::new();
            let mut length = 0usize;
            loop {
                let mut line = String::new();
                if reader.read_line(&mut line).unwrap_or(0) == 0 || line == "\r\n" {
                    break;
                }
                if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                    length = v.trim().parse().unwrap_or(0);
                }
                head.push_str(&line);
            }
            let mut body = vec![0; length];
            let _ = reader.read_exact(&mut body);
            let _ = tx.send(head);
            let mut stream = reader.into_inner();
            let _ = stream.write_all(answer.as_bytes());
        }
    });
    (base, rx)
}

fn answer(status: &str, extra: &str, content_type: &str, body: &str) -> String {
    format!(
        "HTTP/1.1 {status}\r\ncontent-type: {content_type}\r\ncontent-length: {}\r\n{extra}connection: close\r\n\r\n{body}",
        body.len()
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 1)]
async fn requests_answers_and_errors() {
    let job = json!({"id": "j1", "kind": "collision_sweep", "state": "succeeded",
        "created_ms": 1, "started_ms": 2, "finished_ms": 3, "time_limit": 5.0,
        "request": {"kind": "collision_sweep"}, "progress": null,
        "result": {"free_fraction": 0.5}, "error": null});
    let (base, heads) = canned(vec![
        answer("200 OK", "", "application/json", &job.to_string()),
        answer(
            "429 Too Many Requests",
            "retry-after: 3\r\n",
            "application/json",
            r#"{"error": {"code": "queue_full", "message": "the planning queue is full; retry later", "field": null}}"#,
        ),
        answer(
            "422 Unprocessable Entity",
            "",
            "application/json",
            r#"{"error": {"code": "invalid_value", "message": "config.right_elbow: value 4.2 outside limit", "field": "config.right_elbow"}}"#,
        ),
        answer("502 Bad Gateway", "", "text/plain", "upstream down"),
        answer(
            "200 OK",
            "",
            "text/event-stream",
            "event: state\ndata: {\"state\":\"running\"}\n\n: keep-alive\n\nevent: end\ndata: {\"state\":\"succeeded\"}\n\n",
        ),
    ]);
    let c = Client::new(&base)
        .expect("client")
        .with_token("0123456789abcdef");

    let j = c.job("a/b?c").await.expect("job");
    assert_eq!(j.state, JobState::Succeeded);
    assert_eq!(j.result, Some(json!({"free_fraction": 0.5})));
    let head = heads.recv().expect("request");
    assert!(
        head.starts_with("GET /v1/plans/a%2Fb%3Fc HTTP/1.1\r\n"),
        "{head}"
    );
    assert!(
        head.to_ascii_lowercase()
            .contains("authorization: bearer 0123456789abcdef\r\n"),
        "{head}"
    );

    let e = c
        .submit_json(&json!({"kind": "collision_sweep"}), Some(1.5))
        .await
        .expect_err("429");
    assert_eq!(e.status().map(|s| s.as_u16()), Some(429), "{e}");
    assert!(
        matches!(&e, ClientError::Api { retry_after: Some(3), detail, .. } if detail.code == "queue_full"),
        "{e:?}"
    );
    assert!(e.to_string().contains("retry after 3 s"), "{e}");
    let head = heads.recv().expect("request");
    assert!(
        head.starts_with("POST /v1/plans?wait=1.5 HTTP/1.1\r\n"),
        "{head}"
    );

    let e = c
        .fk(
            &serde_json::from_value(json!({"robot": "armar", "config": {"right_elbow": 4.2}}))
                .expect("request"),
        )
        .await
        .expect_err("422");
    assert_eq!(e.field(), Some("config.right_elbow"), "{e}");
    assert!(heads.recv().expect("request").starts_with("POST /v1/fk "));

    let e = c.health().await.expect_err("502");
    match &e {
        ClientError::Api { detail, .. } => {
            assert_eq!(detail.code, "http");
            assert_eq!(detail.message, "upstream down");
            assert_eq!(detail.field, None);
        }
        other => panic!("{other:?}"),
    }
    assert!(heads.recv().expect("request").starts_with("GET /healthz "));

    let mut seen = Vec::new();
    let events = c
        .events("j1", |ev| seen.push(ev.event.clone()))
        .await
        .expect("events");
    assert_eq!(seen, ["state", "end"]);
    assert_eq!(events[1].data, json!({"state": "succeeded"}));
    assert!(heads
        .recv()
        .expect("request")
        .starts_with("GET /v1/plans/j1/events "));
}
