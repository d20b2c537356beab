//! The error body of every 4xx/5xx answer: `{"error": {"code", "message", "field"}}`.

use serde::{Deserialize, Serialize};

/// The JSON body of an error answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ErrorBody {
    pub error: ErrorDetail,
}

/// What went wrong.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ErrorDetail {
    /// Stable code, e.g. `malformed_json`, `invalid_value`, `not_found`, `queue_full`.
    pub code: String,
    pub message: String,
    /// Path of the offending request field (`robots[0].config.right_elbow`), if any.
    pub field: Option<String>,
}
