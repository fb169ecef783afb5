//! Headless command implementations behind `facesynth <command>`; `main.rs` only parses.
