//! The 3-D plan viewer at `/viewer` (and `/viewer?plan=ID`): a page and its script, built from
//! `viewer/` (three.js + urdf-loader) by `build.rs` and embedded in the binary. The page reads
//! everything through the public API — `GET /v1/plans/{id}`, `GET /v1/scenes/{name}`,
//! `GET /v1/robots/{name}`, `GET /v1/robots/{name}/urdf` (the collision model),
//! `GET /v1/robots/{name}/visuals` (the visual geometry, its meshes as OBJ text) and the scenes'
//! mesh shapes — so it shows exactly what a client sees. Both routes are static and hold no
//! data, so they are open on a server with `--token` (the page sends the token given as
//! `?token=` to the API calls).

use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};

/// The bundle (empty when npm was missing or failed at build time).
const VIEWER_JS: &str = include_str!(concat!(env!("OUT_DIR"), "/viewer.js"));
/// Why the bundle is empty (empty when it was built).
const VIEWER_STATUS: &str = include_str!(concat!(env!("OUT_DIR"), "/viewer_status.txt"));
const INDEX: &str = include_str!("../../viewer/index.html");

/// Whether this binary carries the viewer's bundle.
pub fn built() -> bool {
    !VIEWER_JS.is_empty()
}

/// Why the bundle is missing (empty when it was built).
pub fn not_built_reason() -> &'static str {
    VIEWER_STATUS
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// `GET /viewer`: the page, or (503) a page saying why this binary has no viewer.
pub async fn page() -> Response {
    if built() {
        ([(header::CACHE_CONTROL, "no-cache")], Html(INDEX)).into_response()
    } else {
        let body = format!(
            "<!doctype html><html><head><meta charset=\"utf-8\"><title>manyhands viewer: not built</title></head>\
             <body style=\"font-family: sans-serif; max-width: 48em; margin: 3em auto\">\
             <h1>The 3-D viewer was not built into this binary</h1>\
             <p>It is bundled with npm when manyhands is compiled, and that failed: <code>{}</code></p>\
             <p>Install Node.js (18 or newer) with npm, then rebuild (<code>cargo build --release</code>). \
             The rest of the server works without it.</p></body></html>",
            esc(VIEWER_STATUS)
        );
        (StatusCode::SERVICE_UNAVAILABLE, Html(body)).into_response()
    }
}

/// `GET /viewer/viewer.js`: the bundled script.
pub async fn script() -> Response {
    if built() {
        (
            [
                (header::CONTENT_TYPE, "text/javascript; charset=utf-8"),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            VIEWER_JS,
        )
            .into_response()
    } else {
        (
            StatusCode::SERVICE_UNAVAILABLE,
            [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
            format!(
                "console.error({});",
                serde_json::to_string(&format!("manyhands viewer not built: {VIEWER_STATUS}"))
                    .unwrap_or_default()
            ),
        )
            .into_response()
    }
}
