//! The detector: its state, the order of the nine steps ([`Detector::run`]), and the region
//! and walk helpers the steps share. Each step's methods are in the file of that step.

use super::frame::{Frame, UvBox, nearest};
use super::table2::{LEVEL_MAX_MM, level_checks, plausibility};
use super::{LandmarkParams, LandmarkReport};
use crate::Result;
use crate::curvature::SurfaceDescriptors;
use crate::feature_points::{FeaturePoint, Landmarks};
use crate::mesh::{Mesh, Topology};
use glam::{DVec2, DVec3};

/// Our addition: concave feature masks (eye, nose and mouth corners) also need curvedness
/// of at least this, 1/mm (a radius of 50 mm), so shape-index noise on flat skin is ignored.
pub const FEATURE_MIN_CURVEDNESS_PER_MM: f64 = 0.02;

/// The state of one detection: the scan, its descriptors, and the warnings so far.
pub(super) struct Detector<'a> {
    pub(super) mesh: &'a Mesh,
    pub(super) topology: &'a Topology,
    pub(super) desc: &'a SurfaceDescriptors,
    pub(super) params: &'a LandmarkParams,
    pub(super) warnings: Vec<String>,
    /// Where face localisation put the nose tip (this mesh's frame): step 1 keeps the region
    /// around it and step 2 looks near it. `None`: the paper's steps alone.
    pub(super) prior_nose: Option<DVec3>,
    /// Points placed at their Table 2 average position (their feature was not found).
    pub(super) guessed: Vec<FeaturePoint>,
}

/// The warning of a point placed at its Table 2 average position.
pub(super) fn fallback_warning(p: FeaturePoint) -> String {
    format!("{p}: its surface feature was not found; placed at the Table 2 average position")
}

/// What the nine steps found, before the Table 2 and level checks.
#[derive(Debug, Clone)]
pub(super) struct StepPoints {
    pub(super) landmarks: Landmarks,
    /// The mesh vertex each point was snapped to.
    pub(super) vertex: [usize; FeaturePoint::COUNT],
    /// The face frame's roll (radians; `LandmarkReport::roll_deg`).
    pub(super) roll: f64,
    /// The symmetry line's roll (radians), where found.
    pub(super) symmetry_roll: Option<f64>,
    pub(super) face_vertices: usize,
    /// The steps' warnings (fallbacks, replaced regions).
    pub(super) warnings: Vec<String>,
    pub(super) guessed: Vec<FeaturePoint>,
}

impl StepPoints {
    /// The report: the points with the Table 2 plausibility and level checks in the face frame
    /// (origin at the nose tip, turned by the roll), one warning per failed check.
    pub(super) fn into_report(self) -> LandmarkReport {
        let frame = Frame::new(self.landmarks.get(FeaturePoint::NoseTip), self.roll);
        let mut warnings = self.warnings;
        let distances = plausibility(&self.landmarks, &frame);
        for d in &distances {
            if !d.in_range {
                warnings.push(format!(
                    "{}: {} {:?} distance {:.1} mm outside Table 2 range [{}, {}] mm",
                    d.point, d.name, d.stat.direction, d.measured_mm, d.stat.min_mm, d.stat.max_mm
                ));
            }
        }
        let level = if self.symmetry_roll.is_some() {
            level_checks(&self.landmarks, &frame)
        } else {
            Vec::new()
        };
        for l in level.iter().filter(|l| !l.in_range) {
            warnings.push(format!(
                "{}/{}: heights differ by {:.1} mm across the face's symmetry line (more than \
                 {LEVEL_MAX_MM} mm); one of them is probably off",
                l.left,
                l.right,
                l.difference_mm.abs()
            ));
        }
        LandmarkReport {
            landmarks: self.landmarks,
            vertex: self.vertex,
            distances,
            level,
            warnings,
            roll_deg: self.roll.to_degrees(),
            symmetry_roll_deg: self.symmetry_roll.map(f64::to_degrees),
            face_vertices: self.face_vertices,
            guessed: self.guessed,
            spread_mm: None,
            localisation: None,
            descriptors: None,
            suspect: Vec::new(),
        }
    }
}

impl<'a> Detector<'a> {
    /// A detection on `mesh` with its topology and descriptors, no warnings yet.
    pub(super) fn new(
        mesh: &'a Mesh,
        topology: &'a Topology,
        desc: &'a SurfaceDescriptors,
        params: &'a LandmarkParams,
        prior_nose: Option<DVec3>,
    ) -> Self {
        Detector {
            mesh,
            topology,
            desc,
            params,
            warnings: Vec::new(),
            prior_nose,
            guessed: Vec::new(),
        }
    }
}

impl Detector<'_> {
    pub(super) fn p(&self, v: usize) -> DVec3 {
        self.mesh.positions_mm[v]
    }

    pub(super) fn run(mut self) -> Result<StepPoints> {
        use FeaturePoint::*;
        let n = self.mesh.vertex_count();
        // Step 1.
        let face = self.segment_face()?;
        let face_vertices = face.iter().filter(|&&f| f).count();
        // Step 2.
        let (nose_tip, nose_v) = self.nose_tip(&face)?;
        // Step 3 (in the scan frame; the face frame follows from its result).
        let frame0 = Frame::new(nose_tip, 0.0);
        let symmetry_roll = self.symmetry_roll(&face, nose_tip);
        let (inner_r, inner_l) = self.inner_eyes(&frame0, symmetry_roll);
        // The symmetry line is the better roll (0.6° against the eye line's 1.9° mean error on
        // 100 benchmark scans); the eye line stands in where there is none.
        let roll = symmetry_roll
            .unwrap_or_else(|| self.eye_line_roll(inner_r, inner_l).clamp(-0.35, 0.35));
        let frame = Frame::new(nose_tip, roll);
        let (inner_r, inner_l) = if self.params.inner_eye_at_fissure {
            self.inner_eyes_at_fissures(&frame, inner_r, inner_l)
        } else {
            (inner_r, inner_l)
        };
        // Step 4.
        let (mut outer_r, mut outer_l) = self.outer_eyes(&frame, inner_r, inner_l);
        if self.params.outer_eye_at_fissure {
            outer_r = self.outer_eye_fissure_end(&frame, outer_r, -1.0);
            outer_l = self.outer_eye_fissure_end(&frame, outer_l, 1.0);
        }
        // Step 5.
        let nose_r = self.nose_corner(&frame, -1.0);
        let nose_l = self.nose_corner(&frame, 1.0);
        // Step 6.
        let nose_corner_v = 0.5 * (frame.uv(self.p(nose_l)).y + frame.uv(self.p(nose_r)).y);
        let (mouth_r, mouth_l) = self.mouth_corners(&frame, outer_r, outer_l, nose_corner_v);
        // Step 7.
        let eye_v = 0.5 * (frame.uv(self.p(inner_l)).y + frame.uv(self.p(inner_r)).y);
        let mouth_v = 0.5 * (frame.uv(self.p(mouth_l)).y + frame.uv(self.p(mouth_r)).y);
        let cheek_r = self.cheek(&frame, outer_r, -1.0);
        let cheek_l = self.cheek(&frame, outer_l, 1.0);
        // Step 8.
        let mid_u = 0.5 * (frame.uv(self.p(inner_l)).x + frame.uv(self.p(inner_r)).x);
        let forehead = self.forehead(&frame, &face, mid_u, eye_v);
        // Step 9.
        let mouth_u = 0.5 * (frame.uv(self.p(mouth_l)).x + frame.uv(self.p(mouth_r)).x);
        let chin = self.chin(&frame, mouth_u, mouth_v);

        let mut vertex = [0usize; FeaturePoint::COUNT];
        let assign = [
            (NoseTip, nose_v),
            (InnerEyeLeft, inner_l),
            (InnerEyeRight, inner_r),
            (OuterEyeLeft, outer_l),
            (OuterEyeRight, outer_r),
            (NoseCornerLeft, nose_l),
            (NoseCornerRight, nose_r),
            (MouthCornerLeft, mouth_l),
            (MouthCornerRight, mouth_r),
            (CheekLeft, cheek_l),
            (CheekRight, cheek_r),
            (Forehead, forehead),
            (Chin, chin),
        ];
        let mut lm = Landmarks([DVec3::ZERO; FeaturePoint::COUNT]);
        for (p, v) in assign {
            debug_assert!(v < n);
            vertex[p.index()] = v;
            lm.set(p, self.p(v));
        }
        lm.set(NoseTip, nose_tip);
        Ok(StepPoints {
            landmarks: lm,
            vertex,
            roll,
            symmetry_roll,
            face_vertices,
            warnings: self.warnings,
            guessed: self.guessed,
        })
    }

    /// Connected regions of the vertices where `mask` holds.
    pub(super) fn regions(&self, mask: &[bool]) -> Vec<Vec<u32>> {
        let mut seen = vec![false; mask.len()];
        let mut out = Vec::new();
        for s in 0..mask.len() {
            if mask[s] && !seen[s] {
                out.push(self.grow(s, mask, &mut seen));
            }
        }
        out
    }

    /// The connected region of `mask` that holds `seed` (`mask[seed]` must hold).
    pub(super) fn region_of(&self, seed: usize, mask: &[bool]) -> Vec<u32> {
        self.grow(seed, mask, &mut vec![false; mask.len()])
    }

    /// The vertices of `mask` that mesh edges through `mask` reach from `seed`, marked in `seen`.
    fn grow(&self, seed: usize, mask: &[bool], seen: &mut [bool]) -> Vec<u32> {
        let mut region = Vec::new();
        seen[seed] = true;
        let mut stack = vec![seed as u32];
        while let Some(v) = stack.pop() {
            region.push(v);
            for &u in self.topology.neighbours(v as usize) {
                if mask[u as usize] && !seen[u as usize] {
                    seen[u as usize] = true;
                    stack.push(u);
                }
            }
        }
        region
    }

    /// The largest region of `mask`, if any.
    pub(super) fn biggest(&self, mask: &[bool]) -> Option<Vec<u32>> {
        self.biggest_where(mask, |_| true)
    }

    /// The largest region of `mask` for which `keep` holds, if any.
    pub(super) fn biggest_where(
        &self,
        mask: &[bool],
        keep: impl Fn(&[u32]) -> bool,
    ) -> Option<Vec<u32>> {
        (self.regions(mask).into_iter())
            .filter(|r| keep(r))
            .max_by_key(|r| r.len())
    }

    /// Mask of the vertices inside `b` (face frame) where `pred(v)` holds.
    pub(super) fn box_mask(
        &self,
        frame: &Frame,
        b: UvBox,
        pred: impl Fn(usize) -> bool,
    ) -> Vec<bool> {
        (0..self.mesh.vertex_count())
            .map(|v| b.contains(frame.uv(self.p(v))) && pred(v))
            .collect()
    }

    /// The mean position of a (non-empty) region's vertices, mm.
    pub(super) fn centroid(&self, region: &[u32]) -> DVec3 {
        region.iter().map(|&v| self.p(v as usize)).sum::<DVec3>() / region.len() as f64
    }

    /// The region vertex nearest the region's centroid.
    pub(super) fn centroid_vertex(&self, region: &[u32]) -> usize {
        nearest(
            self.mesh,
            region.iter().map(|&v| v as usize),
            self.centroid(region),
        )
    }

    /// The region vertex maximising `f(position)`.
    pub(super) fn most(&self, region: &[u32], f: impl Fn(DVec3) -> f64) -> usize {
        region
            .iter()
            .map(|&v| v as usize)
            .max_by(|&a, &b| f(self.p(a)).total_cmp(&f(self.p(b))))
            .unwrap_or(region[0] as usize)
    }

    /// A walk along a strip: `key[v]` is NaN outside the strip, else the distance along the
    /// walk. Starts from every strip vertex within `seed_band_mm` of the smallest key,
    /// follows mesh edges inside the strip (so depth jumps, holes and the hairline stop it),
    /// and returns the vertices reached, the start (the smallest key) first, then in the order
    /// the walk reached them; `None` where the strip is empty.
    pub(super) fn strip_walk(&self, key: &[f64], seed_band_mm: f64) -> Option<Vec<usize>> {
        let start = (0..key.len())
            .filter(|&v| !key[v].is_nan())
            .min_by(|&a, &b| key[a].total_cmp(&key[b]))?;
        let mask: Vec<bool> = key.iter().map(|k| !k.is_nan()).collect();
        let mut seen = vec![false; key.len()];
        let mut stack: Vec<usize> = (0..key.len())
            .filter(|&v| mask[v] && key[v] <= key[start] + seed_band_mm)
            .collect();
        for &v in &stack {
            seen[v] = true;
        }
        let mut reached = vec![start];
        while let Some(v) = stack.pop() {
            reached.push(v);
            for &u in self.topology.neighbours(v) {
                let u = u as usize;
                if mask[u] && !seen[u] {
                    seen[u] = true;
                    stack.push(u);
                }
            }
        }
        Some(reached)
    }

    /// The vertex nearest a Table 2 prior position (face frame), with a warning.
    pub(super) fn fallback(
        &mut self,
        p: FeaturePoint,
        side: f64,
        frame: &Frame,
        at: DVec2,
    ) -> usize {
        let p = if side < 0.0 { p.mirror() } else { p };
        self.guessed.push(p);
        self.warnings.push(fallback_warning(p));
        let target = frame.origin.truncate() + frame.u * at.x + frame.v * at.y;
        (0..self.mesh.vertex_count())
            .min_by(|&a, &b| {
                let da = (self.p(a).truncate() - target).length_squared();
                let db = (self.p(b).truncate() - target).length_squared();
                da.total_cmp(&db)
            })
            .unwrap_or(0)
    }
}

/// A test surface with what a [`Detector`] reads (default parameters), for unit tests of
/// single steps.
#[cfg(test)]
pub(super) struct TestSurface {
    pub(super) mesh: Mesh,
    topology: Topology,
    desc: SurfaceDescriptors,
    params: LandmarkParams,
}

#[cfg(test)]
impl TestSurface {
    pub(super) fn new(mesh: Mesh) -> Self {
        let params = LandmarkParams::default();
        let topology = Topology::new(&mesh);
        let desc =
            crate::curvature::compute_with_topology(&mesh, &topology, &params.curvature).unwrap();
        TestSurface {
            mesh,
            topology,
            desc,
            params,
        }
    }

    /// A detector on the surface, without a localisation prior.
    pub(super) fn detector(&self) -> Detector<'_> {
        Detector::new(&self.mesh, &self.topology, &self.desc, &self.params, None)
    }
}
