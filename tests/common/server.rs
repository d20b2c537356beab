//! The real server on an ephemeral loopback port with the shipped robots and scenes, its data
//! under a fresh folder of the target directory (removed with the harness), and a JSON client
//! for it.

use std::time::Duration;

use manyhands::server::{Config, Server};
use reqwest::StatusCode;
use serde_json::Value;

pub struct Harness {
    pub server: Server,
    pub base: String,
    pub http: reqwest::Client,
    /// The server's data folder (removed when the harness is dropped).
    pub dir: super::tmp::TestDir,
}

/// Starts a server whose data folder is named after `name`.
pub async fn start(name: &str) -> Harness {
    start_with_robots(name, &super::root().join("robots")).await
}

/// [`start`] with the built-in robots of `robots_dir` instead of the shipped ones.
pub async fn start_with_robots(name: &str, robots_dir: &std::path::Path) -> Harness {
    let dir = super::tmp::TestDir::new(&format!("test-{name}"));
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir.to_path_buf());
    cfg.robots_dir = robots_dir.to_path_buf();
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
        dir,
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
