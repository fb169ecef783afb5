//! VRML reader against the real GavabDB scans and small hand-written VRML 2.0 files.

use facesynth::io::{ReadLimits, read_mesh, vrml};
use std::path::{Path, PathBuf};

const GAVAB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/gavabdb");

fn scan(name: &str) -> PathBuf {
    Path::new(GAVAB).join(name)
}

#[test]
fn cara1_frontal1_counts() {
    let m = read_mesh(&scan("cara1_frontal1.wrl")).unwrap();
    assert_eq!(m.vertex_count(), 13_709);
    let c = m.face_counts();
    assert_eq!(
        (c.faces, c.quads, c.triangles, c.other),
        (13_395, 13_215, 180, 0)
    );
    // Points come out exactly as written (scaleFactor 0.5 ignored, zero translations).
    assert_eq!(m.positions_mm[0], glam::DVec3::new(10.35, 111.83, -1258.74));
    let (lo, hi) = m.bbox_mm().unwrap();
    assert_eq!((lo.x, hi.x), (-102.77, 115.07));
}

#[test]
fn cara1_sonrisa_counts() {
    let m = read_mesh(&scan("cara1_sonrisa.wrl")).unwrap();
    assert_eq!(m.vertex_count(), 13_296);
    let c = m.face_counts();
    assert_eq!(
        (c.faces, c.quads, c.triangles, c.other),
        (12_920, 12_687, 233, 0)
    );
}

/// Whole-scan widths (face plus hair and neck) run from 178 mm (abajo) to 253 mm (sonrisa);
/// applying the file's `scaleFactor 0.5` would give 89–126 mm, so 150–300 mm tells millimetres
/// from half-millimetres.
#[test]
fn all_cara1_scans_parse_in_millimetres() {
    let names = [
        "abajo",
        "arriba",
        "derecha",
        "frontal1",
        "frontal2",
        "gesto",
        "izquierda",
        "risa",
        "sonrisa",
    ];
    for n in names {
        let path = scan(&format!("cara1_{n}.wrl"));
        let m = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
        let (lo, hi) = m.bbox_mm().unwrap();
        let width = hi.x - lo.x;
        assert!(
            (150.0..300.0).contains(&width),
            "{n}: bbox width {width} mm is not a face width in millimetres"
        );
        assert!(m.face_count() > 10_000, "{n}: {} faces", m.face_count());
        // The VIVID exporter writes faces counter-clockwise seen from the scanner (+z):
        // the mean normal must point towards +z.
        let mean: glam::DVec3 = m.normals.iter().copied().sum();
        assert!(mean.z > 0.5 * mean.length(), "{n}: mean normal {mean:?}");
    }
}

fn parse_str(s: &str) -> facesynth::Result<facesynth::Mesh> {
    vrml::parse(s.as_bytes(), Path::new("hand.wrl"), &ReadLimits::default())
}

#[test]
fn vrml2_shape_in_transform_with_def_use() {
    let m = parse_str(
        r#"#VRML V2.0 utf8
# two shapes sharing one DEF'd Coordinate, the second moved by a Transform
WorldInfo { title "test" info [ "a" "b" ] }
DEF Face Shape {
  appearance Appearance { material Material { diffuseColor 1 0 0 } }
  geometry IndexedFaceSet {
    coord DEF C Coordinate { point [ 0 0 0, 1 0 0, 1 1 0, 0 1 0 ] }
    texCoord TextureCoordinate { point [ 0 0, 1 0, 1 1, 0 1 ] }
    coordIndex [ 0, 1, 2, 3, -1 ]
  }
}
Transform {
  children [
    Shape { geometry IndexedFaceSet { coord USE C coordIndex [ 0 1 2 -1 ] ccw FALSE } }
  ]
  translation 10 0 0
  scale 2 2 2
}
ROUTE A.b TO C.d
"#,
    )
    .unwrap();
    assert_eq!(m.vertex_count(), 8);
    assert_eq!(m.face_count(), 2);
    assert_eq!(m.faces.get(0), &[0, 1, 2, 3]);
    // ccw FALSE → reversed; translated copy of the points, scale ignored.
    assert_eq!(m.faces.get(1), &[6, 5, 4]);
    assert_eq!(m.positions_mm[6], glam::DVec3::new(11.0, 1.0, 0.0));
}

#[test]
fn vrml2_use_of_whole_shape_and_proto_skipped() {
    let m = parse_str(
        r#"#VRML V2.0 utf8
PROTO Thing [ field SFVec3f size 1 1 1 ] { Box { size IS size } }
EXTERNPROTO Other [ field SFFloat x ] "other.wrl#Other"
Group { children [
  DEF S Shape { geometry IndexedFaceSet { coord Coordinate { point [0 0 0 1 0 0 0 1 0] }
                                           coordIndex [0 1 2] } }
  Transform { translation 0 0 5 rotation 0 0 1 1.5707963267948966 children USE S }
  Thing { size 2 2 2 }
] }
"#,
    )
    .unwrap();
    assert_eq!(m.vertex_count(), 6);
    assert_eq!(m.face_count(), 2);
    let p = m.positions_mm[4]; // (1,0,0) rotated 90° about z, then moved up 5
    assert!(
        (p - glam::DVec3::new(0.0, 1.0, 5.0)).length() < 1e-12,
        "{p:?}"
    );
}

#[test]
fn vrml2_use_of_unknown_name_is_an_error() {
    let e = parse_str("#VRML V2.0 utf8\nShape { geometry USE Nope }")
        .unwrap_err()
        .to_string();
    assert!(e.contains("hand.wrl") && e.contains("Nope"), "{e}");
}

#[test]
fn missing_header_is_an_error() {
    let e = parse_str("Separator { }").unwrap_err().to_string();
    assert!(
        e.contains("hand.wrl") && e.contains("not a VRML file"),
        "{e}"
    );
}
