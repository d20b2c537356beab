//! The OpenAPI spec as an independent JSON Schema validator (the `jsonschema` crate) sees it:
//! the generated spec, a validator of one of its schemas, and the operation a request path
//! belongs to.

use serde_json::Value;

/// The spec the server generates (identical to `api/openapi.json`, `tests/server_openapi.rs`).
pub fn spec() -> Value {
    serde_json::from_str(&manyhands::server::openapi::openapi_json()).expect("spec")
}

/// A validator of `schema` (a component `$ref` or inline schema of the spec; references
/// resolve inside the spec).
pub fn validator(spec: &Value, schema: &Value) -> jsonschema::Validator {
    let doc = serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "components": spec["components"],
        "allOf": [schema],
    });
    jsonschema::draft202012::new(&doc).expect("the spec's schema compiles")
}

/// Every error of `x` against `v`, with where it is.
pub fn errors(v: &jsonschema::Validator, x: &Value) -> Vec<String> {
    v.iter_errors(x)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect()
}

/// The path template of the spec that `path` (query ignored) is an instance of, e.g.
/// `/v1/plans/{id}` for `/v1/plans/j-1?wait=3`.
pub fn template<'a>(spec: &'a Value, path: &str) -> Option<&'a str> {
    let path = path.split('?').next().unwrap_or(path);
    let parts: Vec<&str> = path.split('/').collect();
    spec["paths"].as_object()?.keys().find_map(|t| {
        let tp: Vec<&str> = t.split('/').collect();
        let same = tp.len() == parts.len()
            && tp
                .iter()
                .zip(&parts)
                .all(|(a, b)| (a.starts_with('{') && a.ends_with('}') && !b.is_empty()) || a == b);
        same.then_some(t.as_str())
    })
}
