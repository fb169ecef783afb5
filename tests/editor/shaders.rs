//! Every WGSL file in shaders/ parses and validates with naga (the compiler wgpu uses), so a
//! shader typo fails `cargo test` instead of the first frame of the editor.

fn validate(name: &str, source: &str) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
}

#[test]
fn every_shader_validates() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            validate(
                &path.display().to_string(),
                &std::fs::read_to_string(&path).unwrap(),
            );
            count += 1;
        }
    }
    assert!(
        count >= 2,
        "expected the viewport shaders in {}",
        dir.display()
    );
}

#[test]
fn shader_entry_points_exist() {
    let source = include_str!("../../shaders/mesh.wgsl");
    let module = naga::front::wgsl::parse_str(source).unwrap();
    let names: Vec<&str> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    for wanted in [
        "vs_mesh",
        "fs_mesh",
        "vs_line",
        "fs_line",
        "vs_marker",
        "fs_marker",
    ] {
        assert!(
            names.contains(&wanted),
            "mesh.wgsl lacks {wanted}: {names:?}"
        );
    }
}

#[test]
fn a_broken_shader_is_caught() {
    // Guards the test itself: naga must reject a type error.
    let bad = "@fragment fn f() -> @location(0) vec4<f32> { return vec3<f32>(1.0); }";
    let parsed = naga::front::wgsl::parse_str(bad);
    let rejected = match parsed {
        Err(_) => true,
        Ok(m) => naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&m)
        .is_err(),
    };
    assert!(rejected);
}
