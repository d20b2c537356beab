//! The Docker image as far as this machine allows without a Docker daemon: the Dockerfile is
//! read stage by stage — the build stage installs npm (so build.rs bundles the viewer and
//! `/viewer` does not answer 503) and refuses to build without the viewer; the runtime stage's
//! environment, with the paths its `COPY --from=build` lines fill mapped to this checkout, is
//! checked by the binary itself (`manyhands serve --check`) with every example token of the
//! Dockerfile, the README and deploy/compose.yaml: each is accepted on the image's 0.0.0.0 bind,
//! and a short one is refused.

mod common;

use std::collections::BTreeMap;
use std::process::Command;

/// One `FROM … AS name` stage: its instructions with continuation lines joined.
struct Stage {
    name: String,
    instructions: Vec<String>,
}

fn stages(text: &str) -> Vec<Stage> {
    let mut joined = Vec::new();
    let mut cur = String::new();
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('#') || (t.is_empty() && cur.is_empty()) {
            continue;
        }
        if let Some(body) = t.strip_suffix('\\') {
            cur.push_str(body.trim());
            cur.push(' ');
        } else {
            cur.push_str(t);
            joined.push(std::mem::take(&mut cur));
        }
    }
    let mut out: Vec<Stage> = Vec::new();
    for ins in joined {
        if let Some(rest) = ins.strip_prefix("FROM ") {
            let name = rest.split(" AS ").nth(1).unwrap_or("").trim().to_string();
            out.push(Stage {
                name,
                instructions: Vec::new(),
            });
        } else if let Some(s) = out.last_mut() {
            s.instructions.push(ins);
        }
    }
    out
}

/// `ENV A=1 B=2` pairs of a stage.
fn env_of(stage: &Stage) -> BTreeMap<String, String> {
    stage
        .instructions
        .iter()
        .filter_map(|i| i.strip_prefix("ENV "))
        .flat_map(|rest| rest.split_whitespace())
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// The example tokens of `MANYHANDS_TOKEN=…` / `MANYHANDS_TOKEN: …` in `text` (no placeholders).
fn example_tokens(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (i, _) in text.match_indices("MANYHANDS_TOKEN") {
        let rest = &text[i + "MANYHANDS_TOKEN".len()..];
        let Some(rest) = rest.strip_prefix('=').or_else(|| rest.strip_prefix(": ")) else {
            continue;
        };
        let tok: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
            .collect();
        if !tok.is_empty() {
            out.push(tok);
        }
    }
    out
}

fn check(env: &BTreeMap<String, String>, token: &str) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args(["serve", "--check"])
        .env_clear()
        .env("PATH", std::env::var_os("PATH").unwrap_or_default())
        .envs(env)
        .env("MANYHANDS_TOKEN", token)
        .output()
        .expect("run manyhands");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_image_builds_the_viewer_and_starts_with_its_documented_token() {
    let root = common::root();
    let text = std::fs::read_to_string(root.join("Dockerfile")).expect("Dockerfile");
    let st = stages(&text);
    let build = st
        .iter()
        .find(|s| s.name == "build")
        .expect("a build stage");
    let runtime = st.last().expect("a runtime stage");

    // The build stage has npm (build.rs bundles the viewer with it) and fails without a viewer.
    let installs: Vec<&str> = build
        .instructions
        .iter()
        .filter(|i| i.starts_with("RUN ") && i.contains("apt-get install"))
        .flat_map(|i| i.split_whitespace())
        .collect();
    for pkg in ["npm", "nodejs"] {
        assert!(
            installs.contains(&pkg),
            "the build stage does not install {pkg}"
        );
    }
    assert_eq!(
        env_of(build)
            .get("MANYHANDS_REQUIRE_VIEWER")
            .map(String::as_str),
        Some("1"),
        "the build stage would quietly build an image without the viewer"
    );
    assert!(
        build
            .instructions
            .iter()
            .any(|i| i.contains("cargo build --release --locked --bin manyhands")),
        "the build stage's build command"
    );

    // The runtime stage's environment, its copied folders mapped to this checkout.
    let data = common::tmp::TestDir::new("docker-data");
    let mut map = BTreeMap::new();
    for ins in &runtime.instructions {
        let Some(rest) = ins.strip_prefix("COPY --from=build ") else {
            continue;
        };
        let mut parts = rest.split_whitespace();
        let (Some(from), Some(to)) = (parts.next(), parts.next()) else {
            continue;
        };
        if let Some(rel) = from.strip_prefix("/src/") {
            map.insert(to.to_string(), root.join(rel));
        }
    }
    for dir in ["robots", "scenes"] {
        assert!(
            map.values().any(|p| p.ends_with(dir)),
            "the image has no copy of {dir}/"
        );
    }
    let env: BTreeMap<String, String> = env_of(runtime)
        .into_iter()
        .map(|(k, v)| {
            let v = match map.get(&v) {
                Some(p) => p.display().to_string(),
                None if k == "MANYHANDS_DATA_DIR" => data.display().to_string(),
                None => v,
            };
            (k, v)
        })
        .collect();
    assert_eq!(
        env.get("MANYHANDS_BIND").map(String::as_str),
        Some("0.0.0.0:8080")
    );

    let mut tokens = example_tokens(&text);
    tokens.extend(example_tokens(
        &std::fs::read_to_string(root.join("README.md")).expect("README"),
    ));
    tokens.extend(example_tokens(
        &std::fs::read_to_string(root.join("deploy/compose.yaml")).expect("compose"),
    ));
    assert!(tokens.len() >= 2, "example tokens: {tokens:?}");
    let robots = std::fs::read_dir(root.join("robots"))
        .expect("robots")
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "urdf"))
        })
        .count();
    for token in &tokens {
        let (code, out, err) = check(&env, token);
        assert_eq!(code, 0, "token {token:?} of the examples is refused: {err}");
        assert!(
            out.contains("would serve on 0.0.0.0:8080 (token required)"),
            "{out}"
        );
        assert!(out.contains(&format!("{robots} robots")), "{out}");
        if manyhands::server::viewer::built() {
            assert!(out.contains("viewer built"), "{out}");
        }
    }
    // What the server refuses, --check refuses: a short token on a non-loopback bind.
    let (code, _, err) = check(&env, "change-me");
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("16"), "{err}");
}
