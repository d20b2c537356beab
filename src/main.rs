//! The `manyhands` command: robot inspection, FK, IK, collision checks, scene generation and
//! benchmarks (and, later, the HTTP server).

mod cli;

fn main() {
    if let Err(e) = cli::run() {
        eprintln!("error: {e:#}");
        std::process::exit(2);
    }
}
