//! The checked-in OpenAPI spec (`api/openapi.json`) must equal the one generated from the Rust
//! types. Regenerate with `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi` or
//! `manyhands serve --print-openapi > api/openapi.json`. The same holds for the standalone JSON
//! Schemas of the request bodies in `api/schemas/` (generated from the spec's components).

mod common;
use common::spec::{errors, validator};

use std::path::PathBuf;

#[test]
fn openapi_spec_matches_the_checked_in_copy() {
    let generated = manyhands::server::openapi::openapi_json();
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("api/openapi.json");
    if std::env::var_os("MANYHANDS_UPDATE_OPENAPI").is_some() {
        std::fs::write(&path, &generated).expect("writing api/openapi.json");
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "api/openapi.json is out of date with the Rust types; regenerate it with \
         `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi`"
    );
    let v: serde_json::Value = serde_json::from_str(&generated).expect("spec is JSON");
    assert!(v["openapi"].as_str().unwrap_or("").starts_with("3.1"));
    for p in [
        "/v1/robots/{name}",
        "/v1/scenes/{name}",
        "/v1/fk",
        "/v1/ik",
        "/v1/check",
        "/v1/plans",
        "/v1/plans/{id}",
        "/v1/plans/{id}/events",
        "/healthz",
        "/readyz",
        "/metrics",
    ] {
        assert!(v["paths"].get(p).is_some(), "{p} missing from the spec");
    }
    // Routes that run on the bounded query pool answer 503 with `Retry-After` when it is full.
    for p in [
        "/v1/meshes",
        "/v1/meshes/{name}",
        "/v1/scenes/{name}/meshes/{list}/{index}/{shape}",
        "/v1/robots/{name}/visuals",
        "/v1/robots/{name}/visuals/{link}/{index}",
    ] {
        let r = &v["paths"][p]["get"]["responses"]["503"];
        let text = r["description"].as_str().unwrap_or("");
        assert!(
            text.contains("Retry-After"),
            "GET {p}: no documented 503: {r}"
        );
    }
}

#[test]
fn request_body_schemas_match_the_checked_in_copies() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("api/schemas");
    let schemas = manyhands::server::openapi::request_schemas();
    if std::env::var_os("MANYHANDS_UPDATE_OPENAPI").is_some() {
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("api/schemas");
        for (f, text) in &schemas {
            std::fs::write(dir.join(f), text).expect("writing a schema");
        }
        return;
    }
    let names: Vec<&str> = schemas.iter().map(|(f, _)| f.as_str()).collect();
    for want in [
        "post-v1-fk.request.schema.json",
        "post-v1-ik.request.schema.json",
        "post-v1-ik-grasp.request.schema.json",
        "post-v1-ik-dual-arm.request.schema.json",
        "post-v1-ik-base-placement.request.schema.json",
        "post-v1-check.request.schema.json",
        "post-v1-grasp-quality.request.schema.json",
        "post-v1-plans.request.schema.json",
        "put-v1-robots-name.request.schema.json",
    ] {
        assert!(names.contains(&want), "{want} not generated: {names:?}");
    }
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    on_disk.sort();
    assert_eq!(
        on_disk, names,
        "api/schemas/ differs from the generated set; regenerate with \
         `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi`"
    );
    for (f, text) in &schemas {
        let disk = std::fs::read_to_string(dir.join(f)).unwrap_or_default();
        assert!(
            &disk == text,
            "api/schemas/{f} is out of date; regenerate with \
             `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi`"
        );
        // Self-contained: every reference resolves inside the file.
        let v: serde_json::Value = serde_json::from_str(text).expect("JSON");
        for r in text
            .match_indices("\"$ref\": \"")
            .map(|(i, m)| &text[i + m.len()..])
        {
            let target = &r[..r.find('"').unwrap_or(0)];
            let name = target
                .strip_prefix("#/$defs/")
                .unwrap_or_else(|| panic!("{f}: external $ref {target}"));
            assert!(
                v["$defs"].get(name).is_some(),
                "{f}: $ref {target} does not resolve"
            );
        }
    }
}

/// The README's `curl` request bodies with their method and path (`-d '…'` bodies only).
fn readme_bodies() -> Vec<(String, String, serde_json::Value)> {
    let readme =
        std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("README.md"))
            .expect("README.md");
    let text = readme.replace("\\\n", " ");
    let mut out = Vec::new();
    for chunk in text.split("curl ").skip(1) {
        let Some(rest) = chunk
            .strip_prefix("-X POST ")
            .map(|r| ("post", r))
            .or_else(|| chunk.strip_prefix("-X PUT ").map(|r| ("put", r)))
        else {
            continue;
        };
        let (method, rest) = rest;
        let target = rest
            .split_whitespace()
            .next()
            .unwrap_or("")
            .trim_matches('"');
        let Some(path) = target.strip_prefix("$S") else {
            continue;
        };
        let path = path.split('?').next().unwrap_or(path).to_string();
        let Some(i) = rest.find("-d '") else { continue };
        let body = &rest[i + 4..];
        let body = &body[..body.find('\'').expect("closing quote")];
        let v: serde_json::Value = serde_json::from_str(body)
            .unwrap_or_else(|e| panic!("README body of {method} {path} is not JSON: {e}\n{body}"));
        out.push((method.to_string(), path, v));
    }
    out
}

/// The spec's schemas are honest: every README request body validates against its operation's
/// request schema (with an independent JSON Schema validator), the server accepts it, and the
/// server's answer validates against the operation's response schema. Bodies the server refuses
/// (unknown field, no `kind`) the spec refuses too.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn readme_bodies_and_answers_validate_against_the_spec() {
    let spec: serde_json::Value =
        serde_json::from_str(&manyhands::server::openapi::openapi_json()).expect("spec");
    let bodies = readme_bodies();
    assert!(bodies.len() >= 14, "{} README bodies", bodies.len());
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir =
        common::tmp::run_root().join(format!("manyhands-spec-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut cfg = manyhands::server::Config::new("127.0.0.1:0".parse().expect("addr"), dir.clone());
    cfg.robots_dir = root.join("robots");
    cfg.scenes_dir = root.join("scenes");
    cfg.workers = 1;
    cfg.query_threads = 1;
    cfg.heavy_threads = 1;
    cfg.shutdown_grace = std::time::Duration::from_millis(100);
    let server = manyhands::server::Server::start(cfg).await.expect("server");
    let base = format!("http://{}", server.addr());
    let http = reqwest::Client::builder()
        .timeout(std::time::Duration::from_secs(120))
        .build()
        .expect("client");
    for (method, path, body) in &bodies {
        let op = &spec["paths"][path.as_str()][method.as_str()];
        let req_schema = &op["requestBody"]["content"]["application/json"]["schema"];
        assert!(req_schema.is_object(), "{method} {path}: no request schema");
        let v = validator(&spec, req_schema);
        let e = errors(&v, body);
        assert!(
            e.is_empty(),
            "README body of {method} {path} fails the spec: {e:?}\n{body}"
        );
        // What the server refuses, the spec refuses.
        if let Some(o) = body.as_object() {
            let mut extra = o.clone();
            extra.insert("no_such_field".into(), serde_json::json!(1));
            assert!(
                !v.is_valid(&serde_json::Value::Object(extra)),
                "{method} {path}: unknown field accepted"
            );
            if o.contains_key("kind") {
                let mut no_kind = o.clone();
                no_kind.remove("kind");
                assert!(
                    !v.is_valid(&serde_json::Value::Object(no_kind)),
                    "{path}: no kind accepted"
                );
            }
        }
        let m = if method == "put" {
            reqwest::Method::PUT
        } else {
            reqwest::Method::POST
        };
        let r = http
            .request(m, format!("{base}{path}"))
            .json(body)
            .send()
            .await
            .expect("request");
        let status = r.status().as_u16();
        let answer: serde_json::Value = r.json().await.unwrap_or(serde_json::Value::Null);
        assert!(
            (200..300).contains(&status),
            "the server refused the README body of {method} {path}: {status} {answer}"
        );
        let resp_schema =
            &op["responses"][status.to_string()]["content"]["application/json"]["schema"];
        assert!(
            resp_schema.is_object(),
            "{method} {path}: no schema for {status}"
        );
        let e = errors(&validator(&spec, resp_schema), &answer);
        assert!(
            e.is_empty(),
            "{method} {path}: the {status} answer fails the spec: {e:?}\n{answer}"
        );
    }
    eprintln!(
        "{} README bodies and their answers validate against api/openapi.json",
        bodies.len()
    );
    server.shutdown().await.expect("shutdown");
    let _ = std::fs::remove_dir_all(dir);
}
