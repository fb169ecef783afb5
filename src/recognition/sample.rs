//! One recognition sample (a range image with its identity) and a file that could not become one.

use serde::Serialize;
use std::path::PathBuf;

/// A range image ready for recognition.
#[derive(Debug, Clone)]
pub struct Sample {
    pub subject: String,
    /// Scan kind (`frontal1`, `risa`, …) or `synthetic`.
    pub kind: String,
    pub path: PathBuf,
    /// Γ: the range image's depths (length `cols × rows`).
    pub features: Vec<f64>,
}

/// A file that could not be used, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Failure {
    pub file: PathBuf,
    pub reason: String,
}
