//! CMC plots (`facesynth evaluate --plot`): recognition rate (%) against rank 1 … N, one curve
//! per run and probe set, drawn with `plotters` into an RGB buffer and written as PNG.
//!
//! Text uses the Ubuntu Light font embedded by `epaint_default_fonts` (Ubuntu Font Licence),
//! registered with plotters' `ab_glyph` backend, so no system font library is needed.

use crate::{Error, Result};
use plotters::prelude::*;
use std::path::Path;

/// One CMC curve.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Legend text.
    pub label: String,
    /// Recognition rate at rank 1 … N, as fractions in [0, 1].
    pub cmc: Vec<f64>,
    /// Colour slot (curves of the same probe set share one).
    pub colour: usize,
    /// Dashed (e.g. the run without augmentation) rather than solid.
    pub dashed: bool,
    /// Thick line (the all-probes curves).
    pub bold: bool,
}

/// Width and height of the picture, pixels.
pub const DEFAULT_SIZE: (u32, u32) = (1000, 700);

const FONT: &str = "sans-serif";

fn register_font() -> Result<()> {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, epaint_default_fonts::UBUNTU_LIGHT)
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::algorithm(
            "plot",
            "the embedded font could not be loaded",
        ))
    }
}

fn palette(slot: usize) -> RGBColor {
    const COLOURS: [RGBColor; 6] = [
        RGBColor(0, 0, 0),
        RGBColor(31, 119, 180),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
    ];
    COLOURS[slot % COLOURS.len()]
}

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::algorithm("plot", e.to_string())
}

/// Renders the curves (all of the same length N ≥ 1) as an RGB8 buffer of `size`.
pub fn render_cmc(title: &str, curves: &[Curve], size: (u32, u32)) -> Result<Vec<u8>> {
    let n = curves.first().map_or(0, |c| c.cmc.len());
    if n == 0 || curves.iter().any(|c| c.cmc.len() != n) {
        return Err(Error::algorithm(
            "plot",
            "CMC curves must be non-empty and all of the same length",
        ));
    }
    if size.0 < 200 || size.1 < 150 {
        return Err(Error::algorithm("plot", "picture smaller than 200 × 150"));
    }
    register_font()?;
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        // A one-rank CMC still gets a visible x range.
        let x_max = (n as f64).max(2.0);
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT, 24))
            .margin(20)
            .x_label_area_size(55)
            .y_label_area_size(70)
            .build_cartesian_2d(1f64..x_max, 0f64..100.5f64)
            .map_err(plot_error)?;
        chart
            .configure_mesh()
            .x_desc("Rank")
            .y_desc("Recognition rate (%)")
            .axis_desc_style((FONT, 20))
            .label_style((FONT, 16))
            .x_labels(n.clamp(2, 13))
            .x_label_formatter(&|x| format!("{:.0}", x))
            .y_labels(11)
            .y_label_formatter(&|y| format!("{:.0}", y))
            .light_line_style(RGBColor(240, 240, 240))
            .max_light_lines(1)
            .draw()
            .map_err(plot_error)?;
        for c in curves {
            let colour = palette(c.colour);
            let style = colour.stroke_width(if c.bold { 3 } else { 2 });
            let points: Vec<(f64, f64)> = c
                .cmc
                .iter()
                .enumerate()
                .map(|(r, &v)| ((r + 1) as f64, 100.0 * v.clamp(0.0, 1.0)))
                .collect();
            let legend_style = style;
            let dashed = c.dashed;
            let anno = if dashed {
                chart
                    .draw_series(DashedLineSeries::new(points, 8, 5, style))
                    .map_err(plot_error)?
            } else {
                chart
                    .draw_series(LineSeries::new(points, style))
                    .map_err(plot_error)?
            };
            // Legend sample: two segments, touching (solid) or apart (dashed).
            let gap = if dashed { 6 } else { 0 };
            anno.label(c.label.clone()).legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (9, 0)], legend_style)
                    + PathElement::new(vec![(9 + gap, 0), (24, 0)], legend_style)
            });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font((FONT, 16))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .margin(12)
            .draw()
            .map_err(plot_error)?;
        root.present().map_err(plot_error)?;
    }
    Ok(buf)
}

/// [`render_cmc`] written to `path` as PNG, atomically.
pub fn write_cmc_png(path: &Path, title: &str, curves: &[Curve], size: (u32, u32)) -> Result<()> {
    let buf = render_cmc(title, curves, size)?;
    let img = image::RgbImage::from_raw(size.0, size.1, buf)
        .ok_or_else(|| Error::algorithm("plot", "buffer size mismatch"))?;
    crate::io::write_png(path, &img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_curves_are_errors_not_panics() {
        assert!(render_cmc("t", &[], DEFAULT_SIZE).is_err());
        let c = |n: usize| Curve {
            label: "x".into(),
            cmc: vec![0.5; n],
            colour: 0,
            dashed: false,
            bold: false,
        };
        assert!(render_cmc("t", &[c(3), c(4)], DEFAULT_SIZE).is_err());
        assert!(render_cmc("t", &[c(0)], DEFAULT_SIZE).is_err());
        assert!(render_cmc("t", &[c(3)], (10, 10)).is_err());
        // One rank is a valid (degenerate) CMC.
        assert!(render_cmc("t", &[c(1)], (300, 200)).is_ok());
    }
}
