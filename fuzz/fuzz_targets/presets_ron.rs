//! The expression-preset and muscle RON parsers on arbitrary text (the first byte picks which).
#![no_main]

use facesynth::fem::{expressions::ExpressionSet, muscles::MuscleSet};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let path = Path::new("user.ron");
    let r = if which & 1 == 0 {
        ExpressionSet::parse(text, path).map(|set| {
            // What the CLI and the editor do next with a loaded set.
            let names: Vec<String> = set.names().iter().map(|s| s.to_string()).collect();
            for e in &set.expressions {
                let _ = e.activations_for(&names);
            }
            let _ = set.select("all");
        })
    } else {
        MuscleSet::parse(text, path).map(|set| {
            let _ = set.names();
        })
    };
    if let Err(e) = r {
        let msg = e.to_string();
        assert!(msg.contains("user.ron") && !msg.contains('\n'), "{msg}");
    }
});
