//! The client crate stays small: `cargo tree -p manyhands-client -e normal` (what a controller
//! depending on it compiles) holds the API types, reqwest, serde and thiserror, and none of the
//! planning core or the server — no parry, nalgebra, axum, utoipa, or the `manyhands` crate.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

/// Packages a controller that only talks to the server must not compile.
const FORBIDDEN: [&str; 12] = [
    "manyhands",
    "parry3d",
    "parry3d-f64",
    "nalgebra",
    "axum",
    "axum-core",
    "utoipa",
    "redb",
    "rayon",
    "mesh-loader",
    "roxmltree",
    "tracing-subscriber",
];

/// The package names of `cargo tree -p PACKAGE -e normal --prefix none` in this workspace.
fn normal_dependencies(package: &str) -> BTreeSet<String> {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../Cargo.toml");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let out = Command::new(cargo)
        .args([
            "tree", "--locked", "-e", "normal", "--prefix", "none", "-p", package,
        ])
        .arg("--manifest-path")
        .arg(&workspace)
        .output()
        .expect("running cargo tree");
    assert!(
        out.status.success(),
        "cargo tree failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect()
}

#[test]
fn the_client_compiles_no_planning_core_and_no_server() {
    let deps = normal_dependencies("manyhands-client");
    // Not vacuous: the tree is the one expected.
    for needed in [
        "manyhands-client",
        "manyhands-api",
        "reqwest",
        "serde",
        "serde_json",
        "thiserror",
    ] {
        assert!(deps.contains(needed), "{needed} missing from {deps:?}");
    }
    let found: Vec<&str> = FORBIDDEN
        .iter()
        .copied()
        .filter(|f| deps.contains(*f))
        .collect();
    assert!(
        found.is_empty(),
        "manyhands-client depends on {found:?}; its tree: {deps:?}"
    );
}

#[test]
fn the_api_types_are_plain_serde_data() {
    // Without its `openapi` feature (the client's view) the API crate needs no HTTP stack either.
    let deps = normal_dependencies("manyhands-api");
    assert!(
        deps.contains("serde") && deps.contains("serde_json"),
        "{deps:?}"
    );
    let found: Vec<&str> = FORBIDDEN
        .iter()
        .copied()
        .chain(["reqwest", "hyper", "tokio"])
        .filter(|f| deps.contains(*f))
        .collect();
    assert!(
        found.is_empty(),
        "manyhands-api depends on {found:?}; its tree: {deps:?}"
    );
}
