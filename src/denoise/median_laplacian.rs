//! The filter's iteration (paper section 2.1.1): estimate, threshold, move; the rim phase and
//! the spike-cluster refits. The step-edge test that keeps creases and lid edges: `step_edge.rs`.

use super::*;

/// Buffers of the median-Laplacian filter, allocated once per run.
pub(super) struct MedianLaplacianWork {
    pub(super) median: Vec<DVec3>,
    pub(super) candidate: Vec<DVec3>,
    pub(super) disp: Vec<f64>,
    /// Per-vertex eligibility floor, mm (the robust estimator's `k σ̂`, else the global floor).
    pub(super) floor: Vec<f64>,
    pub(super) label: Vec<u32>,
    pub(super) region_max: Vec<f64>,
    pub(super) stack: Vec<u32>,
    pub(super) xs: Vec<f64>,
    pub(super) ys: Vec<f64>,
    pub(super) zs: Vec<f64>,
    /// [`Estimator::RobustQuadric`]: the 2-rings (CSR), and which vertices need a new fit.
    pub(super) rings: Option<Rings>,
    /// The 3-rings, for vertices whose 2-ring fit stays rough (spike clusters).
    pub(super) rings3: Option<Rings>,
    pub(super) dirty: Vec<bool>,
    /// [`Estimator::RobustQuadric`]: `false` while the interior is filtered (rim vertices
    /// wait), `true` once it has settled and the rim vertices are filtered.
    pub(super) rim_phase: bool,
    pub(super) fit: QuadricFit,
}

/// The 2-ring of every vertex (the vertex itself excluded), CSR.
pub(super) struct Rings {
    pub(super) offsets: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl Rings {
    pub(super) fn new(topology: &Topology, k: usize) -> Self {
        let n = topology.vertex_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut items = Vec::with_capacity(n * 12);
        let mut scratch = vec![false; n];
        let mut ring = Vec::new();
        offsets.push(0);
        for v in 0..n {
            topology.k_ring(v, k, &mut scratch, &mut ring);
            items.extend_from_slice(&ring);
            offsets.push(items.len() as u32);
        }
        Rings { offsets, items }
    }

    pub(super) fn of(&self, v: usize) -> &[u32] {
        &self.items[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

impl MedianLaplacianWork {
    pub(super) fn new(n: usize, topology: &Topology, estimator: Estimator) -> Self {
        MedianLaplacianWork {
            median: vec![DVec3::ZERO; n],
            candidate: vec![DVec3::ZERO; n],
            disp: vec![0.0; n],
            floor: vec![0.0; n],
            label: vec![u32::MAX; n],
            region_max: Vec::new(),
            stack: Vec::new(),
            xs: Vec::with_capacity(16),
            ys: Vec::with_capacity(16),
            zs: Vec::with_capacity(16),
            rings: (estimator == Estimator::RobustQuadric).then(|| Rings::new(topology, 2)),
            rings3: (estimator == Estimator::RobustQuadric).then(|| Rings::new(topology, 3)),
            dirty: vec![true; n],
            rim_phase: false,
            fit: QuadricFit::default(),
        }
    }

    /// Steps 1–3 of [`Estimator::MedianLaplacian`]: candidates and displacements.
    pub(super) fn estimate_median_laplacian(
        &mut self,
        positions: &[DVec3],
        nb: &FilterNeighbours,
        floor: f64,
    ) {
        // 1. Component-wise median of the vertex and its filter neighbours.
        for (v, m) in self.median.iter_mut().enumerate() {
            let ring = nb.of(v);
            if ring.is_empty() {
                *m = positions[v];
                continue;
            }
            self.xs.clear();
            self.ys.clear();
            self.zs.clear();
            for p in std::iter::once(v).chain(ring.iter().map(|&u| u as usize)) {
                let p = positions[p];
                self.xs.push(p.x);
                self.ys.push(p.y);
                self.zs.push(p.z);
            }
            *m = DVec3::new(
                median(&mut self.xs),
                median(&mut self.ys),
                median(&mut self.zs),
            );
        }
        // 2. Laplacian (umbrella average) of the median-filtered mesh; 3. displacement.
        for v in 0..positions.len() {
            let ring = nb.of(v);
            let c = if ring.is_empty() {
                positions[v]
            } else if nb.is_along_rim(v) {
                self.median[v]
            } else {
                ring.iter().map(|&u| self.median[u as usize]).sum::<DVec3>() / ring.len() as f64
            };
            self.candidate[v] = c;
            self.disp[v] = c.distance(positions[v]);
            self.floor[v] = floor;
        }
    }

    /// Steps 1–3 of [`Estimator::RobustQuadric`] for the vertices marked dirty.
    pub(super) fn estimate_quadric(
        &mut self,
        positions: &[DVec3],
        input: &[DVec3],
        topology: &Topology,
        params: &DenoiseParams,
        floor: f64,
        moved: &[bool],
    ) {
        let rings = self
            .rings
            .as_ref()
            .expect("rings are built for the quadric estimator");
        let rings3 = self
            .rings3
            .as_ref()
            .expect("rings are built for the quadric estimator");
        for v in 0..positions.len() {
            if !self.dirty[v] {
                continue;
            }
            self.dirty[v] = false;
            let p = positions[v];
            let held = topology.is_boundary[v]
                && (params.boundary == BoundaryRule::Hold || !self.rim_phase);
            let estimate = if held {
                None
            } else {
                if topology.is_boundary[v] {
                    // A rim vertex is fitted from the interior of its 3-ring only: other rim
                    // vertices (single-face tips, rim spikes) are the least reliable support.
                    let interior = |u: usize| !topology.is_boundary[u];
                    self.fit
                        .predict(positions, p, rings3.of(v), interior)
                        .or_else(|| self.fit.predict(positions, p, rings3.of(v), |_| true))
                } else {
                    let all = |_: usize| true;
                    match self.fit.predict(positions, p, rings.of(v), all) {
                        // A rough 2-ring: a spike cluster may hold too large a share of it.
                        Some((_, sigma, _)) if sigma > TRIM_MIN_MM => self
                            .fit
                            .predict(positions, p, rings3.of(v), all)
                            .filter(|e| e.1 < sigma),
                        e => e,
                    }
                    .or_else(|| self.fit.predict(positions, p, rings.of(v), all))
                }
            };
            // A rim vertex moves only towards its neighbours' median height and not much
            // past it: a one-sided fit next to other defects can point the wrong way.
            let estimate = estimate.filter(|&(z, _, _)| {
                if !topology.is_boundary[v] {
                    return true;
                }
                self.zs.clear();
                self.zs.extend(
                    topology
                        .neighbours(v)
                        .iter()
                        .map(|&u| positions[u as usize].z),
                );
                if self.zs.is_empty() {
                    return false;
                }
                let towards = median(&mut self.zs) - p.z;
                let step = z - p.z;
                step * towards > 0.0 && step.abs() <= towards.abs() + params.rim_floor_mm
            });
            match estimate {
                Some((z, sigma, rough)) => {
                    self.candidate[v] = DVec3::new(p.x, p.y, z);
                    self.disp[v] = (z - p.z).abs();
                    self.floor[v] = if moved[v] {
                        params.refine_displacement_mm.max(STILL_MM)
                    } else {
                        let f =
                            eligibility_floor(params, floor, sigma, rough, topology.is_boundary[v]);
                        veto_real_surface(f, self.disp[v], input, v, rings3.of(v), topology)
                    };
                }
                None => {
                    self.candidate[v] = p;
                    self.disp[v] = 0.0;
                    self.floor[v] = f64::INFINITY;
                }
            }
        }
        self.estimate_clusters(positions, input, topology, params, floor, moved);
    }

    /// Spike clusters: a vertex whose change clears the displacement floor but not its ring's
    /// roughness test, next to other such vertices, is refitted from its 3-ring without all
    /// of them. Several spiked neighbours (up to a third of a rim vertex's ring) otherwise
    /// pull its fit towards them and make its ring look rough, so the whole cluster stays.
    pub(super) fn estimate_clusters(
        &mut self,
        positions: &[DVec3],
        input: &[DVec3],
        topology: &Topology,
        params: &DenoiseParams,
        floor: f64,
        moved: &[bool],
    ) {
        let rings3 = self
            .rings3
            .as_ref()
            .expect("rings are built for the quadric estimator");
        let n = positions.len();
        let suspect: Vec<bool> = (0..n).map(|v| self.disp[v] >= floor).collect();
        for v in 0..n {
            let blocked = suspect[v] && self.disp[v] < self.floor[v] && !moved[v];
            if !blocked
                || (topology.is_boundary[v] && !self.rim_phase)
                || !topology.neighbours(v).iter().any(|&u| suspect[u as usize])
            {
                continue;
            }
            let p = positions[v];
            let use_point = |u: usize| !suspect[u] && !topology.is_boundary[u];
            let Some((z, sigma, rough)) = self.fit.predict(positions, p, rings3.of(v), use_point)
            else {
                continue;
            };
            // Only a change the same way as the first estimate's: the cluster is one event.
            if (z - p.z) * (self.candidate[v].z - p.z) <= 0.0 {
                continue;
            }
            self.candidate[v] = DVec3::new(p.x, p.y, z);
            self.disp[v] = (z - p.z).abs();
            let f = eligibility_floor(params, floor, sigma, rough, topology.is_boundary[v]);
            self.floor[v] = veto_real_surface(f, self.disp[v], input, v, rings3.of(v), topology);
        }
    }

    /// One iteration; returns how many vertices moved.
    pub(super) fn iterate(
        &mut self,
        positions: &mut [DVec3],
        input: &[DVec3],
        nb: &FilterNeighbours,
        topology: &Topology,
        params: &DenoiseParams,
        moved: &mut [bool],
    ) -> usize {
        let floor = params.min_displacement_mm.max(STILL_MM);
        match params.estimator {
            Estimator::MedianLaplacian => self.estimate_median_laplacian(positions, nb, floor),
            Estimator::RobustQuadric => {
                self.estimate_quadric(positions, input, topology, params, floor, moved)
            }
        }
        // 4. Threshold; 5. move.
        let mut count = 0;
        match params.rule {
            MoveRule::Global => {
                let max = self
                    .disp
                    .iter()
                    .zip(&self.floor)
                    .filter(|(d, f)| d >= f)
                    .map(|(d, _)| *d)
                    .fold(0.0, f64::max);
                let t = params.w * max;
                for v in 0..positions.len() {
                    if self.disp[v] >= t && self.disp[v] >= self.floor[v] {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                        self.mark_dirty(v);
                    }
                }
            }
            MoveRule::PerRegion => {
                self.label_regions(topology);
                for v in 0..positions.len() {
                    let l = self.label[v];
                    if l != u32::MAX && self.disp[v] >= params.w * self.region_max[l as usize] {
                        positions[v] = self.candidate[v];
                        moved[v] = true;
                        count += 1;
                        self.mark_dirty(v);
                    }
                }
            }
        }
        count
    }

    /// Switches the quadric estimator to the rim phase; `false` if there is none (the paper's
    /// estimator, or no rim).
    pub(super) fn start_rim_phase(&mut self, topology: &Topology) -> bool {
        if self.rings.is_none() || !topology.is_boundary.iter().any(|&b| b) {
            return false;
        }
        self.rim_phase = true;
        for (d, &b) in self.dirty.iter_mut().zip(&topology.is_boundary) {
            *d |= b;
        }
        true
    }

    /// After `v` moved: every vertex whose estimate uses `v` needs a new one.
    pub(super) fn mark_dirty(&mut self, v: usize) {
        if let Some(rings) = &self.rings3 {
            self.dirty[v] = true;
            for &u in rings.of(v) {
                self.dirty[u as usize] = true;
            }
        }
    }

    /// Labels the connected regions of eligible vertices (`disp ≥ floor`) and records each
    /// region's largest displacement.
    pub(super) fn label_regions(&mut self, topology: &Topology) {
        self.label.fill(u32::MAX);
        self.region_max.clear();
        for seed in 0..self.disp.len() {
            if self.disp[seed] < self.floor[seed] || self.label[seed] != u32::MAX {
                continue;
            }
            let id = self.region_max.len() as u32;
            let mut max = 0.0f64;
            self.label[seed] = id;
            self.stack.clear();
            self.stack.push(seed as u32);
            while let Some(v) = self.stack.pop() {
                let v = v as usize;
                max = max.max(self.disp[v]);
                for &u in topology.neighbours(v) {
                    let u = u as usize;
                    if self.label[u] == u32::MAX && self.disp[u] >= self.floor[u] {
                        self.label[u] = id;
                        self.stack.push(u as u32);
                    }
                }
            }
            self.region_max.push(max);
        }
    }
}

/// The smallest change that moves a vertex not yet moved: the displacement floor, `k σ̂` of
/// its ring, [`RING_ROUGHNESS_RATIO`] × the ring's roughness, and the rim floor on a rim.
pub(super) fn eligibility_floor(
    params: &DenoiseParams,
    floor: f64,
    sigma: f64,
    rough: f64,
    boundary: bool,
) -> f64 {
    let rim = if boundary { params.rim_floor_mm } else { 0.0 };
    floor
        .max(params.outlier_sigmas * sigma)
        .max(RING_ROUGHNESS_RATIO * rough)
        .max(rim)
}
