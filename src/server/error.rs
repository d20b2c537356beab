//! The one error type of the HTTP API. Every 4xx/5xx answer has the body
//! `{"error": {"code": "...", "message": "...", "field": "..." | null}}`.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

pub use manyhands_api::{ErrorBody, ErrorDetail};

use crate::model::ModelError;

/// An API error: HTTP status, a stable machine-readable `code`, a human message and, when the
/// error is about one field of the request, its path (`robots[1].start.right_elbow`).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{code}: {message}")]
pub struct ApiError {
    pub status: StatusCode,
    pub code: &'static str,
    pub message: String,
    pub field: Option<String>,
    /// Seconds for a `Retry-After` header (429/503).
    pub retry_after: Option<u64>,
}

impl ApiError {
    pub fn new(status: StatusCode, code: &'static str, message: impl Into<String>) -> ApiError {
        ApiError {
            status,
            code,
            message: message.into(),
            field: None,
            retry_after: None,
        }
    }

    /// Attaches the path of the offending field.
    pub fn at(mut self, field: impl Into<String>) -> ApiError {
        let f = field.into();
        self.field = (!f.is_empty()).then_some(f);
        self
    }

    pub fn bad_request(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::BAD_REQUEST, "bad_request", message)
    }

    pub fn malformed(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::BAD_REQUEST, "malformed_json", message)
    }

    /// A well-formed request with a value that cannot be used (422), naming the field.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> ApiError {
        let field = field.into();
        let message = message.into();
        let text = if field.is_empty() {
            message
        } else {
            format!("{field}: {message}")
        };
        ApiError::new(StatusCode::UNPROCESSABLE_ENTITY, "invalid_value", text).at(field)
    }

    pub fn not_found(field: impl Into<String>, message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::NOT_FOUND, "not_found", message).at(field)
    }

    pub fn conflict(message: impl Into<String>) -> ApiError {
        ApiError::new(StatusCode::CONFLICT, "conflict", message)
    }

    pub fn too_large(limit: usize) -> ApiError {
        ApiError::new(
            StatusCode::PAYLOAD_TOO_LARGE,
            "body_too_large",
            format!("request body larger than {limit} bytes"),
        )
    }

    pub fn unauthorized() -> ApiError {
        ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            "missing or wrong bearer token (header 'Authorization: Bearer TOKEN')",
        )
    }

    pub fn queue_full(retry_after: u64) -> ApiError {
        let mut e = ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            "queue_full",
            "the planning queue is full; retry later",
        );
        e.retry_after = Some(retry_after);
        e
    }

    pub fn unavailable(
        code: &'static str,
        message: impl Into<String>,
        retry_after: u64,
    ) -> ApiError {
        let mut e = ApiError::new(StatusCode::SERVICE_UNAVAILABLE, code, message);
        e.retry_after = Some(retry_after);
        e
    }

    /// A real server fault (5xx); logged at error level.
    pub fn internal(message: impl Into<String>) -> ApiError {
        let message = message.into();
        tracing::error!(error = %message, "internal error");
        ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", message)
    }

    /// A robot or scene upload that does not validate: 422 naming the element / field path under
    /// `prefix` (e.g. `urdf`, `srdf` or the scene body).
    pub fn from_model(e: &ModelError, prefix: &str) -> ApiError {
        match e {
            ModelError::Invalid {
                element, reason, ..
            } => {
                let field = if prefix.is_empty() {
                    element.clone()
                } else {
                    format!("{prefix}.{element}")
                };
                ApiError::invalid(field, reason.clone())
            }
            ModelError::Syntax { reason, .. } => {
                ApiError::invalid(prefix, format!("malformed: {reason}"))
            }
            ModelError::Io { reason, .. } => {
                ApiError::invalid(prefix, format!("cannot read: {reason}"))
            }
        }
    }

    pub fn detail(&self) -> ErrorDetail {
        ErrorDetail {
            code: self.code.to_string(),
            message: self.message.clone(),
            field: self.field.clone(),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = ErrorBody {
            error: self.detail(),
        };
        let mut resp = (self.status, axum::Json(body)).into_response();
        if self.status == StatusCode::UNAUTHORIZED {
            resp.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"manyhands\""),
            );
        }
        if let Some(s) = self.retry_after {
            if let Ok(v) = HeaderValue::from_str(&s.to_string()) {
                resp.headers_mut().insert(header::RETRY_AFTER, v);
            }
        }
        resp
    }
}

pub type ApiResult<T> = Result<T, ApiError>;
