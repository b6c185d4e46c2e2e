//! Stacked time-series panels written as SVG: what a person would rather look at than read.

use anyhow::{Result, anyhow};
#[cfg(feature = "svg")]
use plotters::prelude::*;
use std::path::Path;

/// One line of a panel.
pub struct Series<'a> {
    /// Legend text, with the unit.
    pub label: &'a str,
    /// The values, one per time sample.
    pub values: &'a [f64],
}

/// A panel: a y-axis title and its lines over the shared time axis.
pub struct Panel<'a> {
    /// Y-axis title, with the unit.
    pub title: &'a str,
    /// The lines of this panel.
    pub series: Vec<Series<'a>>,
}

#[cfg(feature = "svg")]
const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

/// Largest number of points drawn per line; longer series are decimated (min/max kept).
#[cfg(feature = "svg")]
const MAX_POINTS: usize = 4000;

/// Writes `panels` stacked over the time axis `t_s` to an SVG file.
#[cfg(feature = "svg")]
pub fn write_svg(path: &Path, caption: &str, t_s: &[f64], panels: &[Panel<'_>]) -> Result<()> {
    let err = |e: &dyn std::fmt::Display| anyhow!("{}: cannot draw the plot: {e}", path.display());
    match path.extension().and_then(|e| e.to_str()) {
        Some("svg") => {}
        _ => return Err(anyhow!("{}: the plot must be an .svg file", path.display())),
    }
    let height = 40 + 260 * panels.len() as u32;
    let root = SVGBackend::new(path, (1000, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(caption, ("sans-serif", 20))
        .map_err(|e| err(&e))?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    let (t0, t1) = span(t_s);
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let (lo, hi) = panel
            .series
            .iter()
            .map(|s| span(s.values))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (c, d)| {
                (a.min(c), b.max(d))
            });
        let pad = ((hi - lo) * 0.05).max(1e-9);
        let mut chart = ChartBuilder::on(area)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("t (s)")
            .y_desc(panel.title)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| err(&e))?;
        for (k, s) in panel.series.iter().enumerate() {
            let colour = COLOURS.get(k % COLOURS.len()).copied().unwrap_or(BLACK);
            let points = decimate(t_s, s.values);
            chart
                .draw_series(LineSeries::new(points, colour.stroke_width(1)))
                .map_err(|e| err(&e))?
                .label(s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Without the feature `svg` (a build for the browser, which draws its own plots): an error
/// that says so.
#[cfg(not(feature = "svg"))]
pub fn write_svg(path: &Path, _caption: &str, _t_s: &[f64], _panels: &[Panel<'_>]) -> Result<()> {
    Err(anyhow!(
        "{}: this build draws no plots (pmsm-cli's feature `svg` is off)",
        path.display()
    ))
}

/// Min and max of finite values, widened when flat.
#[cfg(feature = "svg")]
fn span(v: &[f64]) -> (f64, f64) {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        (0.0, 1.0)
    } else if hi - lo < 1e-12 {
        (lo - 0.5, hi + 0.5)
    } else {
        (lo, hi)
    }
}

/// At most `MAX_POINTS` points that keep each bucket's minimum and maximum, in time order;
/// non-finite values (a series' gaps) are left out.
#[cfg(feature = "svg")]
fn decimate(t: &[f64], v: &[f64]) -> Vec<(f64, f64)> {
    let (t, v): (Vec<f64>, Vec<f64>) = t
        .iter()
        .zip(v)
        .filter(|(_, b)| b.is_finite())
        .map(|(&a, &b)| (a, b))
        .unzip();
    let n = t.len();
    let bucket = n.div_ceil(MAX_POINTS / 2).max(1);
    if bucket == 1 {
        return t.iter().zip(&v).map(|(&a, &b)| (a, b)).collect();
    }
    let mut out = Vec::with_capacity(MAX_POINTS + 2);
    for (tc, vc) in t.chunks(bucket).zip(v.chunks(bucket)) {
        let (mut imin, mut imax) = (0, 0);
        for (i, x) in vc.iter().enumerate() {
            if *x < vc[imin] {
                imin = i;
            }
            if *x > vc[imax] {
                imax = i;
            }
        }
        let (a, b) = if imin <= imax {
            (imin, imax)
        } else {
            (imax, imin)
        };
        out.push((tc[a], vc[a]));
        out.push((tc[b], vc[b]));
    }
    out
}
