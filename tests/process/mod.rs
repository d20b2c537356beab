//! The real `manyhands serve` binary as a child process of a test (crash and signal tests).

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use serde_json::Value;

/// A `manyhands serve` child process on an ephemeral loopback port.
pub struct Proc {
    pub child: Child,
    pub addr: SocketAddr,
}

pub fn spawn(data: &Path, extra: &[&str]) -> Proc {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // MANYHANDS_TEST_BIN runs the test against another build (e.g. the base commit's).
    let bin = std::env::var("MANYHANDS_TEST_BIN")
        .unwrap_or_else(|_| env!("CARGO_BIN_EXE_manyhands").to_string());
    let mut child = Command::new(bin)
        .args(["--robots", &root.join("robots").display().to_string()])
        .args(["--scenes", &root.join("scenes").display().to_string()])
        .args(["serve", "--bind", "127.0.0.1:0", "--workers", "2"])
        .args(["--query-threads", "1", "--log-format", "json"])
        .args(extra)
        .arg("--data-dir")
        .arg(data)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn manyhands serve");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    // Reads the log for the bound address, then keeps draining it so the server never blocks.
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if let Ok(v) = serde_json::from_str::<Value>(&line) {
                if let Some(a) = v["addr"]
                    .as_str()
                    .and_then(|a| a.parse::<SocketAddr>().ok())
                {
                    let _ = tx.send(a);
                }
            }
        }
    });
    let addr = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("the server logs its address");
    Proc { child, addr }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
