//! Range images for recognition (paper section 3): "we fit a rectangular mesh with 9,891
//! vertices to the facial surfaces, with the nose tip on the center and moving only the Z
//! coordinate of each vertex … an elliptical mask is used to crop range images and holes inside
//! the ellipse are filled with the average neighborhood information."
//!
//! Steps of [`range_image`]:
//! 1. **Frame.** Every vertex is moved into the face frame: `q = face_from_scan · (p − nose tip)`,
//!    so the nose tip is the origin and (after pose normalisation) the face looks along +z.
//! 2. **Orthographic z-buffer.** The triangles (polygons split into fans) are rasterised along
//!    −z onto a fixed `cols × rows` grid centred on the nose tip; each sample keeps the
//!    front-most (largest z) surface point, barycentrically interpolated. Only Z is measured:
//!    the grid's x and y never move. Default grid 89 × 111 = **9,879 samples** (the paper's
//!    9,891 factors only as 63 × 157 or 21 × 471; 89 × 111 is the closest face-shaped
//!    rectangle), spacing 1.3 mm → 114.4 mm wide × 143.0 mm high.
//! 3. **Spike guard.** A sample more than [`RangeImageParams::spike_reject_mm`] from the median
//!    of its 7 × 7 neighbourhood is dropped (becomes a hole); the scanner's long peaks
//!    (paper 2.1.1) would otherwise dominate the distances.
//! 4. **Elliptic mask** (semi-axes default to the inscribed ellipse), samples outside are 0.
//! 5. **Hole filling** inside the ellipse: a wavefront pass gives each empty sample the mean of
//!    its already-known 8-neighbours, then Gauss–Seidel averaging sweeps over the filled samples
//!    only (measured samples stay fixed) relax it towards a smooth (harmonic) patch.
//!
//! Values are depths relative to the nose tip, mm (≤ 0 almost everywhere on a face).

use crate::{Error, Mesh, Result};
use glam::{DMat3, DVec3};
use serde::Serialize;

/// Parameters of [`range_image`]. Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RangeImageParams {
    /// Grid columns (along x). Default 89.
    pub cols: usize,
    /// Grid rows (along y, top row first). Default 111; 89 × 111 = 9,879 samples.
    pub rows: usize,
    /// Sample spacing, mm (> 0). Default 1.3.
    pub spacing_mm: f64,
    /// Elliptic mask semi-axis along x, mm. Default 57.2 (inscribed in the default grid).
    pub ellipse_semi_x_mm: f64,
    /// Elliptic mask semi-axis along y, mm. Default 71.5 (inscribed in the default grid).
    pub ellipse_semi_y_mm: f64,
    /// A sample further than this from its 7 × 7 neighbourhood median is treated as a hole,
    /// mm. Default 6 (the synthetic and real spikes are 5–40 mm); `f64::INFINITY` disables.
    pub spike_reject_mm: f64,
    /// Gauss–Seidel averaging sweeps over filled holes after the wavefront. Default 30.
    pub smoothing_sweeps: usize,
    /// Smallest fraction of in-mask samples the mesh must cover (before filling), in (0, 1].
    /// Default 0.5; less usually means a wrong nose tip or pose.
    pub min_coverage: f64,
}

impl Default for RangeImageParams {
    fn default() -> Self {
        RangeImageParams {
            cols: 89,
            rows: 111,
            spacing_mm: 1.3,
            ellipse_semi_x_mm: 57.2,
            ellipse_semi_y_mm: 71.5,
            spike_reject_mm: 6.0,
            smoothing_sweeps: 30,
            min_coverage: 0.5,
        }
    }
}

impl RangeImageParams {
    /// Number of samples (the feature-vector length).
    pub fn len(&self) -> usize {
        self.cols * self.rows
    }

    /// True for a grid without samples (never for valid parameters).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Grid position (x, y) of column `i`, row `j` in the face frame, mm (nose tip at 0).
    pub fn sample_xy_mm(&self, i: usize, j: usize) -> (f64, f64) {
        let cx = (self.cols as f64 - 1.0) / 2.0;
        let cy = (self.rows as f64 - 1.0) / 2.0;
        (
            (i as f64 - cx) * self.spacing_mm,
            (cy - j as f64) * self.spacing_mm,
        )
    }

    /// The elliptic mask, row-major: true inside the ellipse centred on the nose tip.
    pub fn mask(&self) -> Vec<bool> {
        let mut mask = vec![false; self.len()];
        for j in 0..self.rows {
            for i in 0..self.cols {
                let (x, y) = self.sample_xy_mm(i, j);
                let e = (x / self.ellipse_semi_x_mm).powi(2) + (y / self.ellipse_semi_y_mm).powi(2);
                mask[j * self.cols + i] = e <= 1.0;
            }
        }
        mask
    }

    fn validate(&self) -> Result<()> {
        let ok = self.cols >= 3
            && self.rows >= 3
            && self.spacing_mm > 0.0
            && self.spacing_mm.is_finite()
            && self.ellipse_semi_x_mm > 0.0
            && self.ellipse_semi_y_mm > 0.0
            && self.spike_reject_mm > 0.0
            && self.min_coverage > 0.0
            && self.min_coverage <= 1.0;
        if ok {
            Ok(())
        } else {
            Err(Error::algorithm(
                "range image",
                format!("invalid parameters {self:?}"),
            ))
        }
    }
}

/// A face resampled on the fixed grid.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RangeImage {
    pub cols: usize,
    pub rows: usize,
    pub spacing_mm: f64,
    /// Depth relative to the nose tip, mm, row-major (top row first, x increasing); 0 outside
    /// the mask. This is the recognition feature vector Γ.
    pub depth_mm: Vec<f64>,
    /// Inside the elliptic mask.
    pub mask: Vec<bool>,
    /// Inside the mask and measured on the mesh (not filled).
    pub measured: Vec<bool>,
    /// Measured fraction of the in-mask samples.
    pub coverage: f64,
    /// Samples dropped by the spike guard.
    pub spikes_rejected: usize,
}

/// Resamples `mesh` (scan frame, mm) onto the grid centred at `nose_tip_in_scan`, after
/// rotating by `face_from_scan` (identity when the scan is already frontal).
pub fn range_image(
    mesh: &Mesh,
    nose_tip_in_scan: DVec3,
    face_from_scan: DMat3,
    params: &RangeImageParams,
) -> Result<RangeImage> {
    params.validate()?;
    if !nose_tip_in_scan.is_finite() {
        return Err(Error::algorithm("range image", "nose tip is not finite"));
    }
    let (cols, rows, s) = (params.cols, params.rows, params.spacing_mm);
    let cx = (cols as f64 - 1.0) / 2.0;
    let cy = (rows as f64 - 1.0) / 2.0;
    // Grid coordinates: u = column (fractional), v = row (fractional).
    let q: Vec<DVec3> = mesh
        .positions_mm
        .iter()
        .map(|&p| {
            let f = face_from_scan * (p - nose_tip_in_scan);
            DVec3::new(f.x / s + cx, cy - f.y / s, f.z)
        })
        .collect();
    let mut depth = vec![f64::NEG_INFINITY; cols * rows];
    for poly in mesh.faces.iter() {
        for k in 1..poly.len().saturating_sub(1) {
            let [a, b, c] = [poly[0], poly[k], poly[k + 1]].map(|v| q[v as usize]);
            rasterize(a, b, c, cols, rows, &mut depth);
        }
    }
    // Spike guard on the raw z-buffer.
    let mut spikes_rejected = 0;
    if params.spike_reject_mm.is_finite() {
        let mut keep = vec![true; depth.len()];
        let mut window = Vec::with_capacity(49);
        for j in 0..rows {
            for i in 0..cols {
                let z = depth[j * cols + i];
                if z == f64::NEG_INFINITY {
                    continue;
                }
                let median = neighbourhood_median(&depth, (cols, rows), (i, j), 3, &mut window);
                if (z - median).abs() > params.spike_reject_mm {
                    keep[j * cols + i] = false;
                }
            }
        }
        for (d, k) in depth.iter_mut().zip(&keep) {
            if !k {
                *d = f64::NEG_INFINITY;
                spikes_rejected += 1;
            }
        }
    }
    let mask = params.mask();
    let measured: Vec<bool> = (0..depth.len())
        .map(|k| mask[k] && depth[k] > f64::NEG_INFINITY)
        .collect();
    let inside = mask.iter().filter(|&&m| m).count();
    let hit = measured.iter().filter(|&&m| m).count();
    let coverage = hit as f64 / inside.max(1) as f64;
    if inside == 0 || coverage < params.min_coverage {
        return Err(Error::algorithm(
            "range image",
            format!(
                "the mesh covers {:.0} % of the elliptic mask (need {:.0} %): wrong nose tip or pose?",
                coverage * 100.0,
                params.min_coverage * 100.0
            ),
        ));
    }
    for k in 0..depth.len() {
        if !mask[k] {
            depth[k] = 0.0;
        }
    }
    fill_holes(
        &mut depth,
        &mask,
        &measured,
        cols,
        rows,
        params.smoothing_sweeps,
    );
    Ok(RangeImage {
        cols,
        rows,
        spacing_mm: s,
        depth_mm: depth,
        mask,
        measured,
        coverage,
        spikes_rejected,
    })
}

/// Median of the filled samples (not `-∞`) of the `(2 half + 1)²` window around column `i`,
/// row `j` of a row-major `cols × rows` grid (fewer at the borders); the window holds at least
/// the centre, which must be filled. `window` is scratch space.
pub(crate) fn neighbourhood_median(
    grid: &[f64],
    (cols, rows): (usize, usize),
    (i, j): (usize, usize),
    half: usize,
    window: &mut Vec<f64>,
) -> f64 {
    window.clear();
    for jj in j.saturating_sub(half)..(j + half + 1).min(rows) {
        for ii in i.saturating_sub(half)..(i + half + 1).min(cols) {
            let w = grid[jj * cols + ii];
            if w > f64::NEG_INFINITY {
                window.push(w);
            }
        }
    }
    let mid = window.len() / 2;
    *window.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Z-buffers triangle abc (grid coordinates u, v, depth z), keeping the largest z.
fn rasterize(a: DVec3, b: DVec3, c: DVec3, cols: usize, rows: usize, depth: &mut [f64]) {
    let area = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
    if !(area.abs() > 1e-12) {
        return;
    }
    let umin = a.x.min(b.x).min(c.x).ceil().max(0.0);
    let umax = a.x.max(b.x).max(c.x).floor().min(cols as f64 - 1.0);
    let vmin = a.y.min(b.y).min(c.y).ceil().max(0.0);
    let vmax = a.y.max(b.y).max(c.y).floor().min(rows as f64 - 1.0);
    if umin > umax || vmin > vmax {
        return;
    }
    let eps = 1e-9;
    for v in vmin as usize..=vmax as usize {
        for u in umin as usize..=umax as usize {
            let (pu, pv) = (u as f64, v as f64);
            let w0 = ((b.x - pu) * (c.y - pv) - (c.x - pu) * (b.y - pv)) / area;
            let w1 = ((c.x - pu) * (a.y - pv) - (a.x - pu) * (c.y - pv)) / area;
            let w2 = 1.0 - w0 - w1;
            if w0 >= -eps && w1 >= -eps && w2 >= -eps {
                let z = w0 * a.z + w1 * b.z + w2 * c.z;
                let d = &mut depth[v * cols + u];
                if z > *d {
                    *d = z;
                }
            }
        }
    }
}

/// Fills in-mask samples that are not `measured`: wavefront of 8-neighbour means, then
/// Gauss–Seidel averaging sweeps over the filled samples only.
fn fill_holes(
    depth: &mut [f64],
    mask: &[bool],
    measured: &[bool],
    cols: usize,
    rows: usize,
    sweeps: usize,
) {
    let mut known: Vec<bool> = measured.to_vec();
    let holes: Vec<usize> = (0..depth.len())
        .filter(|&k| mask[k] && !measured[k])
        .collect();
    if holes.is_empty() {
        return;
    }
    let neighbours = |k: usize| {
        let (i, j) = ((k % cols) as isize, (k / cols) as isize);
        (-1isize..=1)
            .flat_map(move |dj| (-1isize..=1).map(move |di| (di, dj)))
            .filter(|&(di, dj)| di != 0 || dj != 0)
            .filter_map(move |(di, dj)| {
                let (ii, jj) = (i + di, j + dj);
                if ii >= 0 && jj >= 0 && ii < cols as isize && jj < rows as isize {
                    Some(jj as usize * cols + ii as usize)
                } else {
                    None
                }
            })
    };
    let mut pending = holes.clone();
    while !pending.is_empty() {
        let mut newly = Vec::new();
        let mut rest = Vec::new();
        for &k in &pending {
            let (mut sum, mut n) = (0.0, 0usize);
            for nb in neighbours(k) {
                if mask[nb] && known[nb] {
                    sum += depth[nb];
                    n += 1;
                }
            }
            if n > 0 {
                newly.push((k, sum / n as f64));
            } else {
                rest.push(k);
            }
        }
        if newly.is_empty() {
            // Unreachable for a convex mask with at least one measured sample; keep 0.
            for k in rest {
                depth[k] = 0.0;
            }
            break;
        }
        for (k, z) in newly {
            depth[k] = z;
            known[k] = true;
        }
        pending = rest;
    }
    for _ in 0..sweeps {
        for &k in &holes {
            let (mut sum, mut n) = (0.0, 0usize);
            for nb in neighbours(k) {
                if mask[nb] {
                    sum += depth[nb];
                    n += 1;
                }
            }
            if n > 0 {
                depth[k] = sum / n as f64;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tilted plane z = 0.2 x − 0.1 y sampled on a 1 mm grid, with a square hole.
    fn plane(hole: bool) -> Mesh {
        let n = 161;
        let mut pos = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f64 - 80.0, j as f64 - 80.0);
                pos.push(DVec3::new(x, y, 0.2 * x - 0.1 * y - 1000.0));
            }
        }
        let mut faces = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let (x, y) = (i as f64 - 80.0, j as f64 - 80.0);
                if hole && (10.0..20.0).contains(&x) && (-5.0..5.0).contains(&y) {
                    continue;
                }
                let k = (j * n + i) as u32;
                faces.push([k, k + 1, k + 1 + n as u32, k + n as u32]);
            }
        }
        Mesh::from_faces(pos, faces)
    }

    #[test]
    fn plane_is_sampled_exactly_relative_to_nose() {
        let params = RangeImageParams::default();
        let nose = DVec3::new(0.0, 0.0, -1000.0);
        let img = range_image(&plane(false), nose, DMat3::IDENTITY, &params).unwrap();
        assert_eq!(img.depth_mm.len(), 9879);
        assert_eq!(img.coverage, 1.0);
        for j in 0..params.rows {
            for i in 0..params.cols {
                let k = j * params.cols + i;
                let (x, y) = params.sample_xy_mm(i, j);
                let want = if img.mask[k] { 0.2 * x - 0.1 * y } else { 0.0 };
                assert!((img.depth_mm[k] - want).abs() < 1e-9, "{i} {j}");
            }
        }
    }

    #[test]
    fn holes_in_a_plane_are_filled_near_the_plane() {
        let params = RangeImageParams::default();
        let nose = DVec3::new(0.0, 0.0, -1000.0);
        let img = range_image(&plane(true), nose, DMat3::IDENTITY, &params).unwrap();
        let filled: Vec<usize> = (0..img.mask.len())
            .filter(|&k| img.mask[k] && !img.measured[k])
            .collect();
        assert!(filled.len() > 40, "{}", filled.len());
        for k in filled {
            let (x, y) = params.sample_xy_mm(k % params.cols, k / params.cols);
            // Harmonic fill of a linear function is linear up to the sweep budget.
            assert!((img.depth_mm[k] - (0.2 * x - 0.1 * y)).abs() < 0.3);
        }
    }

    #[test]
    fn spike_is_rejected_and_filled() {
        let mut mesh = plane(false);
        let params = RangeImageParams::default();
        // The vertex at (3, 4): a 25 mm spike towards the scanner.
        let k = (84 * 161 + 83) as usize;
        mesh.positions_mm[k].z += 25.0;
        let nose = DVec3::new(0.0, 0.0, -1000.0);
        let img = range_image(&mesh, nose, DMat3::IDENTITY, &params).unwrap();
        assert!(img.spikes_rejected > 0);
        let max_err = (0..img.mask.len())
            .filter(|&k| img.mask[k])
            .map(|k| {
                let (x, y) = params.sample_xy_mm(k % params.cols, k / params.cols);
                (img.depth_mm[k] - (0.2 * x - 0.1 * y)).abs()
            })
            .fold(0.0, f64::max);
        // The spike's tails below the guard threshold stay; the 25 mm peak does not.
        assert!(max_err <= params.spike_reject_mm, "{max_err}");
    }

    #[test]
    fn pose_rotation_is_undone_by_face_from_scan() {
        let params = RangeImageParams::default();
        let nose = DVec3::new(0.0, 0.0, -1000.0);
        let frontal = plane(false);
        let want = range_image(&frontal, nose, DMat3::IDENTITY, &params).unwrap();
        // Pose the scan: rotate about a head centre 100 mm behind the nose.
        let scan_from_face = DMat3::from_euler(glam::EulerRot::ZXY, 0.05, -0.08, 0.1);
        let centre = nose - DVec3::new(0.0, 0.0, 100.0);
        let mut posed = frontal.clone();
        for p in &mut posed.positions_mm {
            *p = centre + scan_from_face * (*p - centre);
        }
        let posed_nose = centre + scan_from_face * (nose - centre);
        let got = range_image(&posed, posed_nose, scan_from_face.transpose(), &params).unwrap();
        let max_diff = want
            .depth_mm
            .iter()
            .zip(&got.depth_mm)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(max_diff < 1e-6, "{max_diff}");
        // Without normalisation the same scan gives a different image.
        let raw = range_image(&posed, posed_nose, DMat3::IDENTITY, &params).unwrap();
        let raw_diff = want
            .depth_mm
            .iter()
            .zip(&raw.depth_mm)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(raw_diff > 1.0, "{raw_diff}");
    }

    #[test]
    fn off_mesh_nose_tip_is_an_error() {
        let nose = DVec3::new(500.0, 0.0, -1000.0);
        let err = range_image(
            &plane(false),
            nose,
            DMat3::IDENTITY,
            &RangeImageParams::default(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("elliptic mask"), "{err}");
    }
}
