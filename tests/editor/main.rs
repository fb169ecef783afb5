//! The editor: its document model, the shaders, and screenshots of a real window (Xvfb).
//!
//! One test binary per group (CI links four instead of 23); each module is one former
//! `tests/<name>.rs`.

#[path = "../common/mod.rs"]
mod common;

mod editor_corrections;
mod editor_document;
mod shaders;
mod viewer_screenshot;
