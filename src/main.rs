//! The `manyhands` command: the HTTP server, robot inspection, FK, IK, collision checks, scene
//! generation, planning and benchmarks.

mod cli;

/// mimalloc instead of the system allocator: the server allocates per request (HTTP, JSON) on
/// several threads, where glibc's malloc/free took ~10 % of its CPU under load.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    if let Err(e) = cli::run() {
        eprintln!("error: {e:#}");
        std::process::exit(2);
    }
}
