//! A throwaway PostgreSQL cluster for a test: `initdb` in a folder of the test run (`crate::tmp`,
//! `tests/common/tmp.rs`, which every test using this module declares), a server on a
//! free loopback port, a fresh database `manyhands`; stopped and removed when dropped.
//!
//! The binaries come from `MANYHANDS_PG_BIN` (a folder), else `PATH`, else the newest
//! `/usr/lib/postgresql/*/bin` (Debian's `postgresql` package). Without them the test prints one
//! `SKIPPED (no PostgreSQL: …)` line and returns, unless `MANYHANDS_REQUIRE_POSTGRES=1`.
//! PostgreSQL refuses to run as root: as root, the folder is given to the `postgres` user
//! (else `nobody`) and the server runs as that user through `runuser` (else `setpriv`).
#![allow(dead_code)]

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// A running PostgreSQL server with a database `manyhands` (user `manyhands`, trust auth).
pub struct PgCluster {
    bin: PathBuf,
    dir: PathBuf,
    port: u16,
    /// The unprivileged user the server runs as when the tests run as root.
    user: Option<String>,
}

const WHY: &str = "no PostgreSQL: install Debian's postgresql";

fn has_initdb(dir: &Path) -> bool {
    ["initdb", "pg_ctl", "postgres"]
        .iter()
        .all(|b| dir.join(b).is_file())
}

/// The folder holding `initdb`, `pg_ctl` and `postgres`.
fn find_bin() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("MANYHANDS_PG_BIN") {
        let dir = PathBuf::from(dir);
        return has_initdb(&dir).then_some(dir);
    }
    if let Some(path) = std::env::var_os("PATH") {
        if let Some(dir) = std::env::split_paths(&path).find(|d| has_initdb(d)) {
            return Some(dir);
        }
    }
    // Debian keeps them out of PATH, one folder per major version: the newest wins.
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .filter_map(Result::ok)
        .filter_map(|e| {
            let v = e.file_name().to_str()?.parse::<u32>().ok()?;
            let bin = e.path().join("bin");
            has_initdb(&bin).then_some((v, bin))
        })
        .collect();
    versions.sort();
    versions.pop().map(|(_, bin)| bin)
}

fn is_root() -> bool {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: geteuid has no preconditions and cannot fail.
        unsafe { libc::geteuid() == 0 }
    }
    #[cfg(not(target_os = "linux"))]
    {
        Command::new("id")
            .arg("-u")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
            .unwrap_or(false)
    }
}

fn user_exists(name: &str) -> bool {
    Command::new("id")
        .arg("-u")
        .arg(name)
        .output()
        .is_ok_and(|o| o.status.success())
}

fn has_command(name: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()))
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port")
}

static CLUSTERS: AtomicUsize = AtomicUsize::new(0);

impl PgCluster {
    /// Starts a cluster for `test_name`, or prints the SKIPPED line and returns `None` when
    /// PostgreSQL is not installed (a panic with `MANYHANDS_REQUIRE_POSTGRES=1`).
    pub fn start(test_name: &str) -> Option<PgCluster> {
        let Some(bin) = find_bin() else {
            if std::env::var("MANYHANDS_REQUIRE_POSTGRES").is_ok_and(|v| v == "1") {
                panic!("SKIPPED ({WHY}): {test_name} (MANYHANDS_REQUIRE_POSTGRES=1)");
            }
            manyhands::skips::report(WHY);
            return None;
        };
        let user = is_root().then(|| {
            if user_exists("postgres") {
                "postgres".to_string()
            } else {
                "nobody".to_string()
            }
        });
        // Short: the server's socket path (dir/.s.PGSQL.port) must stay under 108 bytes.
        let short: String = test_name
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .take(16)
            .collect();
        let dir = crate::tmp::run_root().join(format!(
            "mh-pg-{short}-{}-{}",
            std::process::id(),
            CLUSTERS.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create the cluster folder");
        let mut cluster = PgCluster {
            bin,
            dir,
            port: 0,
            user,
        };
        if let Some(user) = &cluster.user {
            let st = Command::new("chown")
                .arg("-R")
                .arg(user)
                .arg(&cluster.dir)
                .status()
                .expect("run chown");
            assert!(st.success(), "chown {} to {user}", cluster.dir.display());
        }
        let data = cluster.data().display().to_string();
        let out = cluster.run(
            "initdb",
            &[
                "-D",
                &data,
                "-U",
                "manyhands",
                "-A",
                "trust",
                "--no-sync",
                "-E",
                "UTF8",
                "--locale=C",
            ],
        );
        assert!(
            out.status.success(),
            "initdb failed:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        // A port found free may be taken before the server binds it: try a few.
        let mut last = String::new();
        for _ in 0..4 {
            cluster.port = free_port();
            match cluster.pg_ctl_start() {
                Ok(()) => {
                    cluster.create_database();
                    return Some(cluster);
                }
                Err(e) => last = e,
            }
        }
        panic!(
            "PostgreSQL did not start: {last}\n--- server log ---\n{}",
            cluster.log()
        );
    }

    pub fn url(&self) -> String {
        format!("postgres://manyhands@127.0.0.1:{}/manyhands", self.port)
    }

    pub fn port(&self) -> u16 {
        self.port
    }

    /// Stops the server (fast shutdown: sessions are ended at once), keeping its data.
    pub fn stop(&self) {
        let out = self.pg_ctl(&["stop", "-m", "fast", "-w"]);
        assert!(
            out.status.success(),
            "pg_ctl stop failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    /// Starts the stopped server again on the same port.
    pub fn start_again(&self) {
        if let Err(e) = self.pg_ctl_start() {
            panic!(
                "PostgreSQL did not start again: {e}\n--- server log ---\n{}",
                self.log()
            );
        }
    }

    /// The server's log so far.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("log")).unwrap_or_default()
    }

    fn data(&self) -> PathBuf {
        self.dir.join("data")
    }

    fn pg_ctl_start(&self) -> Result<(), String> {
        let opts = format!(
            "-p {} -k {} -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=200",
            self.port,
            self.dir.display()
        );
        let log = self.dir.join("log").display().to_string();
        let out = self.pg_ctl(&["-l", &log, "-w", "-t", "60", "-o", &opts, "start"]);
        if out.status.success() {
            Ok(())
        } else {
            Err(format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            ))
        }
    }

    fn pg_ctl(&self, args: &[&str]) -> Output {
        let data = self.data().display().to_string();
        let mut all = vec!["-D", data.as_str()];
        all.extend_from_slice(args);
        self.run("pg_ctl", &all)
    }

    /// Runs one of the server's programs, as the unprivileged user when we are root.
    fn run(&self, program: &str, args: &[&str]) -> Output {
        let exe = self.bin.join(program);
        let mut cmd = match &self.user {
            None => Command::new(&exe),
            Some(user) if has_command("runuser") => {
                let mut c = Command::new("runuser");
                c.args(["-u", user, "--"]).arg(&exe);
                c
            }
            Some(user) => {
                let mut c = Command::new("setpriv");
                c.arg(format!("--reuid={user}"))
                    .arg(format!("--regid={user}"))
                    .arg("--clear-groups")
                    .arg(&exe);
                c
            }
        };
        cmd.args(args)
            // The unprivileged user may not be allowed into the test's working directory.
            .current_dir(&self.dir)
            .env_remove("PGDATA")
            .env_remove("PGPORT")
            .env_remove("PGHOST")
            .output()
            .unwrap_or_else(|e| panic!("run {}: {e}", exe.display()))
    }

    /// `CREATE DATABASE manyhands`, through the `postgres` database.
    fn create_database(&self) {
        let url = format!("postgres://manyhands@127.0.0.1:{}/postgres", self.port);
        // A thread of its own: the caller may already be inside a tokio runtime.
        let created = std::thread::spawn(move || -> Result<(), String> {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .map_err(|e| e.to_string())?;
            rt.block_on(async {
                let (client, conn) = tokio_postgres::connect(&url, tokio_postgres::NoTls)
                    .await
                    .map_err(|e| e.to_string())?;
                let driver = tokio::spawn(conn);
                client
                    .batch_execute("CREATE DATABASE manyhands")
                    .await
                    .map_err(|e| e.to_string())?;
                drop(client);
                let _ = tokio::time::timeout(Duration::from_secs(5), driver).await;
                Ok(())
            })
        })
        .join()
        .unwrap_or_else(|_| Err("the create-database thread panicked".into()));
        if let Err(e) = created {
            panic!(
                "CREATE DATABASE manyhands: {e}\n--- server log ---\n{}",
                self.log()
            );
        }
    }
}

impl Drop for PgCluster {
    fn drop(&mut self) {
        if self.port != 0 {
            let _ = self.pg_ctl(&["stop", "-m", "immediate", "-w"]);
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
