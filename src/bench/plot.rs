//! The bench's plots as SVG (plotters, no system fonts needed):
//!
//! - [`pareto`]: error against frame time for one scene and view, one curve per mode through
//!   its quality settings. Points down and to the left are better; the reference (error 0) is
//!   left out of this log-log plot.
//! - [`scaling`]: frame time against tet count over the scenes seen from outside, one curve
//!   per configuration: how cost grows with work.
//!
//! Each plot names the adapter, the machine and the date at its foot.

use std::path::Path;

use plotters::prelude::*;

use super::{BenchError, Environment, Row};

const SIZE: (u32, u32) = (820, 560);

/// Distinct, readable series colours.
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Smallest error drawn: exact results (rmse 0) would have no place on a log axis.
const MIN_ERROR: f64 = 1e-9;

type Series = Vec<(String, Vec<(f64, f64)>)>;

/// Error (rmse against the exact reference) against median frame time for `scene` seen from
/// `view`, one curve per mode; written to `path`.
pub fn pareto(
    path: &Path,
    rows: &[Row],
    scene: &str,
    view: &str,
    env: &Environment,
) -> Result<(), BenchError> {
    let mut series: Series = Vec::new();
    for r in rows
        .iter()
        .filter(|r| r.scene == scene && r.view == view && r.mode != "reference")
    {
        let point = (r.median_ms, r.error.rmse.max(MIN_ERROR));
        match series.iter_mut().find(|(m, _)| m == r.mode) {
            Some((_, pts)) => pts.push(point),
            None => series.push((r.mode.to_string(), vec![point])),
        }
    }
    let size = rows
        .iter()
        .find(|r| r.scene == scene)
        .map_or(String::new(), |r| format!(", {}x{}", r.width, r.height));
    draw(
        path,
        &format!("{scene}, {view} view{size}: error against time"),
        ("median frame time (ms)", "rmse against the exact reference"),
        series,
        env,
    )
}

/// Median frame time against tet count over the rows seen from outside, one curve per mode
/// and setting; written to `path`.
pub fn scaling(path: &Path, rows: &[Row], env: &Environment) -> Result<(), BenchError> {
    let mut series: Series = Vec::new();
    for r in rows.iter().filter(|r| r.view == "outside") {
        let name = format!("{} {}", r.mode, r.setting);
        let point = (r.tets as f64, r.median_ms);
        match series.iter_mut().find(|(m, _)| *m == name) {
            Some((_, pts)) => pts.push(point),
            None => series.push((name, vec![point])),
        }
    }
    draw(
        path,
        "frame time against tet count (outside views)",
        ("tets", "median frame time (ms)"),
        series,
        env,
    )
}

/// A log-log chart of `series` (each sorted by x and drawn as a line through its points).
fn draw(
    path: &Path,
    title: &str,
    (x_desc, y_desc): (&str, &str),
    mut series: Series,
    env: &Environment,
) -> Result<(), BenchError> {
    let fail = |e: &dyn std::fmt::Display| BenchError::Plot {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    for (_, pts) in &mut series {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let all = || series.iter().flat_map(|(_, p)| p.iter());
    let range = |f: fn(&(f64, f64)) -> f64| {
        let (lo, hi) = all().map(f).fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if lo.is_finite() && lo > 0.0 {
            (lo / 1.5, hi * 1.5)
        } else {
            (1.0, 10.0)
        }
    };
    let (x, y) = (range(|p| p.0), range(|p| p.1));

    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let foot = format!("{}; {}; {}", env.adapter, env.machine, env.date);
    root.draw(&Text::new(
        foot,
        (10, SIZE.1 as i32 - 16),
        ("sans-serif", 12).into_font(),
    ))
    .map_err(|e| fail(&e))?;
    let (chart_area, _) = root.split_vertically(SIZE.1 - 24);
    let mut chart = ChartBuilder::on(&chart_area)
        .caption(title, ("sans-serif", 18).into_font())
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d((x.0..x.1).log_scale(), (y.0..y.1).log_scale())
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .draw()
        .map_err(|e| fail(&e))?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(2)))
            .map_err(|e| fail(&e))?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))
            .map_err(|e| fail(&e))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}

/// A compact axis label: integers as such, other values in short scientific notation.
fn tick(v: &f64) -> String {
    if *v >= 1.0 && *v < 1e6 && (v - v.round()).abs() < 1e-6 * v {
        format!("{:.0}", v.round())
    } else {
        format!("{v:.0e}")
    }
}

#[cfg(test)]
mod tests {
    use super::tick;

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(&100.0), "100");
        assert_eq!(tick(&99.99999999999999), "100");
        assert_eq!(tick(&9.999999999999999e-6), "1e-5");
        assert_eq!(tick(&2e7), "2e7");
    }
}
