//! The landmark-file parser (JSON name → [x, y, z]) on arbitrary text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("points.json");
    match facesynth::pipeline::parse_landmarks(text, path) {
        Ok(l) => assert!(l.iter().all(|(_, x)| x.is_finite())),
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("points.json") && !msg.contains('\n'), "{msg}");
        }
    }
});
