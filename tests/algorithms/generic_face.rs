//! The built-in generic face: size, Table 2 proportions, symmetry, openings, quad quality,
//! and the OBJ + sidecar round trip of `generic_face::load`.

use facesynth::generic_face::{self, GenericFace, boundary_loops, targets};
use facesynth::mesh::Topology;
use facesynth::{FeaturePoint, Mesh};
use glam::DVec3;
use std::collections::HashSet;
use std::path::Path;
use std::sync::OnceLock;

fn face() -> &'static GenericFace {
    static FACE: OnceLock<GenericFace> = OnceLock::new();
    FACE.get_or_init(generic_face::build)
}

fn at(p: FeaturePoint) -> DVec3 {
    face().landmarks().get(p)
}

#[test]
fn size_and_quad_dominance() {
    let f = face();
    let c = f.mesh.face_counts();
    println!(
        "vertices {}, faces {}, quads {}, triangles {}, other {}",
        f.mesh.vertex_count(),
        c.faces,
        c.quads,
        c.triangles,
        c.other
    );
    assert!((2_500..=4_000).contains(&f.mesh.vertex_count()));
    assert_eq!(c.other, 0);
    assert!(c.quads as f64 >= 0.95 * c.faces as f64, "{c:?}");
    f.mesh.validate().unwrap();
    let (lo, hi) = f.mesh.bbox_mm().unwrap();
    let width = hi.x - lo.x;
    assert!((125.0..=160.0).contains(&width), "face width {width} mm");
    assert!(hi.y - lo.y > 140.0, "forehead to chin {} mm", hi.y - lo.y);
}

#[test]
fn feature_vertices_are_distinct_and_in_range() {
    let f = face();
    let ids: HashSet<u32> = f.feature_vertices.iter().copied().collect();
    assert_eq!(ids.len(), FeaturePoint::COUNT);
    assert!(ids.iter().all(|&v| (v as usize) < f.mesh.vertex_count()));
    assert_eq!(at(FeaturePoint::NoseTip), DVec3::ZERO);
}

#[test]
fn table2_distances_are_within_ten_percent_of_the_averages() {
    use FeaturePoint::*;
    let tip = at(NoseTip);
    let bridge_y = 0.5 * (at(InnerEyeLeft).y + at(InnerEyeRight).y);
    let checks = [
        (
            "nose tip → inner eye (x)",
            0.5 * ((at(InnerEyeLeft).x - tip.x).abs() + (at(InnerEyeRight).x - tip.x).abs()),
            targets::NOSE_TO_INNER_EYE_X,
            17.5,
        ),
        (
            "inner → outer eye (x)",
            0.5 * ((at(OuterEyeLeft).x - at(InnerEyeLeft).x).abs()
                + (at(OuterEyeRight).x - at(InnerEyeRight).x).abs()),
            targets::INNER_TO_OUTER_EYE_X,
            30.6,
        ),
        (
            "nose tip → mouth (y)",
            tip.y - 0.5 * (at(MouthCornerLeft).y + at(MouthCornerRight).y),
            targets::NOSE_TO_MOUTH_Y,
            34.4,
        ),
        (
            "nose tip → chin (y)",
            tip.y - at(Chin).y,
            targets::NOSE_TO_CHIN_Y,
            70.6,
        ),
        (
            "nose tip → nose bridge (y)",
            bridge_y - tip.y,
            targets::NOSE_TO_BRIDGE_Y,
            32.2,
        ),
    ];
    for (name, measured, target, paper) in checks {
        println!("{name}: {measured:.2} mm (paper average {paper} mm)");
        assert_eq!(target, paper);
        assert!(
            (measured - paper).abs() <= 0.1 * paper,
            "{name}: {measured} vs {paper}"
        );
    }
}

#[test]
fn feature_points_are_anatomically_ordered() {
    use FeaturePoint::*;
    // Left is the subject's left, +x.
    for p in [
        InnerEyeLeft,
        OuterEyeLeft,
        NoseCornerLeft,
        MouthCornerLeft,
        CheekLeft,
    ] {
        assert!(at(p).x > 5.0 && at(p.mirror()).x < -5.0, "{p}");
    }
    assert!(at(Forehead).y > at(InnerEyeLeft).y);
    assert!(at(InnerEyeLeft).y > at(NoseCornerLeft).y);
    assert!(at(NoseCornerLeft).y > at(MouthCornerLeft).y);
    assert!(at(MouthCornerLeft).y > at(Chin).y);
    assert!(at(OuterEyeLeft).x > at(InnerEyeLeft).x);
    assert!(at(CheekLeft).x > at(OuterEyeLeft).x);
    // The nose tip is the most anterior point; eye corners sit well behind it.
    let max_z = face()
        .mesh
        .positions_mm
        .iter()
        .map(|p| p.z)
        .fold(f64::MIN, f64::max);
    assert_eq!(max_z, 0.0);
    assert!(at(InnerEyeLeft).z < -15.0 && at(OuterEyeLeft).z < at(InnerEyeLeft).z);
}

#[test]
fn surface_and_feature_points_are_mirror_symmetric() {
    let f = face();
    let key = |p: DVec3| {
        (
            (p.x * 1e6).round() as i64,
            (p.y * 1e6).round() as i64,
            (p.z * 1e6).round() as i64,
        )
    };
    let all: HashSet<_> = f.mesh.positions_mm.iter().map(|&p| key(p)).collect();
    for &p in &f.mesh.positions_mm {
        let m = DVec3::new(-p.x, p.y, p.z);
        // Exact mirror up to 1e-9 mm: look the rounded key up, then compare exactly.
        assert!(all.contains(&key(m)), "no mirror vertex for {p:?}");
    }
    let mut sorted: Vec<DVec3> = f.mesh.positions_mm.clone();
    sorted.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
    for &p in &f.mesh.positions_mm {
        let m = DVec3::new(-p.x, p.y, p.z);
        let best = sorted
            .iter()
            .map(|q| (*q - m).length())
            .fold(f64::INFINITY, f64::min);
        assert!(best <= 1e-9, "mirror of {p:?} is {best} mm away");
    }
    let l = f.landmarks();
    for p in FeaturePoint::ALL {
        let a = l.get(p);
        let b = l.get(p.mirror());
        assert!((a - DVec3::new(-b.x, b.y, b.z)).length() <= 1e-9, "{p}");
    }
}

/// The boundary loop through vertex `v`.
fn loop_through(mesh: &Mesh, v: u32) -> Vec<u32> {
    boundary_loops(mesh)
        .into_iter()
        .find(|l| l.contains(&v))
        .unwrap_or_else(|| panic!("vertex {v} is on no boundary loop"))
}

/// Splits a loop at two of its vertices into the two paths between them (ends excluded).
fn split_loop(lp: &[u32], a: u32, b: u32) -> (Vec<u32>, Vec<u32>) {
    let ia = lp.iter().position(|&v| v == a).unwrap();
    let n = lp.len();
    let rot: Vec<u32> = (0..n).map(|k| lp[(ia + k) % n]).collect();
    let ib = rot.iter().position(|&v| v == b).unwrap();
    (rot[1..ib].to_vec(), rot[ib + 1..].to_vec())
}

#[test]
fn boundary_is_outer_border_two_eyes_and_the_mouth() {
    let f = face();
    let loops = boundary_loops(&f.mesh);
    assert_eq!(
        loops.len(),
        4,
        "loop sizes {:?}",
        loops.iter().map(Vec::len).collect::<Vec<_>>()
    );
    let topo = Topology::new(&f.mesh);
    let on_loops: usize = loops.iter().map(Vec::len).sum();
    assert_eq!(on_loops, topo.is_boundary.iter().filter(|&&b| b).count());
    for l in &loops {
        assert!(l.iter().all(|&v| topo.is_boundary[v as usize]));
    }
}

#[test]
fn the_lips_are_separate_boundaries_meeting_at_the_mouth_corners() {
    use FeaturePoint::*;
    let f = face();
    let p = &f.mesh.positions_mm;
    let (l, r) = (
        f.feature_vertex(MouthCornerLeft),
        f.feature_vertex(MouthCornerRight),
    );
    let lp = loop_through(&f.mesh, l);
    assert!(lp.contains(&r), "both mouth corners on the mouth's loop");
    assert!(lp.len() < 200, "the mouth is not the outer border");
    let (a, b) = split_loop(&lp, l, r);
    assert!(!a.is_empty() && !b.is_empty());
    let mean_y =
        |path: &[u32]| path.iter().map(|&v| p[v as usize].y).sum::<f64>() / path.len() as f64;
    let (upper, lower) = if mean_y(&a) > mean_y(&b) {
        (a, b)
    } else {
        (b, a)
    };
    let corner_y = p[l as usize].y;
    assert!(upper.iter().all(|&v| p[v as usize].y > corner_y));
    assert!(lower.iter().all(|&v| p[v as usize].y < corner_y));
    // Upper and lower lip are different vertices (the mouth can open), with a gap between them.
    let lower_set: HashSet<u32> = lower.iter().copied().collect();
    assert!(upper.iter().all(|v| !lower_set.contains(v)));
    let mid = |path: &[u32]| {
        *path
            .iter()
            .min_by(|&&a, &&b| p[a as usize].x.abs().total_cmp(&p[b as usize].x.abs()))
            .unwrap()
    };
    let gap = p[mid(&upper) as usize].y - p[mid(&lower) as usize].y;
    assert!((0.5..4.0).contains(&gap), "lip gap {gap} mm");
}

#[test]
fn the_eyes_are_holes_ending_at_the_eye_corners() {
    use FeaturePoint::*;
    let f = face();
    let p = &f.mesh.positions_mm;
    for (inner, outer) in [(InnerEyeLeft, OuterEyeLeft), (InnerEyeRight, OuterEyeRight)] {
        let (i, o) = (f.feature_vertex(inner), f.feature_vertex(outer));
        let lp = loop_through(&f.mesh, i);
        assert!(lp.contains(&o), "{inner} and {outer} on one hole");
        assert!(lp.len() < 100, "the eye is not the outer border");
        let (a, b) = split_loop(&lp, i, o);
        let height = |path: &[u32]| {
            path.iter()
                .map(|&v| p[v as usize].y - p[i as usize].y)
                .fold(0.0f64, |m, d| if d.abs() > m.abs() { d } else { m })
        };
        let (ha, hb) = (height(&a), height(&b));
        let opening = ha.abs() + hb.abs();
        assert!(ha * hb < 0.0, "one lid above, one below");
        assert!((5.0..14.0).contains(&opening), "eye opening {opening} mm");
    }
}

#[test]
fn quads_are_well_shaped() {
    let q = face().quad_quality();
    println!("{q:?}");
    assert!(q.min_scaled_jacobian > 0.5, "{q:?}");
    assert!(q.mean_scaled_jacobian > 0.9, "{q:?}");
    assert!(q.max_edge_ratio < 3.5, "{q:?}");
    assert!(q.min_edge_mm > 0.8 && q.max_edge_mm < 8.0, "{q:?}");
    assert!(q.max_warp_deg < 50.0, "{q:?}");
}

/// Projected onto a cylinder round a vertical axis behind the face (the paper's registration
/// projection), every quad keeps its orientation and stays convex: the surface has no folds
/// and no self-intersections.
#[test]
fn the_surface_is_a_graph_over_a_cylinder_without_folds() {
    let f = face();
    let axis_z = -85.0;
    let radius = 85.0;
    let proj = |p: DVec3| {
        let angle = p.x.atan2(p.z - axis_z);
        glam::DVec2::new(angle * radius, p.y)
    };
    for (k, poly) in f.mesh.faces.iter().enumerate() {
        let c: Vec<_> = poly
            .iter()
            .map(|&v| proj(f.mesh.positions_mm[v as usize]))
            .collect();
        for i in 0..c.len() {
            let (a, b, d) = (c[i], c[(i + 1) % c.len()], c[(i + c.len() - 1) % c.len()]);
            let cross = (b - a).perp_dot(d - a);
            assert!(cross > 0.0, "face {k} folds in the cylindrical projection");
        }
    }
}

/// For the FEM's extrusion: offsetting the surface 15 mm towards that vertical axis keeps every
/// quad of the inner layer convex and facing the same way (an offset along the vertex normals
/// would fold where the surface is more curved than the offset, e.g. at the nose).
#[test]
fn a_radial_offset_towards_the_cylinder_axis_does_not_fold() {
    let f = face();
    let axis_z = -85.0;
    let inner: Vec<DVec3> = f
        .mesh
        .positions_mm
        .iter()
        .map(|&p| p - 15.0 * DVec3::new(p.x, 0.0, p.z - axis_z).normalize())
        .collect();
    let layer = Mesh::new(inner, f.mesh.faces.clone());
    let q = generic_face::quad_quality(&layer);
    assert!(q.min_scaled_jacobian > 0.5, "{q:?}");
    for (k, poly) in f.mesh.faces.iter().enumerate() {
        let a = facesynth::mesh::face_normal(&f.mesh.positions_mm, poly);
        let b = facesynth::mesh::face_normal(&layer.positions_mm, poly);
        assert!(a.normalize().dot(b.normalize()) > 0.9, "face {k}");
    }
}

#[test]
fn normals_face_forwards_in_the_face_centre() {
    let f = face();
    let tip = f.feature_vertex(FeaturePoint::NoseTip) as usize;
    assert!(f.mesh.normals[tip].z > 0.9, "{:?}", f.mesh.normals[tip]);
    for (p, n) in f.mesh.positions_mm.iter().zip(&f.mesh.normals) {
        if p.x.abs() < 30.0 && p.y.abs() < 60.0 {
            assert!(n.z > 0.0, "normal {n:?} at {p:?}");
        }
    }
    // And outwards at the sides.
    for p in [FeaturePoint::CheekLeft, FeaturePoint::OuterEyeLeft] {
        let n = f.mesh.normals[f.feature_vertex(p) as usize];
        assert!(n.x > 0.3, "{p}: {n:?}");
    }
}

#[test]
fn build_is_deterministic() {
    let a = generic_face::build();
    let b = generic_face::build();
    assert_eq!(a.mesh, b.mesh);
    assert_eq!(a.feature_vertices, b.feature_vertices);
}

#[test]
fn obj_and_sidecar_round_trip_through_load() {
    let dir = tempfile::tempdir().unwrap();
    let f = face();
    for ext in ["json", "ron"] {
        let obj = dir.path().join("face.obj");
        let side = dir.path().join(format!("face.{ext}"));
        f.save(&obj, &side).unwrap();
        let back = generic_face::load(&obj, &side).unwrap();
        assert_eq!(back.feature_vertices, f.feature_vertices);
        assert_eq!(back.mesh.vertex_count(), f.mesh.vertex_count());
        assert_eq!(back.mesh.face_count(), f.mesh.face_count());
        let first_diff =
            (0..f.mesh.face_count()).find(|&k| back.mesh.faces.get(k) != f.mesh.faces.get(k));
        assert!(
            first_diff.is_none(),
            "face {first_diff:?}: {:?} vs {:?}",
            first_diff.map(|k| back.mesh.faces.get(k)),
            first_diff.map(|k| f.mesh.faces.get(k))
        );
        for (p, q) in back.landmarks().iter().zip(f.landmarks().iter()) {
            assert!((p.1 - q.1).length() < 1e-4, "{}: {} vs {}", p.0, p.1, q.1);
        }
    }
    // A hand-written RON sidecar reads too.
    let side = dir.path().join("hand.ron");
    let body: Vec<String> = FeaturePoint::ALL
        .iter()
        .map(|p| format!("\"{}\": {}", p.name(), f.feature_vertex(*p)))
        .collect();
    std::fs::write(&side, format!("{{\n  {}\n}}\n", body.join(",\n  "))).unwrap();
    let back = generic_face::load(&dir.path().join("face.obj"), &side).unwrap();
    assert_eq!(back.feature_vertices, f.feature_vertices);
    // RON struct syntax too.
    let body: Vec<String> = FeaturePoint::ALL
        .iter()
        .map(|p| format!("{}: {}", p.name(), f.feature_vertex(*p)))
        .collect();
    std::fs::write(&side, format!("(\n  {},\n)\n", body.join(",\n  "))).unwrap();
    let back = generic_face::load(&dir.path().join("face.obj"), &side).unwrap();
    assert_eq!(back.feature_vertices, f.feature_vertices);
}

#[test]
fn sidecar_ids_are_the_obj_files_own_vertex_order() {
    // Vertices listed in an order the faces do not follow, plus an unused one first.
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("v 9 9 9\n");
    for j in 0..4 {
        for i in 0..4 {
            text += &format!("v {i} {j} 0\n");
        }
    }
    for j in (0..3).rev() {
        for i in (0..3).rev() {
            let v = |i: usize, j: usize| 2 + j * 4 + i;
            text += &format!(
                "f {} {} {} {}\n",
                v(i, j),
                v(i + 1, j),
                v(i + 1, j + 1),
                v(i, j + 1)
            );
        }
    }
    let obj = dir.path().join("tiny.obj");
    std::fs::write(&obj, text).unwrap();
    let side = dir.path().join("tiny.json");
    let map: std::collections::BTreeMap<&str, usize> = FeaturePoint::ALL
        .iter()
        .enumerate()
        .map(|(k, p)| (p.name(), k + 1))
        .collect();
    std::fs::write(&side, serde_json::to_string(&map).unwrap()).unwrap();
    let f = generic_face::load(&obj, &side).unwrap();
    for (k, p) in FeaturePoint::ALL.iter().enumerate() {
        let expect = DVec3::new((k % 4) as f64, (k / 4) as f64, 0.0);
        assert_eq!(f.landmarks().get(*p), expect, "{p}");
    }
}

fn load_error(dir: &Path, name: &str, text: &str) -> String {
    let f = face();
    let obj = dir.join("face.obj");
    if !obj.exists() {
        facesynth::io::write_mesh(&obj, &f.mesh).unwrap();
    }
    let side = dir.join(name);
    std::fs::write(&side, text).unwrap();
    let msg = generic_face::load(&obj, &side).unwrap_err().to_string();
    assert!(msg.contains(name), "error names the file: {msg}");
    assert!(!msg.contains('\n'), "one line: {msg}");
    msg
}

#[test]
fn bad_sidecars_give_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut map = face().sidecar_map();
    map.remove("chin");
    let msg = load_error(d, "missing.json", &serde_json::to_string(&map).unwrap());
    assert!(msg.contains("chin") && msg.contains("missing"), "{msg}");

    let mut map = face().sidecar_map();
    map.insert("nose_tip".into(), 999_999);
    let msg = load_error(d, "range.json", &serde_json::to_string(&map).unwrap());
    assert!(msg.contains("nose_tip") && msg.contains("999999"), "{msg}");

    let mut map = face().sidecar_map();
    map.insert("nose_top".into(), 1);
    let msg = load_error(d, "unknown.json", &serde_json::to_string(&map).unwrap());
    assert!(msg.contains("nose_top"), "{msg}");

    let mut map = face().sidecar_map();
    let tip = map["nose_tip"];
    map.insert("chin".into(), tip);
    let msg = load_error(d, "same.json", &serde_json::to_string(&map).unwrap());
    assert!(msg.contains("chin") && msg.contains("nose_tip"), "{msg}");

    let msg = load_error(d, "negative.ron", "{\"nose_tip\": -3}");
    assert!(msg.contains("-3"), "{msg}");
    load_error(d, "broken.json", "{\"nose_tip\": ");
    load_error(d, "sidecar.txt", "{}");

    // A missing OBJ names the OBJ.
    let err = generic_face::load(&d.join("nope.obj"), &d.join("missing.json")).unwrap_err();
    assert!(err.to_string().contains("nope.obj"), "{err}");
}
