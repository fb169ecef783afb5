//! The paper's 13 feature points (section 2.1.2), named once for the whole library.
//!
//! "left" and "right" are the **subject's own** sides: in a frontal scan (face looking towards
//! +z, y up) the subject's left is +x.

use glam::DVec3;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;

/// One of the 13 feature points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FeaturePoint {
    NoseTip,
    InnerEyeLeft,
    InnerEyeRight,
    OuterEyeLeft,
    OuterEyeRight,
    NoseCornerLeft,
    NoseCornerRight,
    MouthCornerLeft,
    MouthCornerRight,
    CheekLeft,
    CheekRight,
    Forehead,
    Chin,
}

impl FeaturePoint {
    pub const COUNT: usize = 13;

    /// All points in a fixed order (the index order of [`Landmarks`]).
    pub const ALL: [FeaturePoint; 13] = [
        FeaturePoint::NoseTip,
        FeaturePoint::InnerEyeLeft,
        FeaturePoint::InnerEyeRight,
        FeaturePoint::OuterEyeLeft,
        FeaturePoint::OuterEyeRight,
        FeaturePoint::NoseCornerLeft,
        FeaturePoint::NoseCornerRight,
        FeaturePoint::MouthCornerLeft,
        FeaturePoint::MouthCornerRight,
        FeaturePoint::CheekLeft,
        FeaturePoint::CheekRight,
        FeaturePoint::Forehead,
        FeaturePoint::Chin,
    ];

    /// The points the detector finds as borders of the face region (where the cheek turns
    /// away, the hairline) rather than as anatomical points.
    pub const BORDER: [FeaturePoint; 3] = [
        FeaturePoint::CheekLeft,
        FeaturePoint::CheekRight,
        FeaturePoint::Forehead,
    ];

    pub fn index(self) -> usize {
        self as usize
    }

    /// The snake_case name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            FeaturePoint::NoseTip => "nose_tip",
            FeaturePoint::InnerEyeLeft => "inner_eye_left",
            FeaturePoint::InnerEyeRight => "inner_eye_right",
            FeaturePoint::OuterEyeLeft => "outer_eye_left",
            FeaturePoint::OuterEyeRight => "outer_eye_right",
            FeaturePoint::NoseCornerLeft => "nose_corner_left",
            FeaturePoint::NoseCornerRight => "nose_corner_right",
            FeaturePoint::MouthCornerLeft => "mouth_corner_left",
            FeaturePoint::MouthCornerRight => "mouth_corner_right",
            FeaturePoint::CheekLeft => "cheek_left",
            FeaturePoint::CheekRight => "cheek_right",
            FeaturePoint::Forehead => "forehead",
            FeaturePoint::Chin => "chin",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Which side of the face the point is on: +1 the subject's left (+x), −1 the right, 0 a
    /// midline point.
    pub fn side(self) -> f64 {
        let name = self.name();
        if name.ends_with("_left") {
            1.0
        } else if name.ends_with("_right") {
            -1.0
        } else {
            0.0
        }
    }

    /// The same point on the other side of the face (midline points map to themselves).
    pub fn mirror(self) -> Self {
        use FeaturePoint::*;
        match self {
            InnerEyeLeft => InnerEyeRight,
            InnerEyeRight => InnerEyeLeft,
            OuterEyeLeft => OuterEyeRight,
            OuterEyeRight => OuterEyeLeft,
            NoseCornerLeft => NoseCornerRight,
            NoseCornerRight => NoseCornerLeft,
            MouthCornerLeft => MouthCornerRight,
            MouthCornerRight => MouthCornerLeft,
            CheekLeft => CheekRight,
            CheekRight => CheekLeft,
            p => p,
        }
    }
}

impl std::fmt::Display for FeaturePoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Positions (mm) of all 13 feature points. Serialises as a JSON/RON map name → [x, y, z].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Landmarks(pub [DVec3; FeaturePoint::COUNT]);

impl Landmarks {
    pub fn get(&self, p: FeaturePoint) -> DVec3 {
        self.0[p.index()]
    }

    pub fn set(&mut self, p: FeaturePoint, position_mm: DVec3) {
        self.0[p.index()] = position_mm;
    }

    pub fn iter(&self) -> impl Iterator<Item = (FeaturePoint, DVec3)> + '_ {
        FeaturePoint::ALL.into_iter().map(|p| (p, self.get(p)))
    }

    /// Name → [x, y, z] map, the on-disk form.
    pub fn to_map(&self) -> BTreeMap<String, [f64; 3]> {
        self.iter()
            .map(|(p, x)| (p.name().to_string(), x.to_array()))
            .collect()
    }

    /// Parses the on-disk form; every one of the 13 names must be present, no others.
    pub fn from_map(map: &BTreeMap<String, [f64; 3]>) -> Result<Self, String> {
        let mut out = [DVec3::NAN; FeaturePoint::COUNT];
        for (name, xyz) in map {
            let p = FeaturePoint::from_name(name)
                .ok_or_else(|| format!("unknown feature point {name:?}"))?;
            let v = DVec3::from_array(*xyz);
            if !v.is_finite() {
                return Err(format!("feature point {name} has a non-finite coordinate"));
            }
            out[p.index()] = v;
        }
        if let Some(p) = FeaturePoint::ALL.iter().find(|p| out[p.index()].is_nan()) {
            return Err(format!("feature point {} is missing", p.name()));
        }
        Ok(Landmarks(out))
    }
}

impl Serialize for Landmarks {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_map().serialize(s)
    }
}

impl<'de> Deserialize<'de> for Landmarks {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let map = BTreeMap::<String, [f64; 3]>::deserialize(d)?;
        Landmarks::from_map(&map).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_mirror_is_an_involution() {
        for (i, p) in FeaturePoint::ALL.into_iter().enumerate() {
            assert_eq!(p.index(), i);
            assert_eq!(FeaturePoint::from_name(p.name()), Some(p));
            assert_eq!(p.mirror().mirror(), p);
            let lr = p.name().ends_with("_left") || p.name().ends_with("_right");
            assert_eq!(p.mirror() != p, lr, "{p}");
            assert_eq!(p.mirror().side(), -p.side(), "{p}");
        }
    }

    #[test]
    fn landmarks_json_round_trip_and_missing_point_is_an_error() {
        let mut l = Landmarks([DVec3::ZERO; 13]);
        for (i, p) in FeaturePoint::ALL.into_iter().enumerate() {
            l.set(p, DVec3::new(i as f64, -(i as f64), 0.5));
        }
        let json = serde_json::to_string(&l).unwrap();
        let back: Landmarks = serde_json::from_str(&json).unwrap();
        assert_eq!(back, l);
        let mut map = l.to_map();
        map.remove("chin");
        assert!(Landmarks::from_map(&map).unwrap_err().contains("chin"));
    }
}
