//! The Python SDK (`api/python`) against the real server: starts a server on an ephemeral
//! loopback port and runs the SDK's unittest suite with `MANYHANDS_REQUIRE_SERVER=1`, so the
//! suite cannot skip itself. Needs `python3` (≥ 3.9, standard library only); `.ci/run` installs
//! it on a machine that lacks it. Without python3 the test fails unless
//! `MANYHANDS_SKIP_PYTHON=1` is set.
//!
//! The SDK is dictionaries, not generated classes, so it is held to the same contract as the
//! server (`api/openapi.json`) by testing: every request body the suite sends through it and
//! every JSON answer it gets validate against the spec (independent validator, the `jsonschema`
//! crate), every request-body operation and every job kind is among them, and its constants
//! `FINAL_STATES` and `JOB_KINDS` equal the spec's.

mod common;
use common::server::start;
use common::spec::{errors, spec, template, validator};

use std::collections::BTreeSet;

use serde_json::Value;

/// `python3` (or `$PYTHON`) if it runs; `None` when it is missing and `MANYHANDS_SKIP_PYTHON=1`.
fn python() -> Option<String> {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let found = std::process::Command::new(&python)
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !found {
        assert!(
            std::env::var("MANYHANDS_SKIP_PYTHON").as_deref() == Ok("1"),
            "{python} not found: install Python ≥ 3.9 (or set MANYHANDS_SKIP_PYTHON=1)"
        );
        return None;
    }
    Some(python)
}

/// Checks the requests the suite recorded (`MANYHANDS_SDK_RECORD`, one JSON line each:
/// method, path, body, status, answer) against the spec; returns how many were checked.
fn check_recorded(lines: &str) -> usize {
    let spec = spec();
    let mut accepted_ops = BTreeSet::new();
    let mut accepted_kinds = BTreeSet::new();
    let mut answered_ops = BTreeSet::new();
    let mut n = 0;
    for line in lines.lines().filter(|l| !l.trim().is_empty()) {
        let r: Value = serde_json::from_str(line).expect("a recorded request");
        let method = r["method"].as_str().unwrap_or("").to_ascii_lowercase();
        let path = r["path"].as_str().unwrap_or("");
        let status = r["status"].as_u64().unwrap_or(0);
        let t = template(&spec, path).unwrap_or_else(|| panic!("{path}: not a path of the spec"));
        let op = &spec["paths"][t][method.as_str()];
        assert!(op.is_object(), "{method} {t}: not an operation of the spec");
        assert!(
            op["responses"][status.to_string()].is_object(),
            "{method} {path}: status {status} is not documented"
        );
        let ok = (200..300).contains(&status);
        if !r["body"].is_null() {
            let schema = &op["requestBody"]["content"]["application/json"]["schema"];
            assert!(
                schema.is_object(),
                "{method} {t}: the SDK sends a body the spec has none for"
            );
            let e = errors(&validator(&spec, schema), &r["body"]);
            // An accepted body is schema-valid; a schema-invalid one was refused.
            assert!(
                e.is_empty() || !ok,
                "{method} {path}: the SDK's body fails the spec although the server accepted it: \
                 {e:?}\n{}",
                r["body"]
            );
            if ok {
                accepted_ops.insert(format!("{method} {t}"));
                if let Some(k) = r["body"]["kind"].as_str() {
                    accepted_kinds.insert(k.to_string());
                }
            }
        }
        if ok {
            answered_ops.insert(format!("{method} {t}"));
        }
        if !r["answer"].is_null() {
            let schema =
                &op["responses"][status.to_string()]["content"]["application/json"]["schema"];
            assert!(
                schema.is_object(),
                "{method} {t}: no JSON schema for {status}"
            );
            let e = errors(&validator(&spec, schema), &r["answer"]);
            assert!(
                e.is_empty(),
                "{method} {path}: the {status} answer fails the spec: {e:?}\n{}",
                r["answer"]
            );
        }
        n += 1;
    }
    // Coverage: every operation with a JSON request body, every job kind.
    for (t, ops) in spec["paths"].as_object().expect("paths") {
        for (m, op) in ops.as_object().expect("operations") {
            // (JSON bodies: the record holds them; a raw upload such as a mesh file is not.)
            if op["requestBody"]["content"]["application/json"].is_object() {
                let key = format!("{m} {t}");
                assert!(
                    accepted_ops.contains(&key),
                    "the SDK suite never sent {key}: {accepted_ops:?}"
                );
            }
        }
    }
    // Calls without a request body the SDK has and the suite must use with success.
    for key in [
        "get /v1/meshes",
        "get /v1/robots/{name}/visuals",
        "get /v1/robots/{name}/visuals/{link}/{index}",
    ] {
        assert!(
            answered_ops.contains(key),
            "the SDK suite never got an answer from {key}: {answered_ops:?}"
        );
    }
    let kinds = spec_kinds(&spec);
    assert_eq!(
        accepted_kinds, kinds,
        "job kinds the SDK suite submitted vs the spec's"
    );
    n
}

/// The `kind`s of the spec's `PlanRequest`.
fn spec_kinds(spec: &Value) -> BTreeSet<String> {
    spec["components"]["schemas"]["PlanRequest"]["oneOf"]
        .as_array()
        .expect("PlanRequest.oneOf")
        .iter()
        .flat_map(|b| {
            b["properties"]["kind"]["enum"]
                .as_array()
                .cloned()
                .unwrap_or_default()
        })
        .filter_map(|k| k.as_str().map(str::to_string))
        .collect()
}

/// The SDK's `FINAL_STATES` and `JOB_KINDS` are the spec's final `JobState`s and `PlanRequest`
/// kinds (no server needed).
#[test]
fn sdk_constants_match_the_spec() {
    let Some(python) = python() else { return };
    let out = std::process::Command::new(python)
        .args([
            "-c",
            "import json, manyhands_client as m; \
             print(json.dumps({'final': sorted(m.FINAL_STATES), 'kinds': list(m.JOB_KINDS)}))",
        ])
        .current_dir(common::root().join("api").join("python"))
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let sdk: Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let spec = spec();
    let states: BTreeSet<String> = spec["components"]["schemas"]["JobState"]["enum"]
        .as_array()
        .expect("JobState.enum")
        .iter()
        .filter_map(|s| s.as_str().map(str::to_string))
        .filter(|s| s != "queued" && s != "running")
        .collect();
    let final_states: BTreeSet<String> =
        serde_json::from_value(sdk["final"].clone()).expect("final");
    assert_eq!(final_states, states);
    let kinds: Vec<String> = serde_json::from_value(sdk["kinds"].clone()).expect("kinds");
    assert_eq!(
        kinds.iter().cloned().collect::<BTreeSet<_>>(),
        spec_kinds(&spec)
    );
    assert_eq!(
        kinds.len(),
        spec_kinds(&spec).len(),
        "{kinds:?} repeats a kind"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_sdk_suite_passes_against_a_live_server() {
    let Some(python) = python() else { return };
    let h = start("python-sdk").await;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let record = common::tmp::run_root().join(format!(
        "manyhands-sdk-record-{}-{nanos}.jsonl",
        std::process::id()
    ));
    let record2 = record.clone();
    let dir = common::root().join("api").join("python");
    let base = h.base.clone();
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new(python)
            .args(["-m", "unittest", "discover", "-v", "-s", "tests"])
            .current_dir(dir)
            .env("MANYHANDS_URL", base)
            .env("MANYHANDS_REQUIRE_SERVER", "1")
            .env("MANYHANDS_SDK_RECORD", &record2)
            .env_remove("MANYHANDS_TOKEN")
            .output()
    })
    .await
    .expect("join")
    .expect("run python");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "Python SDK tests failed:\n{err}");
    assert!(!err.contains("skipped"), "tests were skipped:\n{err}");
    // Every test of the suite ran (one line "… ok" each).
    let ran = err.lines().filter(|l| l.ends_with(" ok")).count();
    assert!(ran >= 10, "only {ran} Python tests ran:\n{err}");
    let lines = std::fs::read_to_string(&record).expect("the recorded requests");
    let _ = std::fs::remove_file(&record);
    let n = check_recorded(&lines);
    eprintln!("{n} SDK requests and their answers validate against api/openapi.json");
}

/// `pip install api/python` builds from the source folder without writing into it (no `build/`,
/// no `*.egg-info`): the pyproject build backend is flit_core. Installs into a temporary
/// `--target`, so the machine's Python is left as it was. Needs pip and the package index.
#[test]
fn pip_install_leaves_the_source_folder_clean() {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let has_pip = std::process::Command::new(&python)
        .args(["-m", "pip", "--version"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !has_pip {
        assert!(
            std::env::var("MANYHANDS_SKIP_PYTHON").as_deref() == Ok("1"),
            "{python} -m pip not found: install pip (or set MANYHANDS_SKIP_PYTHON=1)"
        );
        return;
    }
    let src = common::root().join("api").join("python");
    let listing = || -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&src)
            .expect("api/python")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let before = listing();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let target =
        common::tmp::run_root().join(format!("manyhands-pip-{}-{nanos}", std::process::id()));
    let out = std::process::Command::new(&python)
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-cache-dir",
            "--target",
        ])
        .arg(&target)
        .arg(&src)
        .output()
        .expect("run pip");
    assert!(
        out.status.success(),
        "pip install api/python failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(target.join("manyhands_client").join("py.typed").is_file());
    let after = listing();
    let _ = std::fs::remove_dir_all(&target);
    assert_eq!(before, after, "pip install wrote into api/python");
    assert!(
        !after
            .iter()
            .any(|n| n == "build" || n.ends_with(".egg-info")),
        "{after:?}"
    );
}

/// The recorded-request check is not vacuous: a body the server accepted but the spec refuses
/// (here a `fk` body with an unknown field) fails it.
#[test]
#[should_panic(expected = "fails the spec although the server accepted it")]
fn an_accepted_body_the_spec_refuses_is_caught() {
    let line = serde_json::json!({"method": "POST", "path": "/v1/fk",
        "body": {"robot": "armar", "colour": "red"}, "status": 200, "answer": null});
    check_recorded(&line.to_string());
}
