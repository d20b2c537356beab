//! The checked-in OpenAPI spec (`api/openapi.json`) must equal the one generated from the Rust
//! types. Regenerate with `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi` or
//! `manyhands serve --print-openapi > api/openapi.json`.

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
}
