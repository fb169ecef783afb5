//! Small smooth 1-D helpers for the analytic face: monotone cubic tables and compact bumps.

/// Monotone piecewise-cubic Hermite interpolation (Fritsch–Carlson slopes) through the table's
/// `(x, y)` knots; `x` strictly increasing. C¹, never overshoots the knot values, clamps to the
/// end values outside the table.
pub fn pchip(table: &[(f64, f64)], x: f64) -> f64 {
    let n = table.len();
    debug_assert!(n >= 2 && table.windows(2).all(|w| w[0].0 < w[1].0));
    if x <= table[0].0 {
        return table[0].1;
    }
    if x >= table[n - 1].0 {
        return table[n - 1].1;
    }
    let k = table.partition_point(|&(xk, _)| xk <= x) - 1;
    let (x0, y0) = table[k];
    let (x1, y1) = table[k + 1];
    let h = x1 - x0;
    let m0 = knot_slope(table, k);
    let m1 = knot_slope(table, k + 1);
    let u = (x - x0) / h;
    let (u2, u3) = (u * u, u * u * u);
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    h00 * y0 + h10 * h * m0 + h01 * y1 + h11 * h * m1
}

/// Fritsch–Butland slope at knot `k`: zero at a local extremum, else a weighted harmonic mean
/// of the neighbouring secants; one-sided secant at the ends.
fn knot_slope(table: &[(f64, f64)], k: usize) -> f64 {
    let secant = |i: usize| (table[i + 1].1 - table[i].1) / (table[i + 1].0 - table[i].0);
    let n = table.len();
    if k == 0 {
        return secant(0);
    }
    if k == n - 1 {
        return secant(n - 2);
    }
    let (d0, d1) = (secant(k - 1), secant(k));
    if d0 * d1 <= 0.0 {
        return 0.0;
    }
    let h0 = table[k].0 - table[k - 1].0;
    let h1 = table[k + 1].0 - table[k].0;
    let w0 = 2.0 * h1 + h0;
    let w1 = h1 + 2.0 * h0;
    (w0 + w1) / (w0 / d0 + w1 / d1)
}

/// Compact C² bump of a squared normalised radius: `(1 − r²)³` inside the unit ellipse, 0 out.
pub fn bump(r2: f64) -> f64 {
    if r2 >= 1.0 {
        0.0
    } else {
        let q = 1.0 - r2;
        q * q * q
    }
}

/// Squared normalised distance of `(x, y)` from the centre `(cx, cy)` with radii `(rx, ry)`.
pub fn ell2(x: f64, y: f64, cx: f64, cy: f64, rx: f64, ry: f64) -> f64 {
    let (u, v) = ((x - cx) / rx, (y - cy) / ry);
    u * u + v * v
}

/// Hermite smoothstep from 0 at `e0` to 1 at `e1` (`e1 < e0` gives the falling step).
pub fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let u = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    u * u * (3.0 - 2.0 * u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pchip_hits_knots_clamps_and_stays_monotone() {
        let t = [(0.0, 0.0), (1.0, 1.0), (2.0, 1.0), (4.0, 5.0)];
        for &(x, y) in &t {
            assert!((pchip(&t, x) - y).abs() < 1e-12);
        }
        assert_eq!(pchip(&t, -1.0), 0.0);
        assert_eq!(pchip(&t, 9.0), 5.0);
        let mut prev = f64::NEG_INFINITY;
        for i in 0..=400 {
            let y = pchip(&t, i as f64 * 0.01);
            assert!(y >= prev - 1e-12 && y <= 5.0 + 1e-12);
            prev = y;
        }
        // Flat segment stays flat (no overshoot).
        assert!((pchip(&t, 1.5) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bump_and_smoothstep_ends() {
        assert_eq!(bump(0.0), 1.0);
        assert_eq!(bump(1.0), 0.0);
        assert_eq!(smoothstep(0.0, 2.0, 1.0), 0.5);
        assert_eq!(smoothstep(2.0, 0.0, 2.0), 0.0);
    }
}
