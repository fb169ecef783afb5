//! Readers and bad input: VRML, PLY, XYZ point clouds, mutated real scans, fuzz regressions.
//!
//! One test binary per group (CI links four instead of 23); each module is one former
//! `tests/<name>.rs`.

#[path = "../common/mod.rs"]
mod common;

mod bad_input;
mod fuzz_regressions;
mod io_bad_input;
mod io_ply;
mod io_timing;
mod io_vrml;
mod io_xyz;
