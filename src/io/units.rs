//! Length units of a scan file. facesynth works in millimetres; scanners and tools also export
//! metres (a face 0.15 units wide) and centimetres. The readers scale to millimetres by
//! [`Units`]: given, or guessed from the mesh's size.

use crate::Mesh;
use std::path::Path;

/// The unit of a file's coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Units {
    /// Guess from the size ([`guess`]): metres where the mesh spans
    /// [`METRES_MIN_EXTENT`]–[`METRES_MAX_EXTENT`] units, millimetres otherwise. Default.
    #[default]
    Auto,
    Millimetres,
    Centimetres,
    Metres,
}

impl Units {
    /// Millimetres per file unit; `None` for [`Units::Auto`].
    pub fn mm_per_unit(self) -> Option<f64> {
        match self {
            Units::Auto => None,
            Units::Millimetres => Some(1.0),
            Units::Centimetres => Some(10.0),
            Units::Metres => Some(1000.0),
        }
    }
}

/// The unit a file was read in, and whether it was guessed from the mesh's size: what a report
/// records so that its millimetre coordinates can be taken back to the file's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnitsRead {
    /// Never [`Units::Auto`]: the unit applied.
    pub units: Units,
    /// Guessed ([`Units::Auto`] was asked), not given.
    pub guessed: bool,
}

impl UnitsRead {
    /// Millimetres per file unit.
    pub fn mm_per_unit(self) -> f64 {
        self.units.mm_per_unit().unwrap_or(1.0)
    }

    /// For people: the unit, whether it was guessed or given, and the scaling to mm where
    /// there was one (`m (guessed from the size; scaled ×1000 to mm)`).
    pub fn describe(self) -> String {
        let how = if self.guessed {
            "guessed from the size"
        } else {
            "given"
        };
        let k = self.mm_per_unit();
        if k == 1.0 {
            format!("mm ({how})")
        } else {
            format!("{} ({how}; scaled ×{k} to mm)", self.symbol())
        }
    }

    /// The unit's symbol: `mm`, `cm` or `m`.
    pub fn symbol(self) -> &'static str {
        match self.units {
            Units::Auto | Units::Millimetres => "mm",
            Units::Centimetres => "cm",
            Units::Metres => "m",
        }
    }
}

/// A face, or a head with neck and shoulders, spans 0.1–1 m: a mesh whose largest bounding-box
/// side lies in this range of units is in metres. In millimetres it would be under 3 mm across,
/// smaller than a nostril, which no face scan is.
pub const METRES_MIN_EXTENT: f64 = 0.03;
pub const METRES_MAX_EXTENT: f64 = 3.0;
/// Fewer vertices than this are not guessed at (test shapes and single faces are often
/// unit-sized; a face scan has thousands of vertices).
pub const GUESS_MIN_VERTICES: usize = 500;

/// The units of `mesh` by its size: metres or millimetres (centimetres overlap with small
/// millimetre crops and are never guessed).
pub fn guess(mesh: &Mesh) -> Units {
    let Some((lo, hi)) = mesh.bbox_mm() else {
        return Units::Millimetres;
    };
    let extent = (hi - lo).max_element();
    if mesh.vertex_count() >= GUESS_MIN_VERTICES
        && (METRES_MIN_EXTENT..=METRES_MAX_EXTENT).contains(&extent)
    {
        Units::Metres
    } else {
        Units::Millimetres
    }
}

/// Scales `mesh` (read from `path` in `units`) to millimetres. Returns the unit applied, and a
/// one-line note when it scaled by a guess, for the caller to show: the user must know.
pub fn to_millimetres(mesh: &mut Mesh, units: Units, path: &Path) -> (UnitsRead, Option<String>) {
    let read = UnitsRead {
        units: match units {
            Units::Auto => guess(mesh),
            given => given,
        },
        guessed: units == Units::Auto,
    };
    let scale = read.mm_per_unit();
    if scale == 1.0 {
        return (read, None);
    }
    for p in &mut mesh.positions_mm {
        *p *= scale;
    }
    let note = read.guessed.then(|| {
        let extent = mesh
            .bbox_mm()
            .map_or(0.0, |(lo, hi)| (hi - lo).max_element() / scale);
        format!(
            "{}: the mesh is {extent:.3} units across, so its units look like metres: scaled by \
             1000 to millimetres (--units mm reads it as millimetres)",
            path.display()
        )
    });
    (read, note)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn grid(n: usize, spacing: f64) -> Mesh {
        let mut p = Vec::new();
        let mut f = Vec::new();
        for j in 0..n {
            for i in 0..n {
                p.push(DVec3::new(i as f64, j as f64, 0.0) * spacing);
                if i + 1 < n && j + 1 < n {
                    let k = (j * n + i) as u32;
                    f.push([k, k + 1, k + 1 + n as u32, k + n as u32]);
                }
            }
        }
        Mesh::from_faces(p, f)
    }

    #[test]
    fn a_face_sized_in_metres_is_scaled_and_said() {
        // 30 × 30 samples 5 mm apart, written in metres: 0.145 units across.
        let mut m = grid(30, 0.005);
        let (read, note) = to_millimetres(&mut m, Units::Auto, Path::new("head.ply"));
        let note = note.unwrap();
        assert_eq!(
            (read.symbol(), read.mm_per_unit(), read.guessed),
            ("m", 1000.0, true)
        );
        assert!(
            note.contains("head.ply") && note.contains("metres"),
            "{note}"
        );
        let (lo, hi) = m.bbox_mm().unwrap();
        assert!(((hi - lo).max_element() - 145.0).abs() < 1e-9);
    }

    #[test]
    fn millimetre_scans_and_small_shapes_are_left_alone() {
        for (mut m, what) in [
            (grid(30, 2.0), "a face in mm"),
            (grid(10, 0.01), "100 vertices"),
            (grid(30, 0.0005), "0.0145 units: not a head in metres"),
        ] {
            let before = m.positions_mm.clone();
            let (read, note) = to_millimetres(&mut m, Units::Auto, Path::new("x"));
            assert_eq!(
                (read.symbol(), read.guessed, note),
                ("mm", true, None),
                "{what}"
            );
            assert_eq!(m.positions_mm, before, "{what}");
        }
        // Given units are applied silently, whatever the size.
        let mut m = grid(30, 2.0);
        let (read, note) = to_millimetres(&mut m, Units::Centimetres, Path::new("x"));
        assert_eq!(read.describe(), "cm (given; scaled ×10 to mm)");
        assert_eq!(
            (read.symbol(), read.mm_per_unit(), read.guessed, note),
            ("cm", 10.0, false, None)
        );
        assert_eq!(m.positions_mm[1].x, 20.0);
        let mut m = grid(30, 0.005);
        to_millimetres(&mut m, Units::Millimetres, Path::new("x"));
        assert_eq!(m.positions_mm[1].x, 0.005);
    }
}
