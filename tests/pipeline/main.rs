//! The batch commands end to end: the CLI, gallery augmentation and its resumption.
//!
//! One test binary per group (CI links four instead of 23); each module is one former
//! `tests/<name>.rs`.

#[path = "../common/mod.rs"]
mod common;

mod augment;
mod augment_resume;
mod cli;
mod corrections;
mod fem_cli;
mod fem_quality;
