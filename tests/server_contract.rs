//! Small contract points of the HTTP API: percent-decoded query strings, fixed-length arrays of
//! the wrong length as 422 naming the field, the bearer scheme case-insensitive with
//! `WWW-Authenticate` on every 401, uploads named as uploaded and bounded in size, a capped
//! `time_limit` said in the answer.

#[path = "common/tmp.rs"]
mod tmp;
use std::path::PathBuf;
use std::time::Duration;

use manyhands::server::{Config, Server};
use reqwest::StatusCode;
use serde_json::{json, Value};

const TOKEN: &str = "contract-test-token-0123";

async fn start(token: Option<&str>) -> Server {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = tmp::run_root().join(format!("manyhands-contract-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut cfg = Config::new("127.0.0.1:0".parse().expect("addr"), dir);
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.workers = 1;
    cfg.query_threads = 1;
    cfg.heavy_threads = 1;
    cfg.max_plan_seconds = 30.0;
    cfg.shutdown_grace = Duration::from_millis(100);
    cfg.token = token.map(str::to_string);
    Server::start(cfg).await.expect("server")
}

fn client() -> reqwest::Client {
    reqwest::Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .expect("client")
}

async fn json_of(r: reqwest::Response) -> (StatusCode, Value) {
    let s = r.status();
    (s, r.json().await.unwrap_or(Value::Null))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn queries_arrays_uploads_and_time_limits() {
    let server = start(None).await;
    let base = format!("http://{}", server.addr());
    let http = client();
    let sweep = json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 50});

    // Percent-encoded query keys and values.
    for q in ["wait=%31", "wa%69t=1", "wait=1%2E5"] {
        let (s, v) = json_of(
            http.post(format!("{base}/v1/plans?{q}"))
                .json(&sweep)
                .send()
                .await
                .expect("POST"),
        )
        .await;
        assert_eq!(s, StatusCode::OK, "?{q}: {v}");
        assert_eq!(v["state"], "succeeded", "?{q}: {v}");
    }
    let (s, v) = json_of(
        http.post(format!("{base}/v1/plans?wait=%ZZ"))
            .json(&sweep)
            .send()
            .await
            .expect("POST"),
    )
    .await;
    assert_eq!(s, StatusCode::BAD_REQUEST, "{v}");

    // A 3-vector with four (or two) elements: 422 naming the field.
    for position in [json!([0.4, -0.2, 1.0, 7.0]), json!([0.4, -0.2])] {
        let (s, v) = json_of(
            http.post(format!("{base}/v1/ik"))
                .json(&json!({"robot": "armar", "group": "right_arm", "pose": {"position": position}}))
                .send()
                .await
                .expect("POST"),
        )
        .await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
        assert_eq!(v["error"]["field"], "pose.position", "{v}");
    }

    // A time limit over the server's maximum is capped, and the answer says so.
    let (s, v) = json_of(
        http.post(format!("{base}/v1/plans?wait=10"))
            .json(&json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 50, "time_limit": 1000}))
            .send()
            .await
            .expect("POST"),
    )
    .await;
    assert_eq!(s, StatusCode::OK, "{v}");
    assert_eq!(v["time_limit"], 30.0);
    let warnings = v["warnings"].as_array().cloned().unwrap_or_default();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .is_some_and(|w| w.contains("capped") && w.contains("1000"))),
        "{v}"
    );
    let (_, v) = json_of(
        http.post(format!("{base}/v1/plans?wait=10"))
            .json(&json!({"kind": "collision_sweep", "scene": "kitchen", "samples": 50, "time_limit": 5}))
            .send()
            .await
            .expect("POST"),
    )
    .await;
    assert!(
        v.get("warnings").is_none(),
        "no warning when not capped: {v}"
    );

    // An uploaded robot is named as uploaded, not by its URDF's <robot name>.
    let urdf = r#"<robot name="urdf_name">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0 0 0.25"/><geometry><cylinder radius="0.03" length="0.5"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="1" effort="1"/></joint>
</robot>"#;
    let (s, v) = json_of(
        http.put(format!("{base}/v1/robots/uploaded_as"))
            .json(&json!({"urdf": urdf}))
            .send()
            .await
            .expect("PUT"),
    )
    .await;
    assert!(s.is_success(), "{v}");
    let (s, v) = json_of(
        http.post(format!("{base}/v1/fk"))
            .json(&json!({"robot": "uploaded_as", "config": {"nope": 1.0}}))
            .send()
            .await
            .expect("FK"),
    )
    .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY);
    let msg = v["error"]["message"].as_str().unwrap_or("");
    assert!(
        msg.contains("'uploaded_as'") && !msg.contains("urdf_name"),
        "{msg}"
    );
    let (_, v) = json_of(
        http.get(format!("{base}/v1/robots/uploaded_as"))
            .send()
            .await
            .expect("GET"),
    )
    .await;
    assert_eq!(v["name"], "uploaded_as");

    // An 8 000-joint chain is refused, the limit stated.
    let mut big = String::from("<robot name=\"big\"><link name=\"l0\"/>");
    for i in 0..8000 {
        big.push_str(&format!(
            "<link name=\"l{}\"/><joint name=\"j{i}\" type=\"revolute\"><parent link=\"l{i}\"/><child link=\"l{}\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" velocity=\"1\" effort=\"1\"/></joint>",
            i + 1,
            i + 1
        ));
    }
    big.push_str("</robot>");
    let (s, v) = json_of(
        http.put(format!("{base}/v1/robots/big"))
            .json(&json!({"urdf": big}))
            .send()
            .await
            .expect("PUT"),
    )
    .await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{v}");
    assert_eq!(v["error"]["field"], "urdf");
    let msg = v["error"]["message"].as_str().unwrap_or("");
    assert!(msg.contains("512"), "{msg}");
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bearer_scheme_is_case_insensitive_and_401_says_how() {
    let server = start(Some(TOKEN)).await;
    let url = format!("http://{}/v1/robots", server.addr());
    let http = client();
    for scheme in ["Bearer", "bearer", "BEARER", "bEaReR"] {
        let r = http
            .get(&url)
            .header("authorization", format!("{scheme} {TOKEN}"))
            .send()
            .await
            .expect("GET");
        assert_eq!(r.status(), StatusCode::OK, "scheme {scheme}");
    }
    for auth in [
        None,
        Some("Bearer wrong".to_string()),
        Some(format!("Basic {TOKEN}")),
    ] {
        let mut req = http.get(&url);
        if let Some(a) = &auth {
            req = req.header("authorization", a);
        }
        let r = req.send().await.expect("GET");
        assert_eq!(r.status(), StatusCode::UNAUTHORIZED, "{auth:?}");
        let h = r
            .headers()
            .get("www-authenticate")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string();
        assert!(h.starts_with("Bearer"), "{auth:?}: WWW-Authenticate '{h}'");
        let v: Value = r.json().await.expect("json");
        assert_eq!(v["error"]["code"], "unauthorized");
    }
    server.shutdown().await.expect("shutdown");

    // Off loopback a token needs 16 characters.
    let mut cfg = Config::new("0.0.0.0:0".parse().expect("addr"), tmp::run_root());
    cfg.token = Some("short-token".into());
    let e = cfg.validate().expect_err("short token off loopback");
    assert!(e.to_string().contains("16"), "{e}");
    cfg.token = Some(TOKEN.into());
    assert!(cfg.validate().is_ok());
}
