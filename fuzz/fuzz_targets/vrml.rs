//! The vrml reader on arbitrary bytes: Ok or a one-line error naming the file, never a panic,
//! a hang or an allocation out of proportion to the input.
#![no_main]

use facesynth::io::{MeshFormat, ReadLimits, parse_mesh};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("scan.wrl");
    if let Err(e) = parse_mesh(data, MeshFormat::Vrml, path, &ReadLimits::default()) {
        let msg = e.to_string();
        assert!(msg.contains("scan.wrl") && !msg.contains('\n'), "{msg}");
    }
});
