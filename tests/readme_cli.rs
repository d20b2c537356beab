//! Every CLI example of README.md runs as printed: each `manyhands …` line of the "Commands"
//! block (continuation lines joined, `[…]` optional parts included) and the `cargo run --release
//! -- …` query example of the server section, run through `sh` with `manyhands` being this
//! build's binary. Each must exit 0. `../shared/…` paths are taken relative to the repository as
//! in the README. The examples run in two groups, each in order in its own scratch folder, the
//! two groups side by side (two tests): the reachability grids (`reach build` writes what `reach
//! plot` and `bench ik` read: every line naming a `.reach` file) and all the others (`time
//! reach.json` reads what `plan reach … > reach.json` wrote; the caches under the folder are
//! shared between the examples of one group only).

#[path = "common/tmp.rs"]
mod tmp;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

/// The example command lines of the README.
fn examples(readme: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut in_commands = false;
    let mut in_block = false;
    let mut pending = String::new();
    for line in readme.lines() {
        if line.starts_with("## ") {
            in_commands = line == "## Commands";
        }
        if line.starts_with("```") {
            in_block = !in_block;
            continue;
        }
        if !in_block {
            continue;
        }
        let code = line.trim();
        let cont = !pending.is_empty();
        let wanted = cont
            || (in_commands && code.starts_with("manyhands "))
            || code.starts_with("cargo run --release -- --json query ");
        if !wanted {
            continue;
        }
        // Drop a trailing comment (no example has '#' inside its arguments).
        let code = code.split(" # ").next().unwrap_or(code).trim_end();
        match code.strip_suffix('\\') {
            Some(head) => {
                pending.push_str(head.trim_end());
                pending.push(' ');
            }
            None => {
                pending.push_str(code);
                out.push(std::mem::take(&mut pending));
            }
        }
    }
    out
}

/// `[--json]` → `--json`: the optional parts are run too.
fn with_options(cmd: &str) -> String {
    cmd.replace(['[', ']'], "")
}

/// The examples of one group: those naming a reachability grid file, or all the others.
fn group(reach_grids: bool) -> Vec<String> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).expect("README.md");
    let list = examples(&readme);
    assert!(
        list.len() >= 25,
        "found only {} examples: {list:?}",
        list.len()
    );
    list.into_iter()
        .filter(|ex| ex.contains(".reach") == reach_grids)
        .collect()
}

#[test]
fn the_readme_reachability_examples_run_as_printed() {
    let list = group(true);
    assert!(
        list.len() >= 3,
        "the README's reach build / reach plot / bench ik examples: {list:?}"
    );
    run_in_order(&list, "reach");
}

#[test]
fn every_other_readme_cli_example_runs_as_printed() {
    run_in_order(&group(false), "rest");
}

/// Runs the examples one after the other in a fresh scratch folder; every failure is reported.
fn run_in_order(list: &[String], tag: &str) {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = tmp::run_root().join(format!(
        "manyhands-readme-{tag}-{}-{nanos}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    // The contacts file of `grasp quality --contacts grasp.json` (format given in the README).
    std::fs::write(
        dir.join("grasp.json"),
        r#"{"centre": [0, 0, 0], "contacts": [
            {"point": [0.5, 0, 0], "normal": [-1, 0, 0]}, {"point": [-0.5, 0, 0], "normal": [1, 0, 0]},
            {"point": [0, 0.5, 0], "normal": [0, -1, 0]}, {"point": [0, -0.5, 0], "normal": [0, 1, 0]}]}"#,
    )
    .expect("grasp.json");
    let bin = env!("CARGO_BIN_EXE_manyhands");
    let shared = root.join("..").join("shared");
    let mut failures = Vec::new();
    // The MotionBenchMaker examples need the outside data: found once here (a SKIPPED line,
    // or a failure under MANYHANDS_REQUIRE_MBM=1, without it) and handed to the examples.
    let mbm =
        manyhands::benchmark::mbm_data::data_for_test().map(|d| d.canonicalize().unwrap_or(d));
    for ex in list {
        if ex.contains(" mbm") && mbm.is_none() {
            continue;
        }
        let cmd = with_options(ex)
            .replacen("cargo run --release -- ", "manyhands ", 1)
            .replace("../shared/", &format!("{}/", shared.display()));
        let script = format!("manyhands() {{ \"$MANYHANDS_BIN\" \"$@\"; }}\n{cmd}\n");
        let t0 = Instant::now();
        let out = Command::new("sh")
            .arg("-c")
            .arg(&script)
            .current_dir(&dir)
            .env("MANYHANDS_BIN", bin)
            .env("MANYHANDS_ROBOTS", root.join("robots"))
            .env("MANYHANDS_SCENES", root.join("scenes"))
            .envs(mbm.iter().map(|d| ("MANYHANDS_MBM_DIR", d.as_os_str())))
            .output()
            .expect("sh");
        eprintln!(
            "{:>8.2} s  exit {:?}  {ex}",
            t0.elapsed().as_secs_f64(),
            out.status.code()
        );
        if !out.status.success() {
            failures.push(format!(
                "{ex}\n  exit {:?}\n  stdout: {}\n  stderr: {}",
                out.status.code(),
                String::from_utf8_lossy(&out.stdout)
                    .chars()
                    .take(600)
                    .collect::<String>(),
                String::from_utf8_lossy(&out.stderr)
                    .chars()
                    .take(600)
                    .collect::<String>()
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        failures.is_empty(),
        "{} README examples failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
