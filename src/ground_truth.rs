//! Ground truth written by `../shared/bench/synth_gavab.py` (one JSON per scan), for tests,
//! benchmarks and `facesynth` evaluation commands. Only the fields we score against are read.

use crate::feature_points::FeaturePoint;
use crate::{Error, Result};
use glam::DVec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// One scan's ground truth.
#[derive(Debug, Clone, Deserialize)]
pub struct ScanTruth {
    pub subject: String,
    /// `frontal1`, `frontal2`, `sonrisa`, `risa` or `gesto`.
    pub scan: String,
    pub clean: bool,
    /// Named landmarks in the generator's naming (`inner_eye_corner_left`, …).
    pub landmarks: BTreeMap<String, TruthLandmark>,
    #[serde(default)]
    pub expression_weights: BTreeMap<String, f64>,
    pub grid: TruthGrid,
    /// `None` for clean scans.
    pub noise: Option<TruthNoise>,
}

#[derive(Debug, Clone, Deserialize)]
pub struct TruthLandmark {
    pub xyz_mm: [f64; 3],
    /// Not hidden by lids/lips and inside the field of view.
    pub visible: bool,
    /// Its nearest grid sample is a vertex of the file (not lost to a hole or hair).
    pub in_scan: bool,
}

#[derive(Debug, Clone, Deserialize)]
pub struct TruthGrid {
    pub spacing_mm: f64,
    pub x_first_col_mm: f64,
    pub y_first_row_mm: f64,
    pub ncols: usize,
    pub nrows: usize,
}

#[derive(Debug, Clone, Deserialize)]
pub struct TruthNoise {
    pub spikes: TruthSpikes,
}

#[derive(Debug, Clone, Deserialize)]
pub struct TruthSpikes {
    pub vertex_index: Vec<usize>,
    pub dz_mm: Vec<f64>,
}

impl ScanTruth {
    pub fn load(path: &Path) -> Result<Self> {
        Self::parse(&crate::io::read_text_file(path)?, path)
    }

    /// Parses a sidecar's text (`path` only names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        serde_json::from_str(text).map_err(|e| Error::invalid(path, e.to_string()))
    }

    /// The ground-truth position of one of our feature points, if the generator provides it
    /// (it has no cheek or forehead points).
    pub fn feature_point(&self, p: FeaturePoint) -> Option<&TruthLandmark> {
        self.landmarks.get(truth_name(p)?)
    }

    /// Our feature points that have ground truth, with positions.
    pub fn feature_points(&self) -> Vec<(FeaturePoint, DVec3, &TruthLandmark)> {
        FeaturePoint::ALL
            .into_iter()
            .filter_map(|p| {
                self.feature_point(p)
                    .map(|t| (p, DVec3::from_array(t.xyz_mm), t))
            })
            .collect()
    }
}

/// The generator's name for one of our feature points (same left/right convention).
pub fn truth_name(p: FeaturePoint) -> Option<&'static str> {
    use FeaturePoint::*;
    Some(match p {
        NoseTip => "nose_tip",
        InnerEyeLeft => "inner_eye_corner_left",
        InnerEyeRight => "inner_eye_corner_right",
        OuterEyeLeft => "outer_eye_corner_left",
        OuterEyeRight => "outer_eye_corner_right",
        NoseCornerLeft => "nose_corner_left",
        NoseCornerRight => "nose_corner_right",
        MouthCornerLeft => "mouth_corner_left",
        MouthCornerRight => "mouth_corner_right",
        Chin => "chin",
        CheekLeft | CheekRight | Forehead => return None,
    })
}
