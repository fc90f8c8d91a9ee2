//! The Pareto charts of `izb report`: one point per method and setting,
//! time on a log x axis, four error metrics on y, the front of
//! undominated points joined; PNG and SVG.

use super::Point;
use crate::metrics::Metrics;
use crate::output::{write_atomically, write_png};
use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// The y axes of a Pareto chart: the metric, label.
type Panel = (fn(&Metrics) -> f64, &'static str);
const PANELS: [Panel; 4] = [
    (|m| m.mae, "MAE (all pixels)"),
    (|m| m.smooth_penumbra_mae, "smooth-penumbra MAE"),
    (|m| m.edge_mae, "edge MAE"),
    (|m| m.percent_over_one_sample, "% pixels wrong by > 1/32"),
];

fn register_font() {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        // DejaVu Sans, embedded: no system font libraries needed (README, Precision).
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .unwrap_or_else(|_| panic!("the embedded DejaVu Sans font is valid"));
    });
}

/// Colour and marker kind of a method.
fn style_of(p: &Point) -> (RGBColor, &'static str) {
    let m = p.method.as_str();
    match p.family.as_str() {
        "izb" if m.starts_with("izb1") => (RGBColor(120, 170, 230), "IZB 1 spp"),
        "izb" => (RGBColor(20, 60, 180), "IZB 32 spp"),
        "ray-traced" => (RGBColor(30, 150, 60), "ray-traced 32 samples"),
        "shadow-volume" => (RGBColor(90, 90, 90), "shadow volumes (1 spp)"),
        _ if m.contains("msm") => (RGBColor(0, 150, 150), "moment SM (4 moments)"),
        _ if m.contains("vsm") => (RGBColor(110, 180, 170), "variance SM"),
        _ if m.contains("esm") => (RGBColor(60, 120, 160), "exponential SM"),
        _ if m.starts_with("pcss") => (RGBColor(200, 110, 150), "PCSS"),
        _ if m.starts_with("csm") => (RGBColor(140, 90, 40), "cascaded SM + PCF"),
        _ if m.starts_with("pcf5") => (RGBColor(150, 60, 170), "SM 5x5 PCF"),
        _ if m.starts_with("pcf") => (RGBColor(240, 140, 20), "SM 3x3 PCF"),
        _ => (RGBColor(210, 40, 40), "SM 1 tap"),
    }
}

/// Indices of the points not dominated in (time, metric), fastest first.
fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut best = f64::INFINITY;
    order
        .into_iter()
        .filter(|&i| {
            let keep = points[i].1 < best;
            best = best.min(points[i].1);
            keep
        })
        .collect()
}

/// Draws the 2×2 Pareto panels of `points` onto `area`.
fn draw_chart<DB: DrawingBackend>(
    area: DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    points: &[Point],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing the chart: {e:?}");
    area.fill(&WHITE).map_err(err)?;
    let area = area.titled(title, ("sans-serif", 22)).map_err(err)?;
    let (t_lo, t_hi) = points.iter().fold((f64::INFINITY, 0.0f64), |a, p| {
        (a.0.min(p.seconds), a.1.max(p.seconds))
    });
    let (t_lo, t_hi) = (t_lo.max(1e-9) / 1.6, t_hi.max(1e-9) * 4.0);
    for ((metric, label), panel) in PANELS.iter().zip(area.split_evenly((2, 2))) {
        let ys: Vec<f64> = points.iter().map(|p| metric(&p.metrics)).collect();
        let y_hi = ys
            .iter()
            .copied()
            .filter(|y| y.is_finite())
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1.15;
        let mut chart = ChartBuilder::on(&panel)
            .caption(*label, ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(56)
            .build_cartesian_2d((t_lo..t_hi).log_scale(), 0.0..y_hi)
            .map_err(err)?;
        let y_decimals = axis_decimals(y_hi / 5.0);
        chart
            .configure_mesh()
            .x_desc("shadow seconds (log)")
            .x_label_formatter(&log_tick_label)
            .y_label_formatter(&|y| format!("{y:.y_decimals$}"))
            .label_style(("sans-serif", 11))
            .draw()
            .map_err(err)?;
        let xy: Vec<(f64, f64)> = points
            .iter()
            .zip(&ys)
            .map(|(p, &y)| (p.seconds, y))
            .collect();
        let finite: Vec<(f64, f64)> = xy.iter().copied().filter(|(_, y)| y.is_finite()).collect();
        let front: Vec<(f64, f64)> = pareto_front(&finite)
            .into_iter()
            .map(|i| finite[i])
            .collect();
        chart
            .draw_series(LineSeries::new(
                front,
                RGBColor(150, 150, 150).stroke_width(1),
            ))
            .map_err(err)?;
        for (p, &(x, y)) in points.iter().zip(&xy) {
            if !y.is_finite() {
                continue;
            }
            let (colour, _) = style_of(p);
            let style = colour.filled();
            let marker: DynElement<DB, (f64, f64)> = match p.family.as_str() {
                "shadow-map" => TriangleMarker::new((x, y), 5, style).into_dyn(),
                "ray-traced" | "shadow-volume" => {
                    Cross::new((x, y), 5, colour.stroke_width(2)).into_dyn()
                }
                _ => Circle::new((x, y), 5, style).into_dyn(),
            };
            chart.plotting_area().draw(&marker).map_err(err)?;
            // The label beside the marker, not under it.
            let label = EmptyElement::at((x, y))
                + Text::new(
                    p.method.clone(),
                    (7, -4),
                    ("sans-serif", 10).into_font().color(&BLACK),
                );
            chart.plotting_area().draw(&label).map_err(err)?;
        }
    }
    Ok(())
}

/// A log axis's tick label at 1, 2 and 5 times a power of ten only (a label
/// at every multiple crowded the axis).
fn log_tick_label(x: &f64) -> String {
    if !(x.is_finite() && *x > 0.0) {
        return String::new();
    }
    let decade = x.log10().floor();
    let mantissa = x / 10f64.powf(decade);
    let near = |m: f64| (mantissa - m).abs() < 1e-6 * m;
    if near(1.0) || near(2.0) || near(5.0) || near(10.0) {
        format!("{x:.*}", axis_decimals(*x))
    } else {
        String::new()
    }
}

/// Decimals that show a step of `step` (edge MAE's axis read "0.0" before).
fn axis_decimals(step: f64) -> usize {
    if step.is_finite() && step > 0.0 {
        (-step.log10()).ceil().clamp(0.0, 9.0) as usize
    } else {
        1
    }
}

/// Writes the Pareto chart of `points` as `<stem>.png` and `<stem>.svg`.
pub(super) fn write_chart(
    dir: &Path,
    stem: &str,
    title: &str,
    points: &[Point],
) -> Result<Vec<PathBuf>> {
    register_font();
    let (w, h) = (1200u32, 900u32);
    let svg_path = dir.join(format!("{stem}.svg"));
    let mut svg = String::new();
    draw_chart(
        SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area(),
        title,
        points,
    )?;
    write_atomically(&svg_path, |tmp| Ok(std::fs::write(tmp, &svg)?))?;
    let png_path = dir.join(format!("{stem}.png"));
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    draw_chart(
        BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area(),
        title,
        points,
    )?;
    let img = image::RgbImage::from_raw(w, h, rgb).context("chart buffer size")?;
    write_png(&png_path, &img)?;
    Ok(vec![png_path, svg_path])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let pts = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0), (0.5, 9.0)];
        assert_eq!(pareto_front(&pts), vec![4, 0, 1, 3]);
    }

    #[test]
    fn axis_labels_are_sparse_and_precise() {
        let ticks = [0.001, 0.002, 0.003, 0.005, 0.01, 0.2, 3.0];
        let labels: Vec<String> = ticks.iter().map(log_tick_label).collect();
        assert_eq!(labels, ["0.001", "0.002", "", "0.005", "0.01", "0.2", ""]);
        assert_eq!([0.04, 0.2, 5.0].map(axis_decimals), [2, 1, 0]);
    }
}
