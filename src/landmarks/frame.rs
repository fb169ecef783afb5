//! The face frame and the small geometric helpers the steps share: boxes in the face frame,
//! a depth grid, the nearest vertex.

use crate::mesh::Mesh;
use glam::{DVec2, DVec3};

/// The face frame: origin at the nose tip, `u` along the inner-eye line, `v` up.
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    pub(super) origin: DVec3,
    pub(super) u: DVec2,
    pub(super) v: DVec2,
}

impl Frame {
    pub(super) fn new(origin: DVec3, roll: f64) -> Self {
        let u = DVec2::new(roll.cos(), roll.sin());
        Frame {
            origin,
            u,
            v: u.perp(),
        }
    }

    pub(super) fn uv(&self, p: DVec3) -> DVec2 {
        let d = (p - self.origin).truncate();
        DVec2::new(d.dot(self.u), d.dot(self.v))
    }
}

/// An axis-aligned box in the face frame, mm.
#[derive(Debug, Clone, Copy)]
pub(super) struct UvBox {
    pub(super) u: (f64, f64),
    pub(super) v: (f64, f64),
}

impl UvBox {
    pub(super) fn contains(&self, q: DVec2) -> bool {
        q.x >= self.u.0 && q.x <= self.u.1 && q.y >= self.v.0 && q.y <= self.v.1
    }

    /// The box with a margin of `m` mm on every side.
    pub(super) fn grown(&self, m: f64) -> UvBox {
        UvBox {
            u: (self.u.0 - m, self.u.1 + m),
            v: (self.v.0 - m, self.v.1 + m),
        }
    }
}

/// Mean depth (z) of points on a square xy grid; the nose-tip probe and the symmetry search
/// read the face through it.
pub(super) struct DepthGrid {
    lo: DVec2,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Per cell, NaN where no point fell.
    mean: Vec<f64>,
}

impl DepthGrid {
    /// `nx` × `ny` cells of `cell` mm from the corner `lo`; points outside are left out.
    pub(super) fn new(
        lo: DVec2,
        cell: f64,
        nx: usize,
        ny: usize,
        points: impl Iterator<Item = DVec3>,
    ) -> Self {
        let mut grid = DepthGrid {
            lo,
            cell,
            nx,
            ny,
            mean: vec![0.0; nx * ny],
        };
        let mut count = vec![0u32; nx * ny];
        for p in points {
            if let Some(k) = grid.index(p.truncate()) {
                grid.mean[k] += p.z;
                count[k] += 1;
            }
        }
        for (m, &c) in grid.mean.iter_mut().zip(&count) {
            *m = if c > 0 { *m / c as f64 } else { f64::NAN };
        }
        grid
    }

    fn index(&self, q: DVec2) -> Option<usize> {
        let i = ((q.x - self.lo.x) / self.cell).floor();
        let j = ((q.y - self.lo.y) / self.cell).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| j as usize * self.nx + i as usize)
    }

    /// The mean depth of the cell holding `q`, if any point fell there.
    pub(super) fn at(&self, q: DVec2) -> Option<f64> {
        self.index(q).map(|k| self.mean[k]).filter(|z| !z.is_nan())
    }

    /// Cell centres and mean depths of the cells that hold points.
    pub(super) fn filled(&self) -> impl Iterator<Item = (DVec2, f64)> + '_ {
        self.mean
            .iter()
            .enumerate()
            .filter(|(_, z)| !z.is_nan())
            .map(|(k, &z)| {
                let c = DVec2::new((k % self.nx) as f64, (k / self.nx) as f64) * self.cell
                    + self.lo
                    + 0.5 * self.cell;
                (c, z)
            })
    }
}

/// A box on one side of the face: `|u|` in `au`, `v` in `v` (side −1: the subject's right).
pub(super) fn side_box(side: f64, au: (f64, f64), v: (f64, f64)) -> UvBox {
    let u = if side < 0.0 {
        (-au.1, -au.0)
    } else {
        (au.0, au.1)
    };
    UvBox { u, v }
}

pub(super) fn side_name(side: f64) -> &'static str {
    if side < 0.0 { "right" } else { "left" }
}

pub(super) fn nearest(
    mesh: &Mesh,
    candidates: impl Iterator<Item = usize>,
    target: DVec3,
) -> usize {
    candidates
        .min_by(|&a, &b| {
            (mesh.positions_mm[a] - target)
                .length_squared()
                .total_cmp(&(mesh.positions_mm[b] - target).length_squared())
        })
        .unwrap_or(0)
}
