//! The checked-in OpenAPI spec (`api/openapi.json`) must equal the one generated from the Rust
//! types. Regenerate with `MANYHANDS_UPDATE_OPENAPI=1 cargo test --test server_openapi` or
//! `manyhands serve --print-openapi > api/openapi.json`. The same holds for the standalone JSON
//! Schemas of the request bodies in `api/schemas/` (generated from the spec's components).

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
