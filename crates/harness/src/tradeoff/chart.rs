//! SVG scatter plots of a study: every setting as a point (colour: family; circle: iteration
//! cap, triangle: tolerance) on log axes of cost against error, with the Pareto front as a line.

use diffsoft::base::Choice;
use std::path::Path;

use plotters::prelude::*;

use super::assess::{forward_cost, gradient_cost};
use super::report::{Row, SceneTradeoff, Status};
use super::{Family, Knob};
use diffsoft::solver::Integrator;

const COLORS: [(Family, RGBColor); 6] = [
    (Family::Direct, RGBColor(31, 119, 180)),
    (Family::Split, RGBColor(214, 39, 40)),
    (Family::Chebyshev, RGBColor(44, 160, 44)),
    (Family::Certified, RGBColor(148, 103, 189)),
    (Family::Anderson, RGBColor(255, 127, 14)),
    (Family::Newton, RGBColor(140, 86, 75)),
];

struct Scatter<'a> {
    title: String,
    x_label: &'a str,
    y_label: &'a str,
    /// (family, integrator, is cap, x, y)
    points: Vec<(Family, Integrator, bool, f64, f64)>,
    front: Vec<(f64, f64)>,
}

use crate::plot::ok;

fn render(path: &Path, s: &Scatter<'_>) -> std::io::Result<()> {
    let pts: Vec<_> = s.points.iter().filter(|p| ok(p.3) && ok(p.4)).collect();
    if pts.is_empty() {
        return Err(std::io::Error::other(format!("{}: nothing to plot", path.display())));
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for p in &pts {
        x0 = x0.min(p.3);
        x1 = x1.max(p.3);
        y0 = y0.min(p.4);
        y1 = y1.max(p.4);
    }
    let mut text = String::new();
    let draw = |text: &mut String| -> Result<(), Box<dyn std::error::Error>> {
        let root = SVGBackend::with_string(text, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut c = ChartBuilder::on(&root)
            .caption(&s.title, ("sans-serif", 18))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d((x0 / 1.5..x1 * 1.5).log_scale(), (y0 / 3.0..y1 * 3.0).log_scale())?;
        c.configure_mesh()
            .x_desc(s.x_label)
            .y_desc(s.y_label)
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        // Implicit Euler filled, other integrators hollow, in the family's colour.
        for integrator in [Integrator::ImplicitEuler, Integrator::Bdf2] {
            for (family, color) in COLORS {
                let mine: Vec<_> = pts.iter().filter(|p| p.0 == family && p.1 == integrator).collect();
                if mine.is_empty() {
                    continue;
                }
                let filled = integrator == Integrator::ImplicitEuler;
                let style = if filled { color.filled() } else { color.stroke_width(2) };
                let name = if filled {
                    family.name().to_string()
                } else {
                    format!("{}/{}", integrator.name(), family.name())
                };
                c.draw_series(mine.iter().filter(|p| p.2).map(|p| Circle::new((p.3, p.4), 4, style)))?
                    .label(format!("{name} (circle: cap, triangle: tolerance)"))
                    .legend(move |(x, y)| Circle::new((x + 10, y), 4, style));
                c.draw_series(
                    mine.iter()
                        .filter(|p| !p.2)
                        .map(|p| TriangleMarker::new((p.3, p.4), 5, style)),
                )?;
            }
        }
        let front: Vec<(f64, f64)> = s.front.iter().copied().filter(|p| ok(p.0) && ok(p.1)).collect();
        c.draw_series(LineSeries::new(front, BLACK.stroke_width(2)))?
            .label("Pareto front")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
        c.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw(&mut text).map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
    crate::plot::save_svg(path, &text)
}

fn is_cap(r: &Row) -> bool {
    matches!(r.setting.knob, Knob::Cap(_))
}

/// Write `tradeoff_<slug>.svg` (trajectory error against the `h/R` reference) and, with
/// gradients, `tradeoff_<slug>_gradient.svg` (gradient error against the tight-tolerance gradient
/// at the same step: against the `h/R` one the time step dominates) into `dir`; returns the file
/// names written.
pub fn write(s: &SceneTradeoff, dir: &Path) -> std::io::Result<Vec<String>> {
    let [trajectory_name, gradient_name] = super::plot_names(&s.name);
    std::fs::create_dir_all(dir)?;
    let mut names = Vec::new();
    let time = s.pareto.time_meaning.as_str();
    let traj: Vec<(Family, Integrator, bool, f64, f64)> = s
        .rows
        .iter()
        .filter(|r| r.status == Status::Ran)
        .filter_map(|r| {
            Some((
                r.setting.family,
                r.setting.integrator,
                is_cap(r),
                forward_cost(&s.inputs, r)?,
                r.trajectory?.max_relative,
            ))
        })
        .collect();
    let name = trajectory_name;
    render(
        &diffsoft::output::own_file(dir, &name)?,
        &Scatter {
            title: format!(
                "{}: cost against trajectory error (h = {:e} s; one band per time step)",
                s.name, s.scene.dt
            ),
            x_label: time,
            y_label: "max vertex error / largest displacement (vs h/R reference)",
            points: traj,
            front: s.pareto.trajectory.iter().map(|p| (p.time, p.error)).collect(),
        },
    )?;
    names.push(name);
    if !s.pareto.gradient_solver.is_empty() {
        let grad: Vec<(Family, Integrator, bool, f64, f64)> = s
            .rows
            .iter()
            .filter(|r| r.status == Status::Ran)
            .filter_map(|r| {
                Some((
                    r.setting.family,
                    r.setting.integrator,
                    is_cap(r),
                    gradient_cost(&s.inputs, r)?,
                    r.gradient.solver_error?,
                ))
            })
            .collect();
        let name = gradient_name;
        render(
            &diffsoft::output::own_file(dir, &name)?,
            &Scatter {
                title: format!("{}: cost against gradient error at the same time step", s.name),
                x_label: "forward + backward cost per simulated second",
                y_label: "relative gradient error (vs the tight-tolerance gradient at the same step)",
                points: grad,
                front: s.pareto.gradient_solver.iter().map(|p| (p.time, p.error)).collect(),
            },
        )?;
        names.push(name);
    }
    Ok(names)
}
