//! Meshes that parse must not crash the steps after reading either: denoise → curvature →
//! feature points → registration of the generic face, on whatever OBJ the fuzzer makes (small
//! limits keep one run short). Every step may refuse; none may panic or run away.
#![no_main]

use facesynth::io::{MeshFormat, ReadLimits, parse_mesh};
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use std::sync::OnceLock;

static GENERIC: OnceLock<facesynth::generic_face::GenericFace> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let limits = ReadLimits {
        max_vertices: 4000,
        ..ReadLimits::default()
    };
    let Ok(mut mesh) = parse_mesh(data, MeshFormat::Obj, Path::new("scan.obj"), &limits) else {
        return;
    };
    let _ = facesynth::denoise::denoise(&mut mesh, &Default::default());
    let _ = facesynth::curvature::compute(&mesh, &Default::default());
    let Ok(report) = facesynth::landmarks::detect(&mesh, &Default::default()) else {
        return;
    };
    let generic = GENERIC.get_or_init(facesynth::generic_face::build);
    let points = facesynth::pipeline::registration_points(&report.landmarks, true);
    let _ = facesynth::registration::register_points(generic, &mesh, &points, &Default::default());
});
