//! What a new user meets first: a scenes folder with broken files still serves the good ones
//! and names every bad one once; unknown names and groups list the valid ones (CLI and HTTP);
//! malformed JSON names no field it cannot know; a redirected server log has no colour codes;
//! the shipped scene descriptions speak of the product.

mod common;

use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::server::{field, start};
use serde_json::json;

fn manyhands() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_manyhands"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

#[test]
fn cli_names_the_known_scenes_for_an_unknown_one() {
    let out = manyhands().args(["check", "kitchn"]).output().expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("unknown scene 'kitchn'"), "{err}");
    assert!(
        err.contains("kitchen"),
        "the known scenes are not listed: {err}"
    );
    assert!(!err.contains("cannot read"), "{err}");
}

/// A scenes folder with two broken files and a good one: `serve --check` and `serve` load the
/// good one and name each broken file once.
#[test]
fn one_bad_scene_file_does_not_stop_the_server() {
    let dir = common::tmp::TestDir::new("bad-scenes");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).expect("dir");
    std::fs::copy(
        common::root().join("scenes/kitchen.json"),
        scenes.join("kitchen.json"),
    )
    .expect("copy");
    std::fs::write(scenes.join("broken.json"), "{ not json").expect("write");
    std::fs::write(
        scenes.join("nobody.json"),
        json!({"name": "nobody", "robots": [{"name": "r", "model": "no_such_model"}]}).to_string(),
    )
    .expect("write");
    let robots = common::root().join("robots");
    let out = manyhands()
        .args(["--scenes"])
        .arg(&scenes)
        .args(["--robots"])
        .arg(&robots)
        .args(["serve", "--check", "--data-dir"])
        .arg(dir.join("data"))
        .output()
        .expect("run");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("1 scenes"), "{stdout}");
    for bad in ["broken.json", "nobody.json"] {
        assert_eq!(stderr.matches(bad).count(), 1, "{bad} named once: {stderr}");
    }

    // The server itself: it starts, serves the kitchen, and logs each bad file once.
    let mut child = manyhands()
        .args(["--scenes"])
        .arg(&scenes)
        .args(["--robots"])
        .arg(&robots)
        .args(["serve", "--bind", "127.0.0.1:0", "--data-dir"])
        .arg(dir.join("data"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let mut err = child.stderr.take().expect("stderr");
    let t0 = Instant::now();
    let mut log = String::new();
    let mut buf = [0u8; 4096];
    // Until it listens (or 20 s).
    while !log.contains("listening") && t0.elapsed() < Duration::from_secs(20) {
        match err.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => log.push_str(&String::from_utf8_lossy(&buf[..n])),
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    assert!(log.contains("listening"), "the server did not start: {log}");
    for bad in ["broken.json", "nobody.json"] {
        assert!(log.contains(bad), "{bad} not named: {log}");
    }
    // Redirected (not a terminal): no ANSI colour codes.
    assert!(
        !log.contains('\u{1b}'),
        "colour codes in a redirected log: {log:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_names_list_the_valid_ones_and_malformed_json_names_no_field() {
    let h = start("first-use").await;
    let (s, e) = h
        .post(
            "/v1/plans",
            &json!({"kind": "reach", "scene": "kitchn", "robot": "armar",
                    "group": "torso_right_arm", "object": "wok"}),
        )
        .await;
    assert_eq!(s.as_u16(), 404, "{e}");
    let msg = e["error"]["message"].as_str().unwrap_or("");
    assert!(
        msg.contains("kitchen") && msg.contains("pick_place"),
        "{msg}"
    );
    let (s, e) = h
        .post(
            "/v1/plans",
            &json!({"kind": "reach", "scene": "kitchen", "robot": "armar",
                    "group": "right_armm", "object": "wok"}),
        )
        .await;
    assert_eq!(s.as_u16(), 422, "{e}");
    assert_eq!(field(&e), "group", "{e}");
    let msg = e["error"]["message"].as_str().unwrap_or("");
    assert!(msg.contains("torso_right_arm"), "{msg}");
    let (s, e) = h
        .post(
            "/v1/plans",
            &json!({"kind": "reach", "scene": "kitchen", "robot": "armar",
                    "group": "torso_right_arm", "object": "pan"}),
        )
        .await;
    assert_eq!(s.as_u16(), 422, "{e}");
    assert!(
        e["error"]["message"].as_str().unwrap_or("").contains("wok"),
        "{e}"
    );
    let r = h
        .http
        .get(format!("{}/v1/robots/armr", h.base))
        .send()
        .await
        .expect("GET");
    let v: serde_json::Value = r.json().await.expect("json");
    assert!(
        v["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("armar"),
        "{v}"
    );

    let r = h
        .http
        .post(format!("{}/v1/plans", h.base))
        .header("content-type", "application/json")
        .body(r#"{"kind": "reach", "scene": "kitchen", "robot": "armar" "group": 1}"#)
        .send()
        .await
        .expect("POST");
    assert_eq!(r.status().as_u16(), 400);
    let v: serde_json::Value = r.json().await.expect("json");
    assert_eq!(v["error"]["code"], "malformed_json", "{v}");
    assert!(
        !v["error"]["field"].as_str().unwrap_or("").contains('?'),
        "{v}"
    );
    h.server.shutdown().await.expect("shutdown");
}

#[test]
fn scene_descriptions_speak_of_the_product() {
    let d = manyhands::model::panda_four("panda").description;
    assert!(!d.to_lowercase().contains("issue"), "{d}");
    for e in std::fs::read_dir(common::root().join("scenes"))
        .expect("scenes")
        .flatten()
    {
        if e.path().extension().is_some_and(|x| x == "json") {
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(e.path()).expect("read"))
                    .expect("json");
            let d = v["description"].as_str().unwrap_or("");
            assert!(
                !d.contains("Issue ") && !d.contains("issue "),
                "{}: {d}",
                e.path().display()
            );
        }
    }
}
