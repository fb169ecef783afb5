//! Shared geometry queries on a mesh: closest points on the surface (a uniform grid of
//! triangles), the one ray–triangle test, and the one headless front-view rasteriser.

use super::Mesh;
use glam::DVec3;

/// Distances from points to a mesh surface (exact point-to-triangle), through a uniform 3D
/// grid of triangles by bounding box.
#[derive(Debug, Clone)]
pub struct SurfaceIndex {
    /// Each triangle's corners and bounding box (min, max), stored by triangle so that a query
    /// reads one record per candidate.
    corners: Vec<[DVec3; 3]>,
    boxes: Vec<[DVec3; 2]>,
    min: DVec3,
    /// The grid's far corner (`min + dims · cell`): it covers every triangle.
    max: DVec3,
    cell: f64,
    dims: [usize; 3],
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl SurfaceIndex {
    pub fn new(mesh: &Mesh, cell_mm: f64) -> Self {
        let triangles = mesh.triangles();
        let positions = &mesh.positions_mm;
        let (lo, hi) = mesh.bbox_mm().unwrap_or((DVec3::ZERO, DVec3::ZERO));
        // Cells grow until the grid holds at most a few per triangle, and at most 1024 along
        // any axis: a scan with one vertex far away would otherwise ask for a billion cells.
        // (Growing the cell, not clamping the count, keeps the whole bounding box covered; in
        // steps of 1.25, not 2, so the cells end near the budget: a query's cost grows with
        // the triangles per cell.)
        let budget = (4 * triangles.len()).max(1 << 12) as f64;
        let mut cell = cell_mm.max(1e-3);
        let extent = hi - lo;
        let counts = |cell: f64| [0, 1, 2].map(|k| (extent[k] / cell).floor() + 1.0);
        while counts(cell).iter().product::<f64>() > budget
            || counts(cell).iter().any(|&n| n > 1024.0)
        {
            cell *= 1.25;
        }
        let dims = counts(cell).map(|n| n as usize);
        let cell_of = |p: DVec3| -> [usize; 3] {
            [0, 1, 2].map(|k| (((p[k] - lo[k]) / cell).floor().max(0.0) as usize).min(dims[k] - 1))
        };
        let ncell = dims[0] * dims[1] * dims[2];
        let bounds: Vec<([usize; 3], [usize; 3])> = triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| positions[v as usize]);
                (
                    cell_of(p[0].min(p[1]).min(p[2])),
                    cell_of(p[0].max(p[1]).max(p[2])),
                )
            })
            .collect();
        let idx = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
        let mut counts = vec![0u32; ncell + 1];
        for (a, b) in &bounds {
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        counts[idx(i, j, k) + 1] += 1;
                    }
                }
            }
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[ncell] as usize];
        for (t, (a, b)) in bounds.iter().enumerate() {
            for k in a[2]..=b[2] {
                for j in a[1]..=b[1] {
                    for i in a[0]..=b[0] {
                        let c = idx(i, j, k);
                        items[fill[c] as usize] = t as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        let corners: Vec<[DVec3; 3]> = triangles
            .iter()
            .map(|t| t.map(|v| positions[v as usize]))
            .collect();
        let boxes = corners
            .iter()
            .map(|&[a, b, c]| [a.min(b).min(c), a.max(b).max(c)])
            .collect();
        SurfaceIndex {
            corners,
            boxes,
            min: lo,
            max: lo + DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * cell,
            cell,
            dims,
            offsets: counts,
            items,
        }
    }

    /// Distance from `p` to the surface, mm; `max_mm` if nothing is closer.
    pub fn distance(&self, p: DVec3, max_mm: f64) -> f64 {
        self.closest(p, max_mm).map_or(max_mm, |(d, _)| d)
    }

    /// The closest surface point within `max_mm`: (distance, point).
    pub fn closest(&self, p: DVec3, max_mm: f64) -> Option<(f64, DVec3)> {
        if self.corners.is_empty() {
            return None;
        }
        // Nothing within reach of the grid: answer at once instead of widening the search to
        // `max_mm` over empty cells (a registration far off the scan made this slow; found by
        // fuzzing the pipeline).
        let outside = (self.min - p).max(p - self.max).max(DVec3::ZERO);
        if !(outside.length() <= max_mm) {
            return None;
        }
        let mut r = self.cell;
        loop {
            let r_eff = r.min(max_mm);
            let lo = [0, 1, 2].map(|k| ((p[k] - r_eff - self.min[k]) / self.cell).floor());
            let hi = [0, 1, 2].map(|k| ((p[k] + r_eff - self.min[k]) / self.cell).floor());
            let mut best: Option<(f64, DVec3)> = None;
            if (0..3).all(|k| hi[k] >= 0.0 && lo[k] < self.dims[k] as f64) {
                let lo = [0, 1, 2].map(|k| lo[k].max(0.0) as usize);
                let hi = [0, 1, 2].map(|k| (hi[k] as usize).min(self.dims[k] - 1));
                for kz in lo[2]..=hi[2] {
                    for jy in lo[1]..=hi[1] {
                        for ix in lo[0]..=hi[0] {
                            let c = (kz * self.dims[1] + jy) * self.dims[0] + ix;
                            for &t in
                                &self.items[self.offsets[c] as usize..self.offsets[c + 1] as usize]
                            {
                                // A triangle whose bounding box is no nearer than the best
                                // so far cannot beat it (and a triangle spanning several
                                // cells comes up once per cell).
                                if let Some((bd, _)) = best {
                                    let [lo, hi] = self.boxes[t as usize];
                                    let gap = (lo - p).max(p - hi).max(DVec3::ZERO);
                                    if gap.length_squared() >= bd {
                                        continue;
                                    }
                                }
                                let [a, b, cc] = self.corners[t as usize];
                                let q = closest_point_on_triangle(p, a, b, cc);
                                let d2 = q.distance_squared(p);
                                if best.is_none_or(|(bd, _)| d2 < bd) {
                                    best = Some((d2, q));
                                }
                            }
                        }
                    }
                }
            }
            // Once the box holds the whole grid, a wider one finds nothing more.
            let whole = (0..3).all(|k| lo[k] <= 0.0 && hi[k] >= self.dims[k] as f64 - 1.0);
            if let Some((d2, q)) = best
                && (d2.sqrt() <= r_eff || whole)
            {
                return (d2.sqrt() <= max_mm).then_some((d2.sqrt(), q));
            }
            if r_eff >= max_mm || whole {
                return None;
            }
            r *= 2.0;
        }
    }
}

/// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5).
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Möller–Trumbore ray–triangle intersection, both sides of the origin: (signed distance along
/// `dir` in units of `|dir|`, barycentric weights of `a`, `b`, `c`) or `None`. Edges count as
/// hits within 1e-9 (barycentric), so a ray through a shared edge hits one of its triangles.
pub fn ray_triangle(o: DVec3, dir: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Option<(f64, [f64; 3])> {
    let e1 = b - a;
    let e2 = c - a;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 * e1.length_squared().max(e2.length_squared()) {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - a;
    let u = s.dot(p) * inv;
    const EPS: f64 = 1e-9;
    if !(-EPS..=1.0 + EPS).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < -EPS || u + v > 1.0 + EPS {
        return None;
    }
    let t = e2.dot(q) * inv;
    let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
    let w = (1.0 - u - v).max(0.0);
    let sum = u + v + w;
    Some((t, [w / sum, u / sum, v / sum]))
}

/// An orthographic front view (along −z: x right, y up) of a box in mm, for headless pictures
/// (`landmarks --png`, `synthesize --png`, `fit-expression --residual-png`). No GPU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontView {
    /// Left (x) and top (y) of the picture, mm.
    left_mm: f64,
    top_mm: f64,
    /// Pixels per mm.
    scale: f64,
    /// Blank border, pixels.
    margin_px: f64,
    pub width_px: u32,
    pub height_px: u32,
}

impl FrontView {
    /// The view of the box `lo`–`hi` (mm) `width_px` wide with a `margin_px` border; the height
    /// follows from the box's aspect.
    pub fn fit_width(lo: DVec3, hi: DVec3, width_px: u32, margin_px: f64) -> Self {
        let scale = (width_px as f64 - 2.0 * margin_px) / (hi.x - lo.x).max(1e-9);
        let height_px = ((hi.y - lo.y) * scale + 2.0 * margin_px).ceil().max(1.0) as u32;
        FrontView {
            left_mm: lo.x,
            top_mm: hi.y,
            scale,
            margin_px,
            width_px,
            height_px,
        }
    }

    /// The view of the box at `px_per_mm`, no border, at most `max_px` along either side.
    pub fn at_scale(lo: DVec3, hi: DVec3, px_per_mm: f64, max_px: u32) -> Self {
        let side = |extent: f64| ((extent * px_per_mm) as u32 + 1).min(max_px);
        FrontView {
            left_mm: lo.x,
            top_mm: hi.y,
            scale: px_per_mm,
            margin_px: 0.0,
            width_px: side(hi.x - lo.x),
            height_px: side(hi.y - lo.y),
        }
    }

    /// Picture coordinates (pixels, y down) of a point.
    pub fn to_px(&self, p: DVec3) -> (f64, f64) {
        (
            (p.x - self.left_mm) * self.scale + self.margin_px,
            (self.top_mm - p.y) * self.scale + self.margin_px,
        )
    }

    /// Rasterises `mesh`'s triangles with a depth test (nearest = largest z): for each pixel
    /// centre inside a triangle and nearer than what it holds, calls
    /// `fragment(x, y, corners, barycentric)`. A pixel may be drawn more than once as nearer
    /// triangles arrive; the last call is the visible surface.
    pub fn rasterise(&self, mesh: &Mesh, mut fragment: impl FnMut(u32, u32, [usize; 3], [f64; 3])) {
        let (w, h) = (self.width_px as usize, self.height_px as usize);
        if w == 0 || h == 0 {
            return;
        }
        let mut depth = vec![f64::NEG_INFINITY; w * h];
        for tri in mesh.triangles() {
            let v = tri.map(|i| i as usize);
            let p = v.map(|i| mesh.positions_mm[i]);
            let q = p.map(|p| self.to_px(p));
            let area =
                (q[1].0 - q[0].0) * (q[2].1 - q[0].1) - (q[2].0 - q[0].0) * (q[1].1 - q[0].1);
            if !(area.abs() >= 1e-12) {
                continue;
            }
            let lo = |k: fn(&(f64, f64)) -> f64| q.iter().map(k).fold(f64::INFINITY, f64::min);
            let hi = |k: fn(&(f64, f64)) -> f64| q.iter().map(k).fold(f64::NEG_INFINITY, f64::max);
            let (x0, x1) = (lo(|a| a.0), hi(|a| a.0));
            let (y0, y1) = (lo(|a| a.1), hi(|a| a.1));
            if x1 < 0.0 || y1 < 0.0 {
                continue;
            }
            for y in (y0.floor().max(0.0) as usize)..=(y1.ceil() as usize).min(h - 1) {
                for x in (x0.floor().max(0.0) as usize)..=(x1.ceil() as usize).min(w - 1) {
                    let (fx, fy) = (x as f64 + 0.5, y as f64 + 0.5);
                    let b1 = ((fx - q[0].0) * (q[2].1 - q[0].1)
                        - (q[2].0 - q[0].0) * (fy - q[0].1))
                        / area;
                    let b2 = ((q[1].0 - q[0].0) * (fy - q[0].1)
                        - (fx - q[0].0) * (q[1].1 - q[0].1))
                        / area;
                    let b0 = 1.0 - b1 - b2;
                    if b0 < -1e-9 || b1 < -1e-9 || b2 < -1e-9 {
                        continue;
                    }
                    let z = b0 * p[0].z + b1 * p[1].z + b2 * p[2].z;
                    let k = y * w + x;
                    if z <= depth[k] {
                        continue;
                    }
                    depth[k] = z;
                    fragment(x as u32, y as u32, v, [b0, b1, b2]);
                }
            }
        }
    }
}
