//! The JSON body extractor: content type, body size limit (413), nesting depth, strict parsing
//! with the path of the offending field in every error.

use std::sync::atomic::Ordering;

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{header, StatusCode};
use serde::de::DeserializeOwned;

use super::error::ApiError;
use super::BodyRead;

/// Deepest nesting of arrays/objects accepted in a request body.
pub const MAX_DEPTH: usize = 32;

/// A JSON request body parsed into `T`: 415 without a JSON content type, 413 over the body
/// limit, 408 when it does not arrive within the body timeout, 400 for malformed or too deeply nested JSON, 422 for well-formed JSON whose values do
/// not fit `T` (wrong type, unknown field, …) with the field path.
pub struct ApiJson<T>(pub T);

impl<S, T> FromRequest<S> for ApiJson<T>
where
    S: Send + Sync,
    T: DeserializeOwned,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        let json_type = req
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .map(|v| {
                let mime = v
                    .split(';')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_ascii_lowercase();
                mime == "application/json" || mime.ends_with("+json")
            })
            .unwrap_or(false);
        if !json_type {
            return Err(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported_media_type",
                "expected 'Content-Type: application/json'",
            ));
        }
        // The body must arrive within the server's body timeout (`BodyRead`, set per request
        // by the server's middleware); a client stalled mid-body gets 408 and the connection
        // is closed, so it cannot hold a connection (and its buffers) open.
        let read = req.extensions().get::<BodyRead>().cloned();
        // A body announced larger than the limit is refused at once, before any of it is
        // read (the limit also holds for a body without a length, as it arrives).
        if let Some(r) = &read {
            let announced = req
                .headers()
                .get(header::CONTENT_LENGTH)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.trim().parse::<u64>().ok());
            if announced.is_some_and(|n| n > r.limit as u64) {
                return Err(ApiError::too_large(r.limit));
            }
        }
        let deadline = read.as_ref().map(|r| r.deadline);
        let bytes = Bytes::from_request(req, state);
        let bytes = match deadline {
            Some(d) => tokio::time::timeout_at(d, bytes).await.map_err(|_| {
                ApiError::new(
                    StatusCode::REQUEST_TIMEOUT,
                    "body_timeout",
                    "the request body did not arrive in time",
                )
            })?,
            None => bytes.await,
        }
        .map_err(|e| {
            if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::new(
                    StatusCode::PAYLOAD_TOO_LARGE,
                    "body_too_large",
                    e.body_text(),
                )
            } else {
                ApiError::bad_request(format!("cannot read the body: {}", e.body_text()))
            }
        })?;
        if let Some(r) = read {
            r.complete.store(true, Ordering::SeqCst);
        }
        parse_json(&bytes).map(ApiJson)
    }
}

/// Parses a body: depth check, then strict deserialisation naming the field path on errors.
/// A number with no fractional part written as a float (`3.0`, `1e3`) is an integer, as JSON
/// Schema's `integer` says, so it fills an integer field as `3` would.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    check_depth(bytes, MAX_DEPTH)?;
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let mut value: serde_json::Value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = known_path(&e.path().to_string());
        classify(
            e.into_inner(),
            if path == "." { String::new() } else { path },
        )
    })?;
    de.end().map_err(|e| classify(e, String::new()))?;
    integral_floats_to_integers(&mut value);
    serde_path_to_error::deserialize(value).map_err(|e| {
        let path = known_path(&e.path().to_string());
        let inner = e.into_inner();
        classify(inner, if path == "." { String::new() } else { path })
    })
}

/// Rewrites every float of `v` that is a whole number within ±2^53 (exact in an `f64`) as an
/// integer; a float field reads the integer back as the same value.
fn integral_floats_to_integers(v: &mut serde_json::Value) {
    use serde_json::Value;
    const EXACT: f64 = 9_007_199_254_740_992.0; // 2^53
    match v {
        Value::Number(n) if n.is_f64() => {
            if let Some(x) = n.as_f64().filter(|x| x.fract() == 0.0 && x.abs() <= EXACT) {
                *v = if x < 0.0 {
                    Value::from(x as i64)
                } else {
                    Value::from(x as u64)
                };
            }
        }
        Value::Array(a) => a.iter_mut().for_each(integral_floats_to_integers),
        Value::Object(o) => o.values_mut().for_each(integral_floats_to_integers),
        _ => {}
    }
}

/// The field path without the segments serde could not name (`?`, e.g. inside malformed JSON):
/// `robots[0].?` → `robots[0]`, `?` and `.` → none.
fn known_path(path: &str) -> String {
    if path == "." {
        return String::new();
    }
    path.split('.')
        .take_while(|seg| *seg != "?" && !seg.starts_with("?["))
        .collect::<Vec<_>>()
        .join(".")
}

fn classify(e: serde_json::Error, path: String) -> ApiError {
    use serde_json::error::Category;
    match e.classify() {
        Category::Data => ApiError::invalid(path, strip_position(&e.to_string())),
        // Inside the document, "trailing characters" is a fixed-length array given more
        // elements than it has (e.g. a 3-vector of four): a bad value of that field.
        Category::Syntax
            if !path.is_empty() && e.to_string().starts_with("trailing characters") =>
        {
            ApiError::invalid(path, "too many elements for this fixed-length array")
        }
        Category::Syntax | Category::Eof | Category::Io => {
            ApiError::malformed(format!("malformed JSON: {e}")).at(path)
        }
    }
}

/// serde_json appends " at line L column C"; for data errors the field path says more.
fn strip_position(s: &str) -> String {
    match s.rfind(" at line ") {
        Some(i) => s[..i].to_string(),
        None => s.to_string(),
    }
}

/// Rejects bodies nested deeper than `max` arrays/objects (before parsing, so a hostile body
/// costs one linear scan).
pub fn check_depth(bytes: &[u8], max: usize) -> Result<(), ApiError> {
    let mut depth = 0usize;
    let mut in_string = false;
    let mut escaped = false;
    for &b in bytes {
        if in_string {
            if escaped {
                escaped = false;
            } else if b == b'\\' {
                escaped = true;
            } else if b == b'"' {
                in_string = false;
            }
            continue;
        }
        match b {
            b'"' => in_string = true,
            b'[' | b'{' => {
                depth += 1;
                if depth > max {
                    return Err(ApiError::malformed(format!(
                        "JSON nested deeper than {max} levels"
                    )));
                }
            }
            b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct T {
        a: Vec<Inner>,
    }
    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        x: f64,
    }

    #[test]
    fn field_path_of_wrong_type() {
        let e = parse_json::<T>(br#"{"a": [{"x": 1}, {"x": "no"}]}"#).unwrap_err();
        assert_eq!(e.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(e.field.as_deref(), Some("a[1].x"));
    }

    #[test]
    fn whole_floats_fill_integer_fields() {
        #[derive(serde::Deserialize, Debug)]
        struct I {
            n: u64,
            x: f64,
        }
        let v: I = parse_json(br#"{"n": 867.0, "x": 2}"#).expect("whole float");
        assert_eq!((v.n, v.x), (867, 2.0));
        let e = parse_json::<I>(br#"{"n": 1.5, "x": 0}"#).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("n"));
        let v: I = parse_json(br#"{"n": 1, "x": -0.0}"#).expect("zero");
        assert_eq!(v.x, 0.0);
    }

    #[test]
    fn malformed_json_names_no_unknown_field() {
        let e = parse_json::<T>(b"{\"a\": [{\"x\": 1}, {\"x\": ").unwrap_err();
        assert_eq!(e.code, "malformed_json");
        assert!(
            !e.field.as_deref().unwrap_or("").contains('?'),
            "{:?}",
            e.field
        );
        let e = parse_json::<T>(b"{\"a\" 1}").unwrap_err();
        assert_eq!(e.field, None);
        assert_eq!(known_path("robots[0].?"), "robots[0]");
        assert_eq!(known_path("?"), "");
    }

    #[test]
    fn malformed_and_deep() {
        assert_eq!(
            parse_json::<T>(b"{\"a\": [").unwrap_err().status,
            StatusCode::BAD_REQUEST
        );
        assert_eq!(
            parse_json::<T>(b"{\"a\": [NaN]}").unwrap_err().status,
            StatusCode::BAD_REQUEST
        );
        let deep = "[".repeat(1000) + &"]".repeat(1000);
        assert_eq!(
            parse_json::<T>(deep.as_bytes()).unwrap_err().code,
            "malformed_json"
        );
        assert!(check_depth(br#"{"s": "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[["}"#, 4).is_ok());
    }
}
