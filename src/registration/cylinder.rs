//! Step 3, Z by cylindrical projection: rays from a vertical axis behind the nose onto the
//! outermost scan triangle.

use super::*;

/// The projection cylinder's frame: `origin_mm` is on the axis, the axis is `rotation · Y`
/// and θ = 0 points along `rotation · Z` (towards the face). Local coordinates are mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CylinderFrame {
    pub origin_mm: DVec3,
    pub rotation: DQuat,
}

impl CylinderFrame {
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.rotation.inverse() * (p - self.origin_mm)
    }

    pub fn to_world(&self, q: DVec3) -> DVec3 {
        self.rotation * q + self.origin_mm
    }
}

/// A ray hit of [`CylinderProjector::cast`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CylinderHit {
    /// Hit point in the cylinder frame.
    pub local: DVec3,
    /// Its distance from the axis, mm.
    pub radius: f64,
    /// Index into `scan.triangles()`.
    pub triangle: usize,
    /// Barycentric coordinates in that triangle.
    pub barycentric: [f64; 3],
}

/// Casts horizontal rays from the cylinder axis onto a scan, through a uniform grid over the
/// scan triangles in the unrolled (u = r₀·θ, height) plane.
#[derive(Debug, Clone)]
pub struct CylinderProjector {
    frame: CylinderFrame,
    r0: f64,
    local: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    grid: Grid2,
}

impl CylinderProjector {
    /// `r0` scales θ into mm for the grid (use the nose tip's distance from the axis).
    pub fn new(
        scan: &Mesh,
        frame: CylinderFrame,
        r0: f64,
        params: &RegistrationParams,
    ) -> Result<Self> {
        let local: Vec<DVec3> = scan
            .positions_mm
            .iter()
            .map(|p| frame.to_local(*p))
            .collect();
        let radius: Vec<f64> = local.iter().map(|q| q.x.hypot(q.z)).collect();
        // Spikes: radial distance far from the median of the 1-ring.
        let mut spike = vec![false; local.len()];
        if params.spike_threshold_mm.is_finite() {
            let topo = Topology::new(scan);
            let mut nb = Vec::new();
            for (v, s) in spike.iter_mut().enumerate() {
                nb.clear();
                nb.extend(topo.neighbours(v).iter().map(|&u| radius[u as usize]));
                if nb.len() >= 2 {
                    *s = (radius[v] - median(&mut nb)).abs() > params.spike_threshold_mm;
                }
            }
        }
        let triangles: Vec<[u32; 3]> = scan
            .triangles()
            .into_iter()
            .filter(|t| t.iter().all(|&v| !spike[v as usize]))
            .collect();
        let uv = |q: DVec3| DVec2::new(r0 * q.x.atan2(q.z), q.y);
        let mut boxes = Vec::with_capacity(triangles.len());
        for t in &triangles {
            let p = t.map(|v| local[v as usize]);
            let a = p.map(uv);
            // Skip triangles across θ = ±π (behind the head) or touching the axis.
            let wrap = (a[0].x - a[1].x).abs().max((a[1].x - a[2].x).abs()) > r0 * 1.5;
            let near_axis = t.iter().any(|&v| radius[v as usize] < 1e-6);
            if wrap || near_axis {
                boxes.push(None);
                continue;
            }
            let lo = a[0].min(a[1]).min(a[2]);
            let hi = a[0].max(a[1]).max(a[2]);
            // Edges bulge in (θ, h): pad by a small fraction of the extent.
            let pad = (hi - lo).max_element() * 0.05 + 1e-6;
            boxes.push(Some((lo - pad, hi + pad)));
        }
        let grid = Grid2::build(&boxes, params.grid_cell_mm.max(0.1));
        Ok(CylinderProjector {
            frame,
            r0,
            local,
            triangles,
            grid,
        })
    }

    pub fn frame(&self) -> CylinderFrame {
        self.frame
    }

    /// The outermost scan point on the horizontal ray from the axis at height `h` towards
    /// angle `theta` (radians, 0 = towards the face, positive towards local +x).
    pub fn cast(&self, theta: f64, h: f64) -> Option<CylinderHit> {
        let dir = DVec3::new(theta.sin(), 0.0, theta.cos());
        let origin = DVec3::new(0.0, h, 0.0);
        let mut best: Option<CylinderHit> = None;
        for &ti in self.grid.query(DVec2::new(self.r0 * theta, h)) {
            let t = self.triangles[ti as usize];
            let [a, b, c] = t.map(|v| self.local[v as usize]);
            if let Some((dist, bary)) = ray_triangle(origin, dir, a, b, c)
                && dist > 0.0
                && best.is_none_or(|h| dist > h.radius)
            {
                best = Some(CylinderHit {
                    local: a * bary[0] + b * bary[1] + c * bary[2],
                    radius: dist,
                    triangle: ti as usize,
                    barycentric: bary,
                });
            }
        }
        best
    }
}

/// A uniform 2D grid of item ids by bounding box (CSR storage).
#[derive(Debug, Clone)]
struct Grid2 {
    min: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    offsets: Vec<u32>,
    items: Vec<u32>,
}

impl Grid2 {
    fn build(boxes: &[Option<(DVec2, DVec2)>], cell: f64) -> Self {
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for (l, h) in boxes.iter().flatten() {
            lo = lo.min(*l);
            hi = hi.max(*h);
        }
        if !lo.is_finite() {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let nx = (((hi.x - lo.x) / cell).floor() as usize + 1).min(1 << 14);
        let ny = (((hi.y - lo.y) / cell).floor() as usize + 1).min(1 << 14);
        let cell_of = |p: DVec2| -> (usize, usize) {
            let i = (((p.x - lo.x) / cell).floor().max(0.0) as usize).min(nx - 1);
            let j = (((p.y - lo.y) / cell).floor().max(0.0) as usize).min(ny - 1);
            (i, j)
        };
        let mut counts = vec![0u32; nx * ny + 1];
        for (l, h) in boxes.iter().flatten() {
            let (i0, j0) = cell_of(*l);
            let (i1, j1) = cell_of(*h);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    counts[j * nx + i + 1] += 1;
                }
            }
        }
        for k in 1..counts.len() {
            counts[k] += counts[k - 1];
        }
        let mut fill = counts.clone();
        let mut items = vec![0u32; counts[nx * ny] as usize];
        for (id, b) in boxes.iter().enumerate() {
            if let Some((l, h)) = b {
                let (i0, j0) = cell_of(*l);
                let (i1, j1) = cell_of(*h);
                for j in j0..=j1 {
                    for i in i0..=i1 {
                        let c = j * nx + i;
                        items[fill[c] as usize] = id as u32;
                        fill[c] += 1;
                    }
                }
            }
        }
        Grid2 {
            min: lo,
            cell,
            nx,
            ny,
            offsets: counts,
            items,
        }
    }

    fn query(&self, p: DVec2) -> &[u32] {
        let fx = (p.x - self.min.x) / self.cell;
        let fy = (p.y - self.min.y) / self.cell;
        if !(fx >= 0.0 && fy >= 0.0) || fx >= self.nx as f64 || fy >= self.ny as f64 {
            return &[];
        }
        let c = fy as usize * self.nx + fx as usize;
        &self.items[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }
}
