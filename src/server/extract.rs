//! The JSON body extractor: content type, body size limit (413), nesting depth, strict parsing
//! with the path of the offending field in every error.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{header, StatusCode};
use serde::de::DeserializeOwned;

use super::error::ApiError;

/// Deepest nesting of arrays/objects accepted in a request body.
pub const MAX_DEPTH: usize = 32;

/// A JSON request body parsed into `T`: 415 without a JSON content type, 413 over the body
/// limit, 400 for malformed or too deeply nested JSON, 422 for well-formed JSON whose values do
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
        let bytes = Bytes::from_request(req, state).await.map_err(|e| {
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
        parse_json(&bytes).map(ApiJson)
    }
}

/// Parses a body: depth check, then strict deserialisation naming the field path on errors.
pub fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    check_depth(bytes, MAX_DEPTH)?;
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value: T = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = known_path(&e.path().to_string());
        let inner = e.into_inner();
        classify(inner, path)
    })?;
    de.end().map_err(|e| classify(e, String::new()))?;
    Ok(value)
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
