//! Every reader refuses bad input with a one-line error naming the file and the problem, and
//! never panics, including on truncated and byte-flipped copies of real files.

use facesynth::io::{ReadLimits, obj, ply, read_mesh, read_mesh_with, vrml, xyz};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

const GAVAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/gavabdb");

fn real_wrl() -> Vec<u8> {
    std::fs::read(Path::new(GAVAB).join("cara1_frontal1.wrl")).unwrap()
}

fn real_xyz() -> Vec<u8> {
    std::fs::read(Path::new(GAVAB).join("pointclouds/cara8_abajo.txt")).unwrap()
}

fn real_mesh() -> facesynth::Mesh {
    read_mesh(&Path::new(GAVAB).join("cara1_frontal1.wrl")).unwrap()
}

fn real_ply() -> Vec<u8> {
    let mut b = Vec::new();
    ply::write_binary(&mut b, &real_mesh(), Some(("quality", &vec![0.5; 13_709]))).unwrap();
    b
}

fn real_ascii_ply() -> Vec<u8> {
    let m = real_mesh();
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.vertex_count(),
        m.face_count()
    );
    for p in &m.positions_mm {
        s.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    for f in m.faces.iter() {
        s.push_str(&f.len().to_string());
        for v in f {
            s.push_str(&format!(" {v}"));
        }
        s.push('\n');
    }
    s.into_bytes()
}

fn real_obj() -> Vec<u8> {
    let mut b = Vec::new();
    obj::write(&mut b, &real_mesh()).unwrap();
    b
}

/// Deterministic pseudo-random numbers (xorshift64), so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn garbage(len: usize, seed: u64) -> Vec<u8> {
    let mut r = Rng(seed);
    (0..len).map(|_| r.next() as u8).collect()
}

/// Writes `bytes` as `name` in `dir`, reads it back through `read_mesh`, and checks the error
/// names the file, says `what`, and is one line.
fn expect_err(dir: &Path, name: &str, bytes: &[u8], what: &[&str]) {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    expect_err_at(&path, what);
}

fn expect_err_at(path: &Path, what: &[&str]) {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    let msg = match catch_unwind(AssertUnwindSafe(|| read_mesh(path))) {
        Err(_) => panic!("{name}: the reader panicked"),
        Ok(Ok(m)) => panic!("{name}: read as a mesh of {} faces", m.face_count()),
        Ok(Err(e)) => e.to_string(),
    };
    assert!(
        msg.contains(&name),
        "{name}: error does not name the file: {msg}"
    );
    assert!(!msg.contains('\n'), "{name}: error is not one line: {msg}");
    assert!(
        what.iter().any(|w| msg.contains(w)),
        "{name}: error does not say {what:?}: {msg}"
    );
}

const V1: &str = "#VRML V1.0 ascii\n";
const PLY_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
    property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
    end_header\n";

#[test]
fn truncated_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let wrl = real_wrl();
    expect_err(d, "cut.wrl", &wrl[..wrl.len() * 3 / 5], &["file ends"]);
    expect_err(d, "cut_header.wrl", &wrl[..150], &["file ends"]);
    let ply = real_ply();
    expect_err(d, "cut.ply", &ply[..ply.len() / 2], &["truncated"]);
    expect_err(d, "cut_header.ply", &ply[..60], &["end_header"]);
    let aply = real_ascii_ply();
    expect_err(d, "cut_ascii.ply", &aply[..aply.len() / 2], &["truncated"]);
    // Cut inside the second number of a line: that line has too few values.
    let cloud = real_xyz();
    let nl = cloud.iter().position(|&c| c == b'\n').unwrap();
    expect_err(d, "cut.xyz", &cloud[..nl + 22], &["expected 3 numbers"]);
    // OBJ has no counts, so only a cut inside a line can be seen; here inside an `f` line.
    let o = real_obj();
    let last_f = o.windows(2).rposition(|w| w == b"\nf").unwrap();
    expect_err(d, "cut.obj", &o[..last_f + 5], &["corners"]);
}

#[test]
fn index_out_of_range() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    expect_err(
        d,
        "index.wrl",
        format!("{V1}Separator {{ Coordinate3 {{ point [0 0 0, 1 0 0, 0 1 0] }}\n IndexedFaceSet {{ coordIndex [0, 1, 3, -1] }} }}").as_bytes(),
        &["refers to point 3", "only 3 points"],
    );
    expect_err(
        d,
        "negative.wrl",
        format!("{V1}Separator {{ Coordinate3 {{ point [0 0 0, 1 0 0, 0 1 0] }}\n IndexedFaceSet {{ coordIndex [0, 1, -2, -1] }} }}").as_bytes(),
        &["negative index -2"],
    );
    expect_err(
        d,
        "index.ply",
        format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").as_bytes(),
        &["vertex index 3 is out of range"],
    );
    let mut b = real_ply();
    let n = b.len();
    b[n - 4..].copy_from_slice(&99_999i32.to_le_bytes());
    expect_err(
        d,
        "index_bin.ply",
        &b,
        &["vertex index 99999 is out of range"],
    );
    expect_err(
        d,
        "index.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        &["vertex 4"],
    );
    expect_err(
        d,
        "zero.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
        &["vertex 0"],
    );
}

#[test]
fn non_finite_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (name, bad) in [("nan", "nan"), ("inf", "inf"), ("neg_inf", "-Infinity")] {
        expect_err(
            d,
            &format!("{name}.wrl"),
            format!("{V1}Separator {{ Coordinate3 {{ point [0 0 0, 1 {bad} 0, 0 1 0] }} IndexedFaceSet {{ coordIndex [0 1 2] }} }}").as_bytes(),
            &["non-finite"],
        );
        expect_err(
            d,
            &format!("{name}.ply"),
            format!("{PLY_HEAD}0 0 0\n1 {bad} 0\n0 1 0\n3 0 1 2\n").as_bytes(),
            &["non-finite"],
        );
        expect_err(
            d,
            &format!("{name}.xyz"),
            format!("0 0 0\n1 0 0\n{bad} 1 0\n").as_bytes(),
            &["non-finite"],
        );
        expect_err(
            d,
            &format!("{name}.obj"),
            format!("v 0 0 0\nv 1 {bad} 0\nv 0 1 0\nf 1 2 3\n").as_bytes(),
            &["non-finite"],
        );
    }
    // NaN in binary PLY.
    let mut b = real_ply();
    let at = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    expect_err(d, "nan_bin.ply", &b, &["non-finite"]);
}

#[test]
fn empty_files_and_no_vertices() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for ext in ["wrl", "ply", "xyz", "txt", "obj"] {
        expect_err(d, &format!("empty.{ext}"), b"", &["empty"]);
    }
    expect_err(
        d,
        "novertices.wrl",
        format!(
            "{V1}Separator {{ Coordinate3 {{ point [] }} IndexedFaceSet {{ coordIndex [] }} }}"
        )
        .as_bytes(),
        &["no faces"],
    );
    expect_err(
        d,
        "nocoords.wrl",
        format!("{V1}Separator {{ IndexedFaceSet {{ coordIndex [0 1 2] }} }}").as_bytes(),
        &["no Coordinate3"],
    );
    expect_err(
        d,
        "empty_v2.wrl",
        b"#VRML V2.0 utf8\n# nothing here\n",
        &["no faces"],
    );
    expect_err(
        d,
        "novertices.ply",
        b"ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\n\
          property float y\nproperty float z\nend_header\n",
        &["no vertices"],
    );
    expect_err(
        d,
        "nofaces.ply",
        format!("{}0 0 0\n1 0 0\n0 1 0\n0\n", PLY_HEAD).as_bytes(),
        &["no faces"],
    );
    expect_err(d, "comments.xyz", b"# only a comment\n\n", &["no points"]);
    expect_err(
        d,
        "onepoint.xyz",
        b"1 2 3\n",
        &["cannot triangulate", "row order"],
    );
    expect_err(
        d,
        "novertices.obj",
        b"# nothing\ng group\n",
        &["no vertices"],
    );
    expect_err(d, "nofaces.obj", b"v 0 0 0\nv 1 0 0\n", &["no faces"]);
}

#[test]
fn unknown_extension_directory_and_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    expect_err(
        d,
        "scan.stl",
        b"solid x\nendsolid x\n",
        &["unknown mesh format"],
    );
    expect_err(d, "no_extension", b"v 0 0 0\n", &["unknown mesh format"]);
    let sub = d.join("folder.wrl");
    std::fs::create_dir(&sub).unwrap();
    expect_err_at(&sub, &["is a directory"]);
    expect_err_at(&d.join("missing.ply"), &["No such file", "not found"]);
    // The size limit is checked before reading.
    let path = d.join("big.xyz");
    std::fs::write(&path, real_xyz()).unwrap();
    let limits = ReadLimits {
        max_file_bytes: 1000,
        ..ReadLimits::default()
    };
    let e = read_mesh_with(&path, &limits).unwrap_err().to_string();
    assert!(e.contains("big.xyz") && e.contains("limit"), "{e}");
    let limits = ReadLimits {
        max_vertices: 100,
        ..ReadLimits::default()
    };
    for (name, bytes) in [
        ("many.wrl", real_wrl()),
        ("many.ply", real_ply()),
        ("many.xyz", real_xyz()),
        ("many.obj", real_obj()),
    ] {
        let path = d.join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = read_mesh_with(&path, &limits).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains("100"), "{e}");
    }
}

#[test]
fn random_binary_garbage() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let g = garbage(5000, 0x9e37_79b9_7f4a_7c15);
    expect_err(d, "garbage.wrl", &g, &["not a VRML file"]);
    expect_err(d, "garbage.ply", &g, &["not a PLY file"]);
    expect_err(d, "garbage.xyz", &g, &["not text", "not a number"]);
    expect_err(d, "garbage.obj", &g, &["no vertices", "not a number"]);
    // Garbage behind a valid header.
    let mut v = V1.as_bytes().to_vec();
    v.extend_from_slice(&g);
    expect_err(d, "garbage_body.wrl", &v, &["line"]);
    let mut p = b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n\
        property float y\nproperty float z\nelement face 100\n\
        property list uchar int vertex_indices\nend_header\n"
        .to_vec();
    p.extend_from_slice(&g);
    expect_err(
        d,
        "garbage_body.ply",
        &p,
        &["non-finite", "out of range", "truncated"],
    );
    expect_err(d, "gzip.wrl", &[0x1f, 0x8b, 8, 0, 0, 0], &["gzip"]);
}

/// Truncates each real file at 20 places and flips a byte at 20 places (half of them in the
/// first 2 KB, where headers and structure are); every result must be Ok or Err, not a panic.
#[test]
fn mutated_real_files_never_panic() {
    type Parse = fn(&[u8], &Path, &ReadLimits) -> facesynth::Result<facesynth::Mesh>;
    let inputs: [(&str, Vec<u8>, Parse); 5] = [
        ("m.wrl", real_wrl(), vrml::parse),
        ("m.ply", real_ply(), ply::parse),
        ("m_ascii.ply", real_ascii_ply(), ply::parse),
        ("m.xyz", real_xyz(), xyz::parse),
        ("m.obj", real_obj(), obj::parse),
    ];
    let limits = ReadLimits::default();
    let mut rng = Rng(0xdead_beef_cafe_f00d);
    let mut outcomes = [0usize; 2];
    for (name, bytes, parse) in &inputs {
        let path = PathBuf::from(name);
        let mut run = |what: String, data: &[u8]| {
            let r = catch_unwind(AssertUnwindSafe(|| {
                parse(data, &path, &limits).and_then(|m| {
                    m.validate()
                        .map_err(|e| facesynth::Error::invalid(&path, e))
                        .map(|()| m)
                })
            }));
            match r {
                Err(_) => panic!("{name}: panicked after {what}"),
                Ok(Ok(_)) => outcomes[0] += 1,
                Ok(Err(e)) => {
                    let msg = e.to_string();
                    assert!(msg.contains(name) && !msg.contains('\n'), "{what}: {msg}");
                    outcomes[1] += 1;
                }
            }
        };
        for k in 0..20 {
            let at = if k < 5 {
                k * 37
            } else {
                rng.below(bytes.len())
            };
            run(format!("truncating at {at}"), &bytes[..at]);
        }
        for k in 0..20 {
            let mut m = bytes.clone();
            let at = if k < 10 {
                rng.below(m.len().min(2048))
            } else {
                rng.below(m.len())
            };
            let old = m[at];
            let new = match k % 4 {
                0 => b'-',
                1 => b'}',
                2 => b'9',
                _ => rng.next() as u8,
            };
            m[at] = new;
            run(format!("setting byte {at} from {old} to {new}"), &m);
        }
    }
    // Sanity: the mutations do both things — some survive, most are refused.
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
}
