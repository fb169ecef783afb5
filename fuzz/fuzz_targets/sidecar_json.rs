//! The ground-truth sidecar parser (synth_gavab.py's JSON) on arbitrary text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("scan.json");
    match facesynth::ground_truth::ScanTruth::parse(text, path) {
        Ok(t) => {
            let _ = t.feature_points();
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("scan.json") && !msg.contains('\n'), "{msg}");
        }
    }
});
