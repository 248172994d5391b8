//! The SVG picture of a run (plotters, SVG backend, line series only: no fonts).

use std::f64::consts::TAU;
use std::path::Path;

use nalgebra::Vector2;

use super::error::SimError;
use super::types::SimResult;

/// Draws the horizontal paths, the standoff circle and the obstacles as an SVG (plotters), with
/// at most `max_points` points per track.
pub fn plot_svg(path: &Path, result: &SimResult, max_points: usize) -> Result<(), SimError> {
    use plotters::prelude::*;
    let perr = |e: &dyn std::fmt::Display| SimError::Plot(e.to_string());
    // Bounds over every drawn point.
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    let mut grow = |x: f64, y: f64| {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    };
    for tr in &result.trajectories {
        for s in &tr.samples {
            grow(s.pos[0], s.pos[1]);
        }
    }
    let circles: Vec<(Vector2<f64>, f64, bool)> = result
        .obstacles
        .iter()
        .map(|o| (o.center, o.radius, true))
        .chain(result.circle.map(|(c, r)| (c, r, false)))
        .collect();
    for (c, r, _) in &circles {
        grow(c.x - r, c.y - r);
        grow(c.x + r, c.y + r);
    }
    if !(x0.is_finite() && y0.is_finite()) {
        return Err(SimError::Plot("nothing to draw".into()));
    }
    // Equal axes.
    let span = (x1 - x0).max(y1 - y0) * 1.05 + 1.0;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (x0, x1, y0, y1) = (
        cx - span / 2.0,
        cx + span / 2.0,
        cy - span / 2.0,
        cy + span / 2.0,
    );
    let root = SVGBackend::new(path, (640, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| perr(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| perr(&e))?;
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
    ];
    let mut uav_i = 0;
    for tr in &result.trajectories {
        let stride = tr.samples.len().div_ceil(max_points.max(2)).max(1);
        let pts: Vec<(f64, f64)> = tr
            .samples
            .iter()
            .step_by(stride)
            .chain(tr.samples.last())
            .map(|s| (s.pos[0], s.pos[1]))
            .collect();
        let style = match tr.kind {
            "target" => BLACK.stroke_width(2),
            "estimate" => RGBColor(150, 150, 150).stroke_width(1),
            _ => {
                uav_i += 1;
                palette[(uav_i - 1) % palette.len()].stroke_width(2)
            }
        };
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(|e| perr(&e))?;
    }
    for (c, r, obstacle) in circles {
        let pts: Vec<(f64, f64)> = (0..=120)
            .map(|k| {
                let a = TAU * k as f64 / 120.0;
                (c.x + r * a.cos(), c.y + r * a.sin())
            })
            .collect();
        let style = if obstacle {
            RGBColor(120, 60, 20).stroke_width(3)
        } else {
            RGBColor(255, 127, 14).stroke_width(1)
        };
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(|e| perr(&e))?;
    }
    root.present().map_err(|e| perr(&e))?;
    Ok(())
}
