//! Errors of the model loaders: every one names the file, the element and the reason.

use thiserror::Error;

/// A robot or scene description that cannot be used.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ModelError {
    /// The file could not be read.
    #[error("{file}: cannot read: {reason}")]
    Io { file: String, reason: String },
    /// The file is not well-formed XML / JSON.
    #[error("{file}: malformed: {reason}")]
    Syntax { file: String, reason: String },
    /// An element (XML element or JSON field) is invalid.
    #[error("{file}: {element}: {reason}")]
    Invalid {
        file: String,
        element: String,
        reason: String,
    },
}

impl ModelError {
    pub(crate) fn invalid(
        file: impl Into<String>,
        element: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        ModelError::Invalid {
            file: file.into(),
            element: element.into(),
            reason: reason.into(),
        }
    }

    /// The element (or JSON field path) the error is about, if any.
    pub fn element(&self) -> Option<&str> {
        match self {
            ModelError::Invalid { element, .. } => Some(element),
            _ => None,
        }
    }
}
