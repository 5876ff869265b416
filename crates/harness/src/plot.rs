//! SVG line charts (plotters, no system fonts needed) for report curves.

use std::path::Path;

use plotters::prelude::*;

/// One curve.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`; non-positive or non-finite points are skipped on log axes.
    pub points: Vec<(f64, f64)>,
}

/// A labelled vertical or horizontal reference line.
#[derive(Debug, Clone)]
pub struct RefLine {
    /// Legend label.
    pub label: String,
    /// Position on its axis.
    pub at: f64,
}

/// A log-log line chart.
#[derive(Debug, Clone, Default)]
pub struct LogLogChart {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Curves.
    pub series: Vec<Series>,
    /// Vertical reference lines (x positions).
    pub vlines: Vec<RefLine>,
    /// Horizontal reference lines (y positions).
    pub hlines: Vec<RefLine>,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(127, 127, 127),
];

/// Write a rendered SVG to `path` atomically (under a temporary name, then renamed: a plot is
/// never seen half-written, and one that fails to render leaves the old file).
pub(crate) fn save_svg(path: &Path, text: &str) -> std::io::Result<()> {
    diffsoft::output::write_atomic(path, text.as_bytes())
}

/// Whether `v` can be placed on a log axis: positive, and within [1e-290, 1e290] so that the
/// axis's padding and its decade ticks stay finite (a value of 1e307 would push them past the
/// largest double, and the tick search would not end). Other values are left off the plot.
pub(crate) fn ok(v: f64) -> bool {
    (1e-290..=1e290).contains(&v)
}

/// Whether `v` can be placed on a linear axis (its padding stays finite).
fn linear_ok(v: f64) -> bool {
    v.abs() <= 1e290
}

/// Render `chart` to an SVG file.
pub fn write_svg(path: &Path, chart: &LogLogChart) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)?;
        }
    }
    let pts = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|(x, y)| ok(*x) && ok(*y));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    for h in chart.hlines.iter().filter(|h| ok(h.at)) {
        y0 = y0.min(h.at);
        y1 = y1.max(h.at);
    }
    if !(x1 > x0 && y1 > 0.0) {
        return Err(std::io::Error::other(format!("{}: nothing to plot", path.display())));
    }
    if y1 <= y0 {
        y1 = y0 * 10.0;
    }
    let mut text = String::new();
    let render = |text: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::with_string(text, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(&chart.title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0 / 2.0..y1 * 2.0).log_scale())?;
        c.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        for (k, s) in chart.series.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let p: Vec<(f64, f64)> = s.points.iter().copied().filter(|(x, y)| ok(*x) && ok(*y)).collect();
            c.draw_series(LineSeries::new(p.clone(), color.stroke_width(2)))?
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            c.draw_series(p.into_iter().map(|q| Circle::new(q, 2, color.filled())))?;
        }
        let n = chart.series.len();
        for (k, h) in chart.hlines.iter().filter(|h| ok(h.at)).enumerate() {
            let color = PALETTE[(n + k) % PALETTE.len()];
            c.draw_series(DashedLineSeries::new(
                vec![(x0, h.at), (x1, h.at)],
                6,
                4,
                color.stroke_width(1),
            ))?
            .label(h.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        let n = n + chart.hlines.len();
        for (k, v) in chart
            .vlines
            .iter()
            .filter(|v| ok(v.at) && v.at >= x0 && v.at <= x1)
            .enumerate()
        {
            let color = PALETTE[(n + k) % PALETTE.len()];
            c.draw_series(DashedLineSeries::new(
                vec![(v.at, y0 / 2.0), (v.at, y1 * 2.0)],
                6,
                4,
                color.stroke_width(1),
            ))?
            .label(v.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    render(&mut text).map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
    crate::plot::save_svg(path, &text)
}

/// A line chart with linear axes (time series).
#[derive(Debug, Clone, Default)]
pub struct LinearChart {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Curves (non-finite points are skipped).
    pub series: Vec<Series>,
}

/// Render a [`LinearChart`] to an SVG file.
pub fn write_linear_svg(path: &Path, chart: &LinearChart) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)?;
        }
    }
    let finite = |p: &&(f64, f64)| linear_ok(p.0) && linear_ok(p.1);
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in chart.series.iter().flat_map(|s| s.points.iter()).filter(finite) {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x1.partial_cmp(&x0) != Some(std::cmp::Ordering::Greater) || !y0.is_finite() {
        return Err(std::io::Error::other(format!("{}: nothing to plot", path.display())));
    }
    let pad = ((y1 - y0) * 0.05).max(1e-12 * y1.abs().max(1.0));
    let (y0, y1) = (y0 - pad, y1 + pad);
    let mut text = String::new();
    let render = |text: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::with_string(text, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(&chart.title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        c.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .draw()?;
        for (k, s) in chart.series.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            let p: Vec<(f64, f64)> = s.points.iter().filter(finite).copied().collect();
            c.draw_series(LineSeries::new(p, color.stroke_width(2)))?
                .label(s.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    render(&mut text).map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
    crate::plot::save_svg(path, &text)
}

/// One panel of a [`Snapshots`] figure: a title and 2-D points.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Panel title.
    pub title: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
}

/// A grid of point-cloud panels with shared axis ranges (e.g. front views of a body over time).
#[derive(Debug, Clone)]
pub struct Snapshots {
    /// Title.
    pub title: String,
    /// Rows of panels (each row the same length).
    pub rows: Vec<Vec<Panel>>,
    /// Shared x range.
    pub x_range: (f64, f64),
    /// Shared y range.
    pub y_range: (f64, f64),
}

/// Render [`Snapshots`] to an SVG file.
pub fn write_snapshots_svg(path: &Path, s: &Snapshots) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)?;
        }
    }
    let (nr, nc) = (s.rows.len(), s.rows.iter().map(Vec::len).max().unwrap_or(0));
    if nr == 0 || nc == 0 {
        return Err(std::io::Error::other(format!("{}: nothing to plot", path.display())));
    }
    let mut text = String::new();
    let render = |text: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let (w, h) = (200 * nc as u32, 230 * nr as u32 + 40);
        let root = SVGBackend::with_string(text, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let root = root.titled(&s.title, ("sans-serif", 20))?;
        let cells = root.split_evenly((nr, nc));
        for (k, cell) in cells.iter().enumerate() {
            let Some(panel) = s.rows.get(k / nc).and_then(|r| r.get(k % nc)) else {
                continue;
            };
            let mut c = ChartBuilder::on(cell)
                .caption(&panel.title, ("sans-serif", 13))
                .margin(4)
                .x_label_area_size(18)
                .y_label_area_size(28)
                .build_cartesian_2d(s.x_range.0..s.x_range.1, s.y_range.0..s.y_range.1)?;
            c.configure_mesh().x_labels(3).y_labels(3).disable_mesh().draw()?;
            let color = PALETTE[k / nc % PALETTE.len()];
            c.draw_series(
                panel
                    .points
                    .iter()
                    .filter(|p| p.0.is_finite() && p.1.is_finite())
                    .map(|&p| Circle::new(p, 1, color.filled())),
            )?;
        }
        root.present()?;
        Ok(())
    };
    render(&mut text).map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
    crate::plot::save_svg(path, &text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values past what a log axis can pad and tick (1e307, the largest double) are left off
    /// the plot instead of sending the tick search past the largest double, where it never
    /// ends; the file is written whole.
    #[test]
    fn huge_values_are_left_off_a_log_plot() {
        let path = std::env::temp_dir().join(format!("diffsoft-plot-huge-{}.svg", std::process::id()));
        let chart = LogLogChart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                label: "s".into(),
                points: vec![(1.0, 1e-3), (2.0, 1e307), (3.0, f64::MAX), (4.0, 1e-2)],
            }],
            vlines: Vec::new(),
            hlines: Vec::new(),
        };
        write_svg(&path, &chart).unwrap();
        assert!(std::fs::read_to_string(&path).unwrap().trim_end().ends_with("</svg>"));
        assert!(!ok(1e307) && !ok(f64::MAX) && ok(1e-3) && !ok(0.0) && !ok(f64::NAN));
        std::fs::remove_file(&path).unwrap();
    }
}
