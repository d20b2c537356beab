//! The real server on an ephemeral loopback port with the shipped robots and scenes, its data
//! under a fresh temporary folder, and a JSON client for it.

use std::time::Duration;

use manyhands::server::{Config, Server};
use reqwest::StatusCode;
use serde_json::Value;

pub struct Harness {
    pub server: Server,
    pub base: String,
    pub http: reqwest::Client,
}

/// Starts a server whose data folder is named after `name`.
pub async fn start(name: &str) -> Harness {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!(
        "manyhands-test-{name}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("dir");
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir);
    cfg.robots_dir = super::root().join("robots");
    cfg.scenes_dir = super::root().join("scenes");
    cfg.workers = 2;
    cfg.query_threads = 2;
    let server = Server::start(cfg).await.expect("server");
    Harness {
        base: format!("http://{}", server.addr()),
        server,
        http: reqwest::Client::builder()
            .timeout(Duration::from_secs(120))
            .build()
            .expect("client"),
    }
}

impl Harness {
    /// `POST path` with a JSON body: the status and the JSON answer (`null` if none).
    pub async fn post(&self, path: &str, body: &Value) -> (StatusCode, Value) {
        let r = self
            .http
            .post(format!("{}{path}", self.base))
            .json(body)
            .send()
            .await
            .expect("POST");
        let s = r.status();
        (s, r.json().await.unwrap_or(Value::Null))
    }
}

/// The `field` of an error answer.
pub fn field(v: &Value) -> String {
    v["error"]["field"].as_str().unwrap_or("").to_string()
}
