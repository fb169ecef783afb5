//! The bad-input suite (issue #8): every kind of broken file, in every format, through the
//! library and through the CLI. Each is refused with a one-line error naming the file and the
//! problem (exit code 1 on the CLI), or — where accepting is the sensible answer — accepted
//! with the documented outcome. Pipeline steps that cannot do their job say so with a typed
//! error ([`facesynth::error::Stage`]) that augment's `failures.json` carries.
//!
//! `tests/io/io_bad_input.rs` covers the same ground on the readers alone, more deeply (mutated
//! real files, limits per reader); this file is the end-to-end table.

use crate::common;

use facesynth::error::Stage;
use facesynth::io::{self, ReadLimits, read_mesh};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::Command;

const V1: &str = "#VRML V1.0 ascii\n";

fn wrl(points: &str, index: &str) -> String {
    format!(
        "{V1}Separator {{ Coordinate3 {{ point [{points}] }}\n IndexedFaceSet {{ coordIndex [{index}] }} }}\n"
    )
}

fn ply_ascii(vertices: usize, faces: usize, body: &str) -> String {
    format!(
        "ply\nformat ascii 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
         property float z\nelement face {faces}\nproperty list uchar int vertex_indices\n\
         end_header\n{body}"
    )
}

/// A binary little-endian PLY with float xyz and int indices.
fn ply_binary(declared_vertices: usize, points: &[[f32; 3]], faces: &[&[i32]]) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {declared_vertices}\n\
         property float x\nproperty float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        faces.len()
    )
    .into_bytes();
    for p in points {
        for c in p {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for f in faces {
        b.push(f.len() as u8);
        for i in *f {
            b.extend_from_slice(&i.to_le_bytes());
        }
    }
    b
}

/// 3 × 3 points in scanner row order (top row first), one `x y z` per line.
fn xyz_grid(z: impl Fn(usize) -> String) -> String {
    let mut s = String::new();
    for k in 0..9 {
        let (row, col) = (k / 3, k % 3);
        s.push_str(&format!("{col} {} {}\n", 2 - row, z(k)));
    }
    s
}

fn utf16(text: &str) -> Vec<u8> {
    let mut b = vec![0xff, 0xfe];
    for u in text.encode_utf16() {
        b.extend_from_slice(&u.to_le_bytes());
    }
    b
}

fn real_wrl() -> Vec<u8> {
    std::fs::read(common::gavab("cara1_frontal1.wrl")).unwrap()
}

fn facesynth(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_facesynth"))
        .args(args)
        .output()
        .unwrap()
}

/// The library refuses `path` with a one-line message naming it and saying one of `what`.
fn lib_refuses(path: &Path, what: &[&str]) -> String {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let msg = match catch_unwind(AssertUnwindSafe(|| read_mesh(path))) {
        Err(_) => panic!("{name}: the reader panicked"),
        Ok(Ok(m)) => panic!("{name}: accepted as a mesh of {} faces", m.face_count()),
        Ok(Err(e)) => e.to_string(),
    };
    assert!(msg.contains(&name), "{name}: not named in: {msg}");
    assert!(!msg.contains('\n'), "{name}: not one line: {msg}");
    assert!(
        what.iter().any(|w| msg.contains(w)),
        "{name}: does not say {what:?}: {msg}"
    );
    msg
}

/// `facesynth info PATH` exits with 1 and one stderr line naming the file and the problem.
fn cli_refuses(path: &Path, what: &[&str]) {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let out = facesynth(&["info".as_ref(), path.as_os_str()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
    assert!(out.stdout.is_empty(), "{name}: printed a result");
    assert_eq!(stderr.lines().count(), 1, "{name}: not one line: {stderr}");
    assert!(
        stderr.starts_with("facesynth: error: ") && stderr.contains(&name),
        "{name}: {stderr}"
    );
    assert!(
        what.iter().any(|w| stderr.contains(w)),
        "{name}: does not say {what:?}: {stderr}"
    );
}

/// Writes each case into a fresh folder and checks library and CLI refuse it.
fn refuse_all(cases: &[(&str, Vec<u8>, &[&str])]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, what) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        lib_refuses(&path, what);
        cli_refuses(&path, what);
    }
}

#[test]
fn truncated_files() {
    let w = real_wrl();
    let tri = ply_ascii(3, 1, "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    let bin = ply_binary(
        3,
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[&[0, 1, 2]],
    );
    refuse_all(&[
        ("cut.wrl", w[..w.len() / 2].to_vec(), &["file ends"]),
        (
            "cut.ply",
            tri.as_bytes()[..tri.len() - 3].to_vec(),
            &["truncated"],
        ),
        ("cut_bin.ply", bin[..bin.len() - 2].to_vec(), &["truncated"]),
        (
            "cut_header.ply",
            tri.as_bytes()[..40].to_vec(),
            &["end_header"],
        ),
        (
            "cut.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2".to_vec(),
            &["corners"],
        ),
        (
            "cut.xyz",
            b"0 0 0\n1 0 0\n0 1".to_vec(),
            &["expected 3 numbers"],
        ),
    ]);
}

#[test]
fn wrong_counts() {
    // The header promises more vertices than there are: the faces are read as vertices and
    // the data runs out; fewer than there are: data is left after the declared elements.
    let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let pts = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    refuse_all(&[
        (
            "more_declared.ply",
            ply_ascii(5, 1, body).into_bytes(),
            &["truncated"],
        ),
        (
            "fewer_declared.ply",
            ply_ascii(3, 1, &format!("{body}3 0 1 2\n")).into_bytes(),
            &["after the elements the header declares"],
        ),
        // Here the 4th vertex eats the face's 12 index bytes and the face's count is the last
        // byte (0): the reader sees a point cloud.
        (
            "more_declared_bin.ply",
            ply_binary(4, &pts, &[&[0, 1, 2]]),
            &["truncated", "out of range", "no faces"],
        ),
        (
            "fewer_declared_bin.ply",
            ply_binary(2, &pts, &[&[0, 1, 2]]),
            &["after the elements", "out of range"],
        ),
        // A list longer than the face's data.
        (
            "list_count.ply",
            ply_ascii(3, 1, "0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n").into_bytes(),
            &["truncated"],
        ),
    ]);
    // OBJ, VRML and xyz carry no counts: what a count would catch shows as a bad index
    // (`indices_out_of_range`) or a cut line (`truncated_files`).
}

#[test]
fn indices_out_of_range() {
    refuse_all(&[
        (
            "index.wrl",
            wrl("0 0 0, 1 0 0, 0 1 0", "0, 1, 3, -1").into_bytes(),
            &["refers to point 3"],
        ),
        (
            "negative.wrl",
            wrl("0 0 0, 1 0 0, 0 1 0", "0, 1, -2, -1").into_bytes(),
            &["negative index -2"],
        ),
        (
            "index.ply",
            ply_ascii(3, 1, "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").into_bytes(),
            &["vertex index 3 is out of range"],
        ),
        (
            "index_bin.ply",
            ply_binary(3, &[[0.0; 3]; 3], &[&[0, 1, 70_000]]),
            &["vertex index 70000 is out of range"],
        ),
        (
            "index.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_vec(),
            &["vertex 4"],
        ),
        (
            "negative.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n".to_vec(),
            &["vertex -4", "out of range", "refers"],
        ),
    ]);
}

#[test]
fn nan_and_infinite_coordinates() {
    let mut cases: Vec<(String, Vec<u8>)> = Vec::new();
    for bad in ["nan", "inf", "-inf"] {
        let tag = bad.replace('-', "neg");
        cases.push((
            format!("{tag}.wrl"),
            wrl(&format!("0 0 0, 1 {bad} 0, 0 1 0"), "0 1 2").into_bytes(),
        ));
        cases.push((
            format!("{tag}.ply"),
            ply_ascii(3, 1, &format!("0 0 0\n1 {bad} 0\n0 1 0\n3 0 1 2\n")).into_bytes(),
        ));
        cases.push((
            format!("{tag}.obj"),
            format!("v 0 0 0\nv 1 {bad} 0\nv 0 1 0\nf 1 2 3\n").into_bytes(),
        ));
        cases.push((
            format!("{tag}.xyz"),
            xyz_grid(|k| if k == 4 { bad.into() } else { "0".into() }).into_bytes(),
        ));
    }
    cases.push((
        "nan_bin.ply".into(),
        ply_binary(
            3,
            &[[0.0; 3], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]],
            &[&[0, 1, 2]],
        ),
    ));
    let table: Vec<(&str, Vec<u8>, &[&str])> = cases
        .iter()
        .map(|(n, b)| (n.as_str(), b.clone(), &["non-finite"][..]))
        .collect();
    refuse_all(&table);
}

#[test]
fn huge_coordinates_are_refused_as_out_of_range() {
    // 2e9 mm = 2000 km: a corrupt number or other units, never a face.
    let big = "2e9";
    refuse_all(&[
        (
            "big.wrl",
            wrl(&format!("0 0 0, {big} 0 0, 0 1 0"), "0 1 2").into_bytes(),
            &["beyond the limit"],
        ),
        (
            "big.ply",
            ply_ascii(3, 1, &format!("0 0 0\n{big} 0 0\n0 1 0\n3 0 1 2\n")).into_bytes(),
            &["beyond the limit"],
        ),
        (
            "big_bin.ply",
            ply_binary(
                3,
                &[[0.0; 3], [0.0, 2e9, 0.0], [0.0, 1.0, 0.0]],
                &[&[0, 1, 2]],
            ),
            &["beyond the limit"],
        ),
        (
            "big.obj",
            format!("v 0 0 0\nv {big} 0 0\nv 0 1 0\nf 1 2 3\n").into_bytes(),
            &["beyond the limit"],
        ),
        (
            "big.xyz",
            xyz_grid(|k| if k == 4 { big.into() } else { "0".into() }).into_bytes(),
            &["beyond the limit"],
        ),
    ]);
    // The bound is a limit like the others: raised, the same file reads.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.obj");
    std::fs::write(&path, format!("v 0 0 0\nv {big} 0 0\nv 0 1 0\nf 1 2 3\n")).unwrap();
    let limits = ReadLimits {
        max_abs_coordinate_mm: 1e10,
        ..ReadLimits::default()
    };
    assert_eq!(io::read_mesh_with(&path, &limits).unwrap().face_count(), 1);
}

#[test]
fn no_vertices_and_empty_files() {
    refuse_all(&[
        ("empty.wrl", Vec::new(), &["empty"]),
        ("empty.ply", Vec::new(), &["empty"]),
        ("empty.obj", Vec::new(), &["empty"]),
        ("empty.xyz", Vec::new(), &["empty"]),
        ("none.wrl", wrl("", "").into_bytes(), &["no faces"]),
        (
            "none.ply",
            ply_ascii(0, 0, "").into_bytes(),
            &["no vertices"],
        ),
        ("none.obj", b"# nothing\n".to_vec(), &["no vertices"]),
        ("none.xyz", b"# nothing\n".to_vec(), &["no points"]),
        // Vertices but every face degenerate: nothing left.
        (
            "all_degenerate.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\nf 3 3 3\n".to_vec(),
            &["no faces"],
        ),
    ]);
}

/// Accepted inputs, with what the reader makes of them.
#[test]
fn one_face_degenerate_duplicate_and_non_manifold_faces_are_accepted_sensibly() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    // One face is a mesh, in every format that has faces.
    for p in [
        write("one.wrl", wrl("0 0 0, 1 0 0, 0 1 0", "0 1 2 -1").as_bytes()),
        write(
            "one.ply",
            ply_ascii(3, 1, "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").as_bytes(),
        ),
        write("one.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
    ] {
        let m = read_mesh(&p).unwrap();
        assert_eq!(
            (m.vertex_count(), m.face_count()),
            (3, 1),
            "{}",
            p.display()
        );
        let out = facesynth(&["info".as_ref(), p.as_os_str()]);
        assert!(out.status.success());
        let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(info["faces"], 1);
    }
    // Duplicate faces (same vertices, either orientation) are dropped: 2 faces remain.
    let dup = write(
        "dup.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 1 2 3\nf 3 2 1\n",
    );
    let m = read_mesh(&dup).unwrap();
    assert_eq!(m.face_count(), 2);
    let dup_ply = write(
        "dup.ply",
        ply_ascii(3, 2, "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 1 2 0\n").as_bytes(),
    );
    assert_eq!(read_mesh(&dup_ply).unwrap().face_count(), 1);
    // Repeated corners: merged when consecutive, the face dropped when no area is left.
    let degen = write(
        "degenerate.obj",
        b"v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 2 4\nf 1 1 4\nf 1 2 3\n",
    );
    let m = read_mesh(&degen).unwrap();
    // `f 1 2 2 4` → triangle 1 2 4; `f 1 1 4` dropped; the collinear `f 1 2 3` is kept (no
    // area: it adds nothing to the area-weighted normals, which stay finite).
    assert_eq!(m.face_count(), 2);
    assert_eq!(m.faces.get(0), &[0, 1, 3]);
    assert!(m.normals.iter().all(|n| n.is_finite()));
    // A non-manifold edge (three faces on edge 1–2) is kept; topology copes with it.
    let nm = write(
        "nonmanifold.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n",
    );
    let m = read_mesh(&nm).unwrap();
    assert_eq!(m.face_count(), 3);
    let t = facesynth::mesh::Topology::new(&m);
    assert_eq!(t.neighbours(0).len(), 4);
    let out = facesynth(&["info".as_ref(), nm.as_os_str()]);
    assert!(out.status.success());
}

#[test]
fn wrong_encoding_and_binary_garbage() {
    let garbage: Vec<u8> = (0u32..4000)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    refuse_all(&[
        (
            "utf16.wrl",
            utf16(&wrl("0 0 0, 1 0 0, 0 1 0", "0 1 2")),
            &["UTF-16"],
        ),
        (
            "utf16.ply",
            utf16(&ply_ascii(3, 1, "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")),
            &["UTF-16"],
        ),
        (
            "utf16.obj",
            utf16("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
            &["UTF-16"],
        ),
        ("utf16.xyz", utf16("0 0 0\n1 0 0\n0 1 0\n"), &["UTF-16"]),
        (
            "utf16be_no_bom.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
                .encode_utf16()
                .flat_map(|u| u.to_be_bytes())
                .collect(),
            &["UTF-16"],
        ),
        ("garbage.wrl", garbage.clone(), &["not a VRML file"]),
        ("garbage.ply", garbage.clone(), &["not a PLY file"]),
        (
            "garbage.obj",
            garbage.clone(),
            &["no vertices", "not a number"],
        ),
        ("garbage.xyz", garbage, &["not text", "not a number"]),
        ("gzip.wrl", vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0], &["gzip"]),
    ]);
}

#[test]
fn a_directory_instead_of_a_file_and_a_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["wrl", "ply", "obj", "xyz"] {
        let p = dir.path().join(format!("folder.{ext}"));
        std::fs::create_dir(&p).unwrap();
        lib_refuses(&p, &["is a directory"]);
        cli_refuses(&p, &["is a directory"]);
        let missing = dir.path().join(format!("missing.{ext}"));
        lib_refuses(&missing, &["No such file"]);
        cli_refuses(&missing, &["No such file"]);
    }
    // Text inputs go through the same checks.
    let p = dir.path().join("folder.json");
    std::fs::create_dir(&p).unwrap();
    let e = facesynth::pipeline::read_landmarks(&p)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("folder.json") && e.contains("is a directory"),
        "{e}"
    );
}

#[cfg(unix)]
#[test]
fn unreadable_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    for ext in ["wrl", "ply", "obj", "xyz"] {
        let p = dir.path().join(format!("locked.{ext}"));
        std::fs::write(&p, b"v 0 0 0\n").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o000)).unwrap();
        // As root (CI containers) mode 000 is still readable: then the content decides, and
        // the error is the parse error, still naming the file.
        let readable = std::fs::File::open(&p).is_ok();
        let what: &[&str] = if readable {
            &["locked."]
        } else {
            &["Permission denied"]
        };
        lib_refuses(&p, what);
        cli_refuses(&p, what);
        if !readable {
            let e = lib_refuses(&p, what);
            assert!(!e.contains("no faces"), "{e}");
        }
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o644)).unwrap();
    }
}

#[test]
fn limits_are_flags_on_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("scan.wrl");
    std::fs::write(&p, real_wrl()).unwrap();
    let run = |flags: &[&str]| {
        let mut args: Vec<&std::ffi::OsStr> = vec!["info".as_ref(), p.as_os_str()];
        args.extend(flags.iter().map(std::ffi::OsStr::new));
        facesynth(&args)
    };
    assert!(run(&[]).status.success());
    for (flags, what) in [
        (&["--max-vertices", "1000"][..], "--max-vertices"),
        (&["--max-file-mb", "0"][..], "--max-file-mb"),
    ] {
        let out = run(flags);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("scan.wrl") && stderr.contains(what) && stderr.lines().count() == 1,
            "{stderr}"
        );
    }
    // Raised, the same limit lets the scan through.
    assert!(run(&["--max-vertices", "14000"]).status.success());
}

fn grid_obj(path: &Path, n: usize, z: impl Fn(f64, f64) -> f64) {
    let mut s = String::new();
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (
                (i as f64 - n as f64 / 2.0) * 2.0,
                (j as f64 - n as f64 / 2.0) * 2.0,
            );
            s.push_str(&format!("v {x} {y} {}\n", z(x, y)));
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i + 1;
            s.push_str(&format!("f {v} {} {} {}\n", v + 1, v + 1 + n, v + n));
        }
    }
    std::fs::write(path, s).unwrap();
}

fn sphere(x: f64, y: f64) -> f64 {
    (80.0f64 * 80.0 - x * x - y * y).max(0.0).sqrt()
}

/// A flat plane and a sphere are meshes but not faces: the landmark step says what it could
/// not find, typed as [`Stage::Landmarks`], on the CLI and in augment's failure list.
#[test]
fn pipeline_steps_report_what_they_could_not_do_as_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let plane = dir.path().join("plane_frontal1.obj");
    let ball = dir.path().join("ball_frontal1.obj");
    let single = dir.path().join("single_frontal1.obj");
    grid_obj(&plane, 60, |_, _| 0.0);
    grid_obj(&ball, 60, sphere);
    std::fs::write(&single, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();

    for (path, what) in [
        (&plane, "nothing protrudes like a nose"),
        (&ball, "nothing protrudes like a nose"),
        (&single, "facial segmentation"),
    ] {
        let e = facesynth::pipeline::prepare_scan(path, None, &facesynth::generic_face::build())
            .unwrap_err();
        assert_eq!(e.stage(), Stage::Landmarks, "{e}");
        let msg = e.to_string();
        assert!(msg.contains(path.file_name().unwrap().to_str().unwrap()) && msg.contains(what));
        let out = facesynth(&["landmarks".as_ref(), path.as_os_str()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(what), "{stderr}");
        // The message is not repeated (the error chain is printed once).
        assert_eq!(stderr.matches(what).count(), 1, "{stderr}");
    }

    // The batch goes on and lists each with its stage.
    let out = dir.path().join("aug");
    let (done, failed) = facesynth::augment::augment(
        dir.path(),
        &out,
        &facesynth::augment::AugmentParams::default(),
        &|_, _, _| {},
    )
    .unwrap();
    assert!(done.is_empty());
    assert_eq!(failed.len(), 3);
    let list: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("failures.json")).unwrap()).unwrap();
    let list = list.as_array().unwrap();
    assert_eq!(list.len(), 3);
    for f in list {
        assert_eq!(f["stage"], "landmarks", "{f}");
        let scan = PathBuf::from(f["scan"].as_str().unwrap());
        let name = scan.file_name().unwrap().to_str().unwrap();
        assert!(f["reason"].as_str().unwrap().contains(name), "{f}");
        // No subject folder is marked done.
        let stem = scan.file_stem().unwrap();
        assert!(!out.join(stem).join("done.json").exists());
    }
}

/// An ill-posed FEM model is a typed error with the FEM stage (the variants themselves are
/// checked in tests/algorithms/fem_face.rs).
#[test]
fn fem_singular_and_invalid_materials_are_typed_fem_errors() {
    use facesynth::fem::{FaceModel, FemParams};
    let face = facesynth::generic_face::build();
    let mut model = FaceModel::from_generic(&face, &FemParams::default()).unwrap();
    let e = model
        .set_fixed_nodes(vec![false; model.volume.nodes_mm.len()])
        .unwrap_err();
    assert!(matches!(
        e,
        facesynth::Error::Fem(facesynth::FemError::NoFixedNodes)
    ));
    assert_eq!(e.stage(), Stage::Fem);
    assert!(e.to_string().contains("singular"), "{e}");
    let mut bad = FemParams::default();
    bad.skin.young_modulus_pa = f64::NAN;
    let e = FaceModel::from_generic(&face, &bad).unwrap_err();
    assert_eq!(e.stage(), Stage::Fem);
    // Named with the scan when it happens in the pipeline.
    let e = e.in_file(Path::new("subj000_frontal1.wrl"));
    assert_eq!(e.stage(), Stage::Fem);
    assert!(
        e.to_string().starts_with("subj000_frontal1.wrl: fem: "),
        "{e}"
    );
}

#[test]
fn text_inputs_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, Vec<u8>, &str); 5] = [
        (
            "points.json",
            b"{\"nose_tip\": [0, 0".to_vec(),
            "not a landmark file",
        ),
        (
            "partial.json",
            b"{\"nose_tip\": [0, 0, 1]}".to_vec(),
            "not a landmark file",
        ),
        ("utf16.json", utf16("{}"), "not UTF-8"),
        (
            "presets.ron",
            b"(expressions: [(name: 3".to_vec(),
            "presets.ron",
        ),
        ("muscles.ron", b"(muscles: [".to_vec(), "muscles.ron"),
    ];
    for (name, bytes, what) in cases {
        let p = dir.path().join(name);
        std::fs::write(&p, &bytes).unwrap();
        let e = if name.ends_with(".json") {
            facesynth::pipeline::read_landmarks(&p).map(|_| ())
        } else if name.starts_with("presets") {
            facesynth::fem::expressions::ExpressionSet::load(&p).map(|_| ())
        } else {
            facesynth::fem::muscles::MuscleSet::load(&p).map(|_| ())
        }
        .unwrap_err()
        .to_string();
        assert!(
            e.contains(name) && e.contains(what) && !e.contains('\n'),
            "{e}"
        );
    }
    // The sidecar parser too.
    let p = dir.path().join("scan.json");
    std::fs::write(&p, b"{\"subject\": 1}").unwrap();
    let e = facesynth::ground_truth::ScanTruth::load(&p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("scan.json"), "{e}");
}

/// A write that fails half-way leaves the old file as it was and no temporary file; a write
/// into a missing folder or onto a directory is an error naming the path.
#[test]
fn atomic_writes_keep_the_old_file_when_a_write_fails() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("report.json");
    io::write_text_atomic(&path, "old\n").unwrap();
    let e = io::write_atomic(&path, |w| {
        w.write_all(b"half a rep")?;
        Err(std::io::Error::other("disk full"))
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("report.json") && e.contains("disk full"), "{e}");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from("report.json")]);
    // The temporary name is hidden, unique per write, and no reader takes it for a mesh.
    let a = io::temp_path_for(&dir.path().join("smile.ply"));
    let b = io::temp_path_for(&dir.path().join("smile.ply"));
    assert_ne!(a, b);
    assert!(io::MeshFormat::from_path(&a).is_err(), "{}", a.display());
    // Targets that cannot be written.
    let mesh = read_mesh(&common::gavab("cara1_frontal1.wrl")).unwrap();
    for bad in [
        dir.path().join("no/such/dir/x.ply"),
        dir.path().to_path_buf(),
    ] {
        let bad = if bad.extension().is_none() {
            let d = dir.path().join("folder.ply");
            std::fs::create_dir_all(&d).unwrap();
            d
        } else {
            bad
        };
        let e = io::write_mesh(&bad, &mesh).unwrap_err().to_string();
        assert!(e.contains(bad.to_str().unwrap()), "{e}");
        let out = facesynth(&[
            "convert".as_ref(),
            common::gavab("cara1_frontal1.wrl").as_os_str(),
            bad.as_os_str(),
        ]);
        assert_eq!(out.status.code(), Some(1));
        assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 1);
    }
}
