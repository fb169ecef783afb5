//! The paper's steps on their own: curvature, denoising, feature points, registration, the FEM, recognition.
//!
//! One test binary per group (CI links four instead of 23); each module is one former
//! `tests/<name>.rs`.

#[path = "../common/mod.rs"]
mod common;

mod curvature;
mod denoise;
mod fem_element;
mod fem_face;
mod fem_fit;
mod generic_face;
mod landmarks;
mod recognition;
mod registration;
