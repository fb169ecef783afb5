//! Per-vertex colour maps with a legend (GPU-free, tested without a window): shape index,
//! displacement and distance heat maps in the viewport.

/// A colour ramp.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ramp {
    /// Sequential dark-blue → green → yellow (magnitudes: distances, displacements, mm).
    Sequential,
    /// Diverging blue → white → red (signed quantities and the shape index: cup → saddle → cap).
    Diverging,
}

/// Control points of the ramps (linear RGB), evenly spaced over [0, 1].
const SEQUENTIAL: [[f32; 3]; 5] = [
    [0.050, 0.030, 0.250],
    [0.050, 0.260, 0.520],
    [0.060, 0.560, 0.420],
    [0.500, 0.800, 0.150],
    [0.990, 0.870, 0.080],
];
const DIVERGING: [[f32; 3]; 5] = [
    [0.060, 0.180, 0.700],
    [0.350, 0.600, 0.900],
    [0.900, 0.900, 0.880],
    [0.900, 0.450, 0.300],
    [0.700, 0.050, 0.080],
];

/// A scalar field's mapping to colours: values outside `[min, max]` are clamped; NaN (no
/// value, e.g. an unmatched vertex) is drawn grey.
#[derive(Debug, Clone, PartialEq)]
pub struct ColourScale {
    pub ramp: Ramp,
    pub min: f64,
    pub max: f64,
    /// Legend title with its unit, e.g. "distance to scan (mm)".
    pub title: String,
}

/// Colour of vertices without a value.
pub const NO_VALUE: [f32; 4] = [0.35, 0.35, 0.35, 1.0];

impl ColourScale {
    /// A scale from 0 to the 98th percentile of the finite values (so one spike does not wash
    /// out the map), at least `floor`.
    pub fn magnitude(values: &[f64], floor: f64, title: impl Into<String>) -> Self {
        let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let max = if finite.is_empty() {
            floor
        } else {
            let k = ((finite.len() - 1) as f64 * 0.98).round() as usize;
            let (_, v, _) = finite.select_nth_unstable_by(k, f64::total_cmp);
            v.max(floor)
        };
        ColourScale {
            ramp: Ramp::Sequential,
            min: 0.0,
            max,
            title: title.into(),
        }
    }

    /// Colour of one value, linear RGBA.
    pub fn colour(&self, value: f64) -> [f32; 4] {
        if !value.is_finite() {
            return NO_VALUE;
        }
        let span = self.max - self.min;
        let t = if span > 0.0 {
            ((value - self.min) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let [r, g, b] = ramp_colour(self.ramp, t as f32);
        [r, g, b, 1.0]
    }

    pub fn colours(&self, values: &[f64]) -> Vec<[f32; 4]> {
        values.iter().map(|&v| self.colour(v)).collect()
    }

    /// Evenly spaced legend ticks (value, label), `count` ≥ 2.
    pub fn ticks(&self, count: usize) -> Vec<(f64, String)> {
        let count = count.max(2);
        let decimals = if (self.max - self.min).abs() >= 10.0 {
            0
        } else if (self.max - self.min).abs() >= 1.0 {
            1
        } else {
            2
        };
        (0..count)
            .map(|i| {
                let v = self.min + (self.max - self.min) * i as f64 / (count - 1) as f64;
                (v, format!("{v:.decimals$}"))
            })
            .collect()
    }
}

/// Piecewise-linear interpolation of a ramp at `t` ∈ [0, 1].
pub fn ramp_colour(ramp: Ramp, t: f32) -> [f32; 3] {
    let stops = match ramp {
        Ramp::Sequential => &SEQUENTIAL,
        Ramp::Diverging => &DIVERGING,
    };
    let x = t.clamp(0.0, 1.0) * (stops.len() - 1) as f32;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f32;
    let (a, b) = (stops[i], stops[i + 1]);
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_of_the_scale_get_the_ends_of_the_ramp_and_outside_values_clamp() {
        let s = ColourScale {
            ramp: Ramp::Sequential,
            min: 0.0,
            max: 2.0,
            title: "d (mm)".into(),
        };
        assert_eq!(s.colour(0.0)[..3], SEQUENTIAL[0]);
        assert_eq!(s.colour(2.0)[..3], SEQUENTIAL[4]);
        assert_eq!(s.colour(-5.0), s.colour(0.0));
        assert_eq!(s.colour(9.0), s.colour(2.0));
        assert_eq!(s.colour(f64::NAN), NO_VALUE);
        // Monotone brightness along the sequential ramp.
        let lum = |c: [f32; 4]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mut last = -1.0;
        for i in 0..=20 {
            let l = lum(s.colour(i as f64 * 0.1));
            assert!(l > last, "brightness falls at {i}");
            last = l;
        }
    }

    #[test]
    fn magnitude_scale_ignores_a_few_outliers_and_nan() {
        let mut values: Vec<f64> = (0..1000).map(|i| i as f64 / 1000.0).collect();
        values.extend([500.0, 800.0, f64::NAN]);
        let s = ColourScale::magnitude(&values, 0.1, "x");
        assert!(s.max > 0.95 && s.max < 1.0, "max {}", s.max);
        assert_eq!(ColourScale::magnitude(&[], 0.5, "x").max, 0.5);
        let ticks = s.ticks(3);
        assert_eq!(ticks.len(), 3);
        assert_eq!(ticks[0].0, 0.0);
        assert!((ticks[2].0 - s.max).abs() < 1e-12);
    }
}
