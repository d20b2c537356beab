//! How a test that cannot run says so: one `SKIPPED (why): TEST` line that a run can count.
//!
//! The line goes to standard error as one whole line in a single write, starting on a line of
//! its own (the test harness writes `test NAME ... ` without a newline before running a test on
//! one thread), and — when `MANYHANDS_SKIP_LOG` ([`SKIP_LOG_ENV`]) names a file — is appended
//! to that file in one write, where nothing else interleaves with it. `.ci/run` and
//! `.ci/fresh-clone` count the file's lines.

use std::io::Write;

/// Environment variable naming the file that collects the skip lines.
pub const SKIP_LOG_ENV: &str = "MANYHANDS_SKIP_LOG";

/// The skip line of the current test: `SKIPPED (why): TEST` (no newline).
pub fn line(why: &str) -> String {
    let name = std::thread::current()
        .name()
        .unwrap_or("unnamed test")
        .to_string();
    format!("SKIPPED ({why}): {name}")
}

/// Reports that the current test did not run because of `why` (see the module docs). Written
/// past the harness's output capture (eprintln! would be captured).
pub fn report(why: &str) {
    let line = line(why);
    let _ = std::io::stderr()
        .lock()
        .write_all(format!("\n{line}\n").as_bytes());
    if let Some(path) = std::env::var_os(SKIP_LOG_ENV) {
        if let Ok(mut f) = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
        {
            let _ = f.write_all(format!("{line}\n").as_bytes());
        }
    }
}
