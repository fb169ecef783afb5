//! Lays a structured quad grid over the analytic surface ([`super::shape`]) so that the 13
//! feature points fall on vertices, cuts the mouth and eye slits, and assembles the mesh.
//!
//! The grid has columns at fixed fractions `σ ∈ [-1, 1]` of each height's arc length to the
//! side of the face and rows at fixed heights `t`. Feature points are knots of the column and
//! row layouts; between knots, a monotone cubic spreads the grid lines smoothly. Eyes and
//! mouth are slits along a row: the slit's inner vertices are duplicated so the upper and lower
//! lid (lip) are separate boundaries, and the rows around them are pushed apart (a smooth
//! warp of `t` that fades out over a few rows) to open the almond-shaped eyes and a narrow gap
//! between the lips.

use super::interp::{pchip, smoothstep};
use super::shape::{self, Section};
use super::{GenericFace, targets};
use crate::feature_points::FeaturePoint;
use crate::mesh::Mesh;
use glam::DVec3;

/// Height of the mesh's bottom row (one row under the chin point) and top row (forehead), mm.
/// The bottom row is 1.4 mm below the chin point (was −78 with 4 rows under the chin): under
/// the chin a frontal scan has no data (the chin–neck shadow), so registration could only
/// extrapolate those rows, 5–14 mm off the scan (issue #4).
const T_BOTTOM: f64 = -72.0;
const T_TOP: f64 = 84.0;
/// Height of the nose-corner row (widest point of the alae), mm.
const T_NOSE_CORNER: f64 = -5.0;
/// Height of the subnasale (where the nose meets the upper lip): rows are denser above it.
const T_SUBNASALE: f64 = -14.0;
/// Height of the cheek feature row (between eyes and mouth), mm.
const T_CHEEK: f64 = 0.0;
/// Frontal x of the cheek feature (the cheek's lateral border), mm.
const X_CHEEK: f64 = 60.0;

/// How far round the head the mesh reaches at each height (ellipse angle, degrees): 68° at
/// mid height (x = ±66 mm; the cheek feature column is at 59°), narrowing to 45–50° along
/// the jaw below the mouth and to the temples above. A frontal scan sees the side of the face
/// only up to where it turns ~75–80° away from the scanner (steeper cells are not scanned),
/// scans are yawed by a few degrees, and under the jaw line there is the chin–neck shadow:
/// the earlier extent (82° at mid height, 56–60° at the jaw: the front of the ears) put
/// 13–23 % of the vertices beyond the scans' coverage, where registration can only
/// extrapolate them (issue #4). Narrower than this at the jaw squeezes the outer columns
/// there past the quad edge-ratio limit.
const SIDE_ANGLE_DEG: [(f64, f64); 8] = [
    (-78.0, 45.0),
    (-70.0, 50.0),
    (-55.0, 62.0),
    (-40.0, 66.0),
    (-20.0, 68.0),
    (40.0, 68.0),
    (70.0, 68.0),
    (84.0, 64.0),
];

/// Eye opening: peak heights (mm) of the upper and lower lid above/below the slit row, and how
/// far (mm) the row warp reaches up and down.
const EYE_UPPER_MM: f64 = 4.5;
const EYE_LOWER_MM: f64 = 3.5;
const EYE_WARP_UP_MM: f64 = 11.0;
const EYE_WARP_DOWN_MM: f64 = 9.0;
/// Mouth opening: half the gap between the lips at the centre (mm) and the warp's reach (mm).
const MOUTH_HALF_GAP_MM: f64 = 0.8;
const MOUTH_WARP_MM: f64 = 5.0;

/// How far (0–1) the columns move towards an even spread at the bottom row.
const CHIN_EVEN_COLUMNS: f64 = 0.7;

/// Arc length (mm) from the midline to the side of the mesh at height `t`.
fn side_arc(t: f64) -> f64 {
    Section::at(t).arc(pchip(&SIDE_ANGLE_DEG, t).to_radians())
}

/// The unwarped grid point at column fraction `sigma` on the row at height `t`.
fn point(sigma: f64, t: f64) -> DVec3 {
    shape::surface(sigma * side_arc(t), t)
}

/// The column fraction `σ ∈ (0, 1)` whose vertex at height `t` has `x = x_mm` (bisection).
fn sigma_for_x(x_mm: f64, t: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if point(mid, t).x < x_mm {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Grid lines from knots: `knots[k]` is the value at line index `sum(counts[..k])`.
fn lines(knots: &[f64], counts: &[usize]) -> (Vec<f64>, Vec<usize>) {
    let mut table = Vec::with_capacity(knots.len());
    let mut index = 0usize;
    let mut at = Vec::with_capacity(knots.len());
    for (k, &v) in knots.iter().enumerate() {
        table.push((index as f64, v));
        at.push(index);
        if k < counts.len() {
            index += counts[k];
        }
    }
    let values = (0..=index).map(|i| pchip(&table, i as f64)).collect();
    (values, at)
}

/// `sin(π u)` over a skewed `u` (peak moved towards 0 for `skew > 0`); 0 outside (0, 1).
fn lid_shape(u: f64, skew: f64) -> f64 {
    if u <= 0.0 || u >= 1.0 {
        return 0.0;
    }
    let v = u + skew * u * (1.0 - u);
    (std::f64::consts::PI * v).sin()
}

/// Row layout.
struct Rows {
    t: Vec<f64>,
    bottom_chin: usize,
    mouth: usize,
    nose_corner: usize,
    tip: usize,
    eye: usize,
    forehead: usize,
}

fn rows() -> Rows {
    let knots = [
        T_BOTTOM,
        -targets::NOSE_TO_CHIN_Y,
        -targets::NOSE_TO_MOUTH_Y,
        T_SUBNASALE,
        T_NOSE_CORNER,
        0.0,
        targets::NOSE_TO_BRIDGE_Y,
        targets::FOREHEAD_Y,
        T_TOP,
    ];
    let counts = [1, 12, 8, 5, 2, 12, 13, 4];
    let (t, at) = lines(&knots, &counts);
    Rows {
        t,
        bottom_chin: at[1],
        mouth: at[2],
        nose_corner: at[4],
        tip: at[5],
        eye: at[6],
        forehead: at[7],
    }
}

/// Column layout (one half, σ ≥ 0; the other half mirrors it).
struct Columns {
    sigma: Vec<f64>,
    inner_eye: usize,
    mouth: usize,
    outer_eye: usize,
    cheek: usize,
}

fn columns(rows: &Rows) -> Columns {
    let t_eye = rows.t[rows.eye];
    let inner = sigma_for_x(targets::NOSE_TO_INNER_EYE_X, t_eye);
    let outer = sigma_for_x(
        targets::NOSE_TO_INNER_EYE_X + targets::INNER_TO_OUTER_EYE_X,
        t_eye,
    );
    let mouth = sigma_for_x(targets::MOUTH_HALF_WIDTH_X, rows.t[rows.mouth]);
    let cheek = sigma_for_x(X_CHEEK, T_CHEEK);
    let knots = [0.0, inner, mouth, outer, cheek, 1.0];
    debug_assert!(knots.windows(2).all(|w| w[0] < w[1]), "{knots:?}");
    let counts = [7, 3, 8, 4, 8];
    let (sigma, at) = lines(&knots, &counts);
    Columns {
        sigma,
        inner_eye: at[1],
        mouth: at[2],
        outer_eye: at[3],
        cheek: at[4],
    }
}

pub fn build() -> GenericFace {
    let rows = rows();
    let cols = columns(&rows);
    let half = cols.sigma.len() - 1;
    let ncol = 2 * half + 1;
    let nrow = rows.t.len();
    let ic = half;
    // Full signed column fractions, exactly mirrored.
    let sigma: Vec<f64> = (0..ncol)
        .map(|i| {
            if i < ic {
                -cols.sigma[ic - i]
            } else {
                cols.sigma[i - ic]
            }
        })
        .collect();

    let t_eye = rows.t[rows.eye];
    let t_mouth = rows.t[rows.mouth];
    let (s_in, s_out) = (cols.sigma[cols.inner_eye], cols.sigma[cols.outer_eye]);
    let s_mouth = cols.sigma[cols.mouth];
    // Lid and lip openings (mm) at column fraction |σ|.
    let eye_u = |a: f64| (a - s_in) / (s_out - s_in);
    let upper_lid = |a: f64| EYE_UPPER_MM * lid_shape(eye_u(a), 0.2);
    let lower_lid = |a: f64| EYE_LOWER_MM * lid_shape(eye_u(a), -0.2);
    let lip = |sg: f64| MOUTH_HALF_GAP_MM * lid_shape((sg + s_mouth) / (2.0 * s_mouth), 0.0);
    // Row warp: vertical shift (mm) of grid vertex (σ, t_row) that opens eyes and mouth.
    let warp = |sg: f64, t_row: f64| -> f64 {
        let a = sg.abs();
        let mut dt = 0.0;
        let d = t_row - t_eye;
        if d > 0.0 {
            dt += upper_lid(a) * (1.0 - d / EYE_WARP_UP_MM).max(0.0);
        } else if d < 0.0 {
            dt -= lower_lid(a) * (1.0 + d / EYE_WARP_DOWN_MM).max(0.0);
        }
        let d = t_row - t_mouth;
        if d > 0.0 {
            dt += lip(sg) * (1.0 - d / MOUTH_WARP_MM).max(0.0);
        } else if d < 0.0 {
            dt -= lip(sg) * (1.0 + d / MOUTH_WARP_MM).max(0.0);
        }
        dt
    };
    let in_eye_slit = |i: usize| {
        let k = i.abs_diff(ic);
        k > cols.inner_eye && k < cols.outer_eye
    };
    let in_mouth_slit = |i: usize| i.abs_diff(ic) < cols.mouth;

    // Below the mouth the face narrows to the chin: there the columns drift towards an even
    // spread so the fine spacing around nose and eyes does not crowd the chin.
    let column = |i: usize, t_row: f64| -> f64 {
        let beta = CHIN_EVEN_COLUMNS * smoothstep(t_mouth, T_BOTTOM, t_row);
        let even = (i as f64 - ic as f64) / half as f64;
        (1.0 - beta) * sigma[i] + beta * even
    };
    let arcs: Vec<f64> = rows.t.iter().map(|&t| side_arc(t)).collect();
    let mut positions = Vec::with_capacity(ncol * nrow + 64);
    for (j, &t_row) in rows.t.iter().enumerate() {
        for (i, &sg) in sigma.iter().enumerate() {
            let column = column(i, t_row);
            // Slit rows: this is the upper copy (upper lid / upper lip).
            let dt = if j == rows.eye {
                upper_lid(sg.abs())
            } else if j == rows.mouth {
                lip(sg)
            } else {
                warp(sg, t_row)
            };
            positions.push(shape::surface(column * arcs[j], t_row + dt));
        }
    }
    let id = |i: usize, j: usize| (j * ncol + i) as u32;
    // Lower copies of the slits' inner vertices (lower lid / lower lip).
    let mut lower = vec![u32::MAX; ncol * nrow];
    for (i, &sg) in sigma.iter().enumerate() {
        for (j, open) in [
            (rows.eye, in_eye_slit(i).then(|| lower_lid(sg.abs()))),
            (rows.mouth, in_mouth_slit(i).then(|| lip(sg))),
        ] {
            if let Some(gap) = open {
                lower[j * ncol + i] = positions.len() as u32;
                let t_row = rows.t[j];
                positions.push(shape::surface(column(i, t_row) * arcs[j], t_row - gap));
            }
        }
    }
    let mut faces = Vec::with_capacity((ncol - 1) * (nrow - 1));
    for j in 0..nrow - 1 {
        for i in 0..ncol - 1 {
            // The quad's top edge lies on row j + 1: below a slit it uses the lower copies.
            let top = |i: usize| {
                let l = lower[(j + 1) * ncol + i];
                if l != u32::MAX { l } else { id(i, j + 1) }
            };
            faces.push([id(i, j), id(i + 1, j), top(i + 1), top(i)]);
        }
    }

    // Nose tip at the origin.
    let tip = positions[id(ic, rows.tip) as usize];
    let shift = DVec3::new(0.0, 0.0, -tip.z);
    for p in &mut positions {
        *p += shift;
    }
    let mesh = Mesh::from_faces(positions, faces);

    let mut feature_vertices = [0u32; FeaturePoint::COUNT];
    let both = |k: usize, j: usize| (id(ic + k, j), id(ic - k, j));
    let mut set_pair = |left: FeaturePoint, k: usize, j: usize| {
        let (l, r) = both(k, j);
        feature_vertices[left.index()] = l;
        feature_vertices[left.mirror().index()] = r;
    };
    set_pair(FeaturePoint::InnerEyeLeft, cols.inner_eye, rows.eye);
    set_pair(FeaturePoint::OuterEyeLeft, cols.outer_eye, rows.eye);
    set_pair(
        FeaturePoint::NoseCornerLeft,
        cols.inner_eye,
        rows.nose_corner,
    );
    set_pair(FeaturePoint::MouthCornerLeft, cols.mouth, rows.mouth);
    set_pair(FeaturePoint::CheekLeft, cols.cheek, rows.tip);
    feature_vertices[FeaturePoint::NoseTip.index()] = id(ic, rows.tip);
    feature_vertices[FeaturePoint::Forehead.index()] = id(ic, rows.forehead);
    feature_vertices[FeaturePoint::Chin.index()] = id(ic, rows.bottom_chin);
    GenericFace {
        mesh,
        feature_vertices,
    }
}
