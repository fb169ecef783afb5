//! The analytic face surface: a smooth, left/right symmetric map from the parameter plane
//! `(s, t)` to millimetres.
//!
//! * `t` is the height, and is the vertex's `y` (the surface is displaced horizontally only).
//! * Each height has a *base* cross-section, the front half of an ellipse (half-width `A(t)`,
//!   depth `B(t)`, front at `z = Z(t)`) that curves back to the front of the ears. `s` is the
//!   signed arc length along it from the midline (+ = subject's left = +x), so a grid uniform in
//!   `s` gives even quads on the strongly curved sides, where a height field `z(x, y)` would
//!   stretch them.
//! * Facial features (nose, brows, eye sockets, lips, chin, cheeks, …) are smooth compact bumps
//!   `h(X, t)` over the base point's frontal coordinate `X`, added along the base curve's
//!   horizontal normal.
//!
//! Everything is in millimetres with the nose tip near the origin (the builder moves it there
//! exactly); every function uses `|s|` so the surface is exactly mirror symmetric in `x`.

use super::interp::{bump, ell2, pchip};
use glam::DVec3;

/// Half-width `A(t)` of the base ellipse (mm): narrow chin and forehead top, widest at the
/// cheekbones.
const HALF_WIDTH: [(f64, f64); 9] = [
    (-95.0, 40.0),
    (-80.0, 46.0),
    (-60.0, 56.0),
    (-40.0, 63.0),
    (-20.0, 68.0),
    (10.0, 71.0),
    (40.0, 70.0),
    (70.0, 66.0),
    (100.0, 60.0),
];

/// Depth `B(t)` of the base ellipse (mm): from the front of the face back to the ears.
const DEPTH: [(f64, f64); 5] = [
    (-95.0, 58.0),
    (-70.0, 64.0),
    (-40.0, 72.0),
    (40.0, 74.0),
    (100.0, 74.0),
];

/// Front `Z(t)` of the base ellipse on the midline (mm), before features: the forehead slopes
/// back at the top and the jaw curves under the chin at the bottom.
const FRONT_Z: [(f64, f64); 12] = [
    (-95.0, -62.0),
    (-82.0, -46.0),
    (-72.0, -36.0),
    (-58.0, -30.0),
    (-40.0, -28.0),
    (-10.0, -25.5),
    (20.0, -25.0),
    (45.0, -25.0),
    (60.0, -27.0),
    (75.0, -32.0),
    (90.0, -40.0),
    (100.0, -47.0),
];

/// Base cross-section at height `t`: half-width, depth and front z.
#[derive(Debug, Clone, Copy)]
pub struct Section {
    pub a: f64,
    pub b: f64,
    pub front_z: f64,
}

impl Section {
    pub fn at(t: f64) -> Self {
        Section {
            a: pchip(&HALF_WIDTH, t),
            b: pchip(&DEPTH, t),
            front_z: pchip(&FRONT_Z, t),
        }
    }

    /// Arc length from the midline to the ellipse angle `theta` (8-point Gauss–Legendre, exact
    /// to ~1e-10 mm for these nearly circular ellipses).
    pub fn arc(&self, theta: f64) -> f64 {
        const X: [f64; 4] = [
            0.183_434_642_495_649_8,
            0.525_532_409_916_329,
            0.796_666_477_413_626_7,
            0.960_289_856_497_536_3,
        ];
        const W: [f64; 4] = [
            0.362_683_783_378_362,
            0.313_706_645_877_887_3,
            0.222_381_034_453_374_5,
            0.101_228_536_290_376_3,
        ];
        let half = 0.5 * theta;
        let mut sum = 0.0;
        for (x, w) in X.iter().zip(W) {
            for u in [half * (1.0 - x), half * (1.0 + x)] {
                sum += w * self.speed(u);
            }
        }
        sum * half
    }

    fn speed(&self, theta: f64) -> f64 {
        let (s, c) = theta.sin_cos();
        (self.a * self.a * c * c + self.b * self.b * s * s).sqrt()
    }

    /// Ellipse angle at arc length `s ≥ 0` (Newton on [`Section::arc`]).
    pub fn theta_at(&self, s: f64) -> f64 {
        let mut theta = s / self.a;
        for _ in 0..8 {
            let f = self.arc(theta) - s;
            if f.abs() < 1e-10 {
                break;
            }
            theta -= f / self.speed(theta);
        }
        theta
    }
}

/// The surface point at signed arc length `s` and height `t`.
pub fn surface(s: f64, t: f64) -> DVec3 {
    let sec = Section::at(t);
    let theta = sec.theta_at(s.abs());
    let (sin, cos) = theta.sin_cos();
    let x_base = sec.a * sin;
    let z_base = sec.front_z - sec.b * (1.0 - cos);
    let normal = glam::DVec2::new(sec.b * sin, sec.a * cos).normalize();
    let h = relief(x_base, t);
    let x = x_base + h * normal.x;
    DVec3::new(if s < 0.0 { -x } else { x }, t, z_base + h * normal.y)
}

/// Relief of the facial features (mm, along the base normal) at frontal coordinate `x` (only
/// `|x|` matters) and height `t`. Each term is one anatomical feature.
pub fn relief(x: f64, t: f64) -> f64 {
    let ax = x.abs();
    let mut h = 0.0;

    // --- Nose: dorsum ridge from the nasion down to the tip, the tip lobule, the alae. ---
    let nose_height = pchip(
        &[
            (-17.0, 0.0),
            (-14.0, 2.0),
            (-10.0, 8.0),
            (-6.5, 15.5),
            (-3.0, 21.5),
            (0.0, 23.5),
            (3.5, 22.0),
            (9.0, 17.0),
            (18.0, 11.5),
            (28.0, 6.0),
            (37.0, 1.5),
            (44.0, 0.0),
        ],
        t,
    );
    let nose_half_width = pchip(
        &[
            (-14.0, 10.0),
            (-6.0, 13.0),
            (2.0, 14.0),
            (10.0, 12.5),
            (25.0, 11.5),
            (40.0, 11.0),
        ],
        t,
    );
    let u = ax / nose_half_width;
    if u < 1.0 {
        let q = 1.0 - u * u;
        h += nose_height * q * q;
    }
    // Alae (nostril wings) beside and just behind the tip.
    h += 7.5 * bump(ell2(ax, t, 11.0, -5.0, 9.0, 7.5));

    // --- Eyes: orbit hollow, eyeball/lids, brow ridge, glabella. ---
    h -= 7.5 * bump(ell2(ax, t, 32.0, 32.0, 21.0, 14.0));
    h += 5.0 * bump(ell2(ax, t, 33.0, 32.5, 14.5, 9.0));
    h += 3.8 * bump(ell2(ax, t, 29.0, 44.5, 25.0, 10.5));
    h += 3.0 * bump(ell2(ax, t, 0.0, 45.0, 15.0, 9.0));

    // --- Cheeks: cheekbones, hollow below them. ---
    h += 4.5 * bump(ell2(ax, t, 46.0, 12.0, 22.0, 17.0));
    h -= 1.5 * bump(ell2(ax, t, 50.0, -28.0, 16.0, 20.0));

    // --- Mouth: dental arch, lips, the lips' roll-in at the slit, corners, folds, chin. ---
    h += 9.0 * bump(ell2(ax, t, 0.0, -29.0, 36.0, 27.0));
    h += 2.6 * bump(ell2(ax, t, 0.0, -31.2, 21.0, 3.6));
    h += 3.0 * bump(ell2(ax, t, 0.0, -38.5, 19.0, 5.0));
    // Philtrum: a shallow groove from the columella down to the upper lip.
    h -= 0.9 * bump(ell2(ax, t, 0.0, -22.0, 4.5, 8.0));
    h -= 2.0 * (-((t + 34.4) / 1.6).powi(2)).exp() * bump((ax / 26.0).powi(2));
    h -= 1.2 * bump(ell2(ax, t, 25.5, -34.4, 5.0, 5.0));
    h -= 1.8 * bump(ell2(ax, t, 0.0, -48.0, 20.0, 5.0));
    h += 8.0 * bump(ell2(ax, t, 0.0, -63.0, 20.0, 14.5));

    // --- Forehead: frontal eminences. ---
    h += 1.5 * bump(ell2(ax, t, 22.0, 64.0, 18.0, 14.0));
    h
}
