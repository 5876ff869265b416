//! Coulomb friction: a capstan. A cloth strip hangs over a fixed horizontal cylinder, half a turn
//! in contact, its two ends hanging free; it sticks while the heavier end is shorter than the
//! Euler-Eytelwein threshold and slides beyond it.
//!
//! The loads are the hanging ends' own weights, so the strip's weight on the cylinder enters
//! too: for a belt of weight `w` per length on the upper half of a cylinder of radius `R` with
//! friction `mu`, limiting equilibrium (`dT/dphi = mu (T + w R cos phi) - w R sin phi`, `phi`
//! from the top) gives the threshold tension `T2 = e^(mu pi) T1 + w R b (e^(mu pi) + 1)`,
//! `b = 2 mu / (1 + mu^2)` ([`closed::heavy_capstan_limit`]; docs/validation.md derives it), with `T = w L` for a hanging length `L`. The weightless capstan is the limit `w R -> 0`.
//!
//! The strip starts draped and at rest, unstretched; its stretching stiffness makes the elastic
//! stretch small (below 1e-3), and implicit Euler damps the oscillations of the release. The
//! verdict reads the slip, how far the light end rises, over the second half of the run.

use std::time::Instant;

use nalgebra::Vector3;

use super::case::{Case, Spec};
use super::closed;
use diffsoft::cloth::ClothSpec;
use diffsoft::contact::{Obstacle, TriMeshObstacle};
use diffsoft::mesh::surface::TriSurface;
use diffsoft::model::ModelBuilder;
use diffsoft::solver::{CertifyPolicy, Settings, Simulator, SolverKind};

/// Coulomb coefficient of the cylinder.
const MU: f64 = 0.3;
/// Radius of the cylinder's contact surface (its facets' inscribed radius plus the contact
/// thickness; m).
const RADIUS: f64 = 0.05;
/// Contact thickness of the cylinder (m).
const THICKNESS: f64 = 1e-3;
/// Facets round the cylinder.
const FACETS: usize = 128;
/// Width of the strip (m).
const WIDTH: f64 = 0.04;
/// Cells across the strip.
const ACROSS: usize = 2;
/// Length of a cell along the strip (m).
const CELL: f64 = 0.01;
/// Hanging length of the lighter end (m).
const SHORT: f64 = 0.2;
/// Area density (kg/m^2) and stretching stiffness (N/m) of the strip.
const AREA_DENSITY: f64 = 0.1;
const STRETCHING: f64 = 2000.0;
/// Gravity (m/s^2).
const G: f64 = 9.81;
/// Time step and run length (s).
const DT: f64 = 0.005;
const DURATION: f64 = 0.8;
/// The strip sticks when its light end rises less than this over the run's second half (m):
/// a twentieth of a cell, many times the elastic stretch of the light end.
const STICK_SLIP: f64 = 5e-4;

/// The path of the draped strip at arclength `s` (the cylinder's axis is `z`, its top at
/// `y = RADIUS`): down the left side, over the top, down the right side.
fn draped(s: f64, short: f64) -> Vector3<f64> {
    let arc = std::f64::consts::PI * RADIUS;
    if s < short {
        Vector3::new(-RADIUS, -(short - s), 0.0)
    } else if s < short + arc {
        let phi = -std::f64::consts::FRAC_PI_2 + (s - short) / RADIUS;
        Vector3::new(RADIUS * phi.sin(), RADIUS * phi.cos(), 0.0)
    } else {
        Vector3::new(RADIUS, -(s - short - arc), 0.0)
    }
}

/// The strip, flat (its rest shape: length along `x`, width along `z`) and draped (its start),
/// and the light end's vertex on the centre line.
fn strip(long: f64) -> (TriSurface, Vec<Vector3<f64>>, usize) {
    let length = SHORT + std::f64::consts::PI * RADIUS + long;
    let along = (length / CELL).round() as usize;
    let ds = length / along as f64;
    let id = |i: usize, j: usize| j * (along + 1) + i;
    let (mut flat, mut start) = (Vec::new(), Vec::new());
    for j in 0..=ACROSS {
        let z = WIDTH * (j as f64 / ACROSS as f64 - 0.5);
        for i in 0..=along {
            let s = i as f64 * ds;
            flat.push(Vector3::new(s, 0.0, z));
            start.push(draped(s, SHORT) + Vector3::new(0.0, 0.0, z));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ACROSS {
        for i in 0..along {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    // The light end's vertex on the centre line.
    (
        TriSurface {
            vertices: flat,
            triangles,
        },
        start,
        id(0, ACROSS / 2),
    )
}

/// The cylinder: an open tube of [`FACETS`] facets whose inscribed radius is
/// `RADIUS - THICKNESS`, twice the strip's width long.
fn cylinder() -> Result<TriMeshObstacle, String> {
    let r = (RADIUS - THICKNESS) / (std::f64::consts::PI / FACETS as f64).cos();
    let mut vertices = Vec::new();
    for k in 0..FACETS {
        let a = 2.0 * std::f64::consts::PI * k as f64 / FACETS as f64;
        for z in [-WIDTH, WIDTH] {
            vertices.push(Vector3::new(r * a.sin(), r * a.cos(), z));
        }
    }
    let mut triangles = Vec::new();
    for k in 0..FACETS {
        let (a, b) = (2 * k, 2 * ((k + 1) % FACETS));
        triangles.push([a, b, b + 1]);
        triangles.push([a, b + 1, a + 1]);
    }
    TriMeshObstacle::new(vertices, triangles).map_err(|e| e.to_string())
}

/// One run: the slip (how far the light end rose) over the whole run and over its second half
/// (m), the largest elastic stretch, and the steps whose contact solve stopped unconverged.
fn run(long: f64) -> Result<(f64, f64, f64, usize), String> {
    let (surface, start, end) = strip(long);
    let n = start.len();
    let cloth = ClothSpec::new("strip", surface, STRETCHING, 0.0, AREA_DENSITY);
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -G, 0.0))
        .cloth(cloth)
        .obstacle(Obstacle::new("cylinder", cylinder()?, MU, THICKNESS))
        .build()
        .map_err(|e| e.to_string())?;
    let settings = Settings {
        dt: DT,
        solver: SolverKind::Direct,
        certify: CertifyPolicy::Off,
        tolerance: 1e-7,
        max_iterations: 5000,
        ..Settings::default()
    };
    let mut sim = Simulator::new(model, settings).map_err(|e| e.to_string())?;
    sim.set_state(start.clone(), vec![Vector3::zeros(); n])
        .map_err(|e| e.to_string())?;
    let steps = (DURATION / DT).round() as usize;
    let (mut half, mut unconverged, mut stretch) = (0.0, 0, 0.0f64);
    for k in 0..steps {
        let st = sim.step().map_err(|e| e.to_string())?;
        unconverged += usize::from(!st.converged);
        if k + 1 == steps / 2 {
            half = sim.state().q[end].y;
        }
        let cloth = sim.model().cloth().ok_or("no cloth")?;
        stretch = stretch.max(cloth.stretch_range(&sim.state().q).0 - 1.0);
    }
    let last = sim.state().q[end].y;
    Ok((last - start[end].y, last - half, stretch, unconverged))
}

/// The capstan cases: the heavier end `0.9`, `0.95`, `1.05` and `1.1` times the threshold
/// length (`mu = 0.3`, half a turn), as `(variant, ratio)`; the fast subset runs the two at 5%.
pub fn variants(fast: bool) -> Vec<(&'static str, f64)> {
    let all = [
        ("sticks", 0.9),
        ("sticks_near", 0.95),
        ("slides_near", 1.05),
        ("slides", 1.1),
    ];
    all.into_iter().filter(|(v, _)| !fast || v.ends_with("_near")).collect()
}

/// The capstan case `variant`: the heavier end `ratio` times the threshold length.
pub fn case(variant: &str, ratio: f64) -> Case {
    let w = AREA_DENSITY * WIDTH * G;
    let threshold = closed::heavy_capstan_limit(w * SHORT, MU, w, RADIUS) / w;
    let t0 = Instant::now();
    let long = ratio * threshold;
    let result = run(long);
    let mut spec = Spec::new("capstan", variant, "cloth", "mu");
    spec.setup = format!(
        "cloth strip {WIDTH} m wide ({AREA_DENSITY} kg/m^2, stretching {STRETCHING} N/m, no bending \
         stiffness, cells of {CELL} m along and {:.3} m across) over a fixed horizontal cylinder of radius \
         {RADIUS} m ({FACETS} facets, contact thickness {THICKNESS} m, mu = {MU}), half a turn in contact; \
         the ends hang {SHORT} m and {long:.4} m ({ratio} x the threshold {threshold:.4} m); released \
         draped and at rest, implicit Euler at {DT} s for {DURATION} s with the direct solver",
        WIDTH / ACROSS as f64
    );
    spec.quantity = "slip (rise of the light end) over the run's second half (m)".into();
    spec.formula = format!(
        "{}: L2 {} e^(mu pi) L1 + R b (e^(mu pi) + 1), b = 2 mu / (1 + mu^2)",
        if ratio < 1.0 { "sticks" } else { "slides" },
        if ratio < 1.0 { "<" } else { ">" }
    );
    spec.source = "Euler 1762, Eytelwein 1808: the capstan equation, with the belt's own weight \
                   (limiting equilibrium of a heavy belt on a cylinder, docs/validation.md)"
        .into();
    spec.tolerance = STICK_SLIP;
    spec.tolerance_basis = "a stick/slip verdict at 5% and 10% either side of the threshold: sticking means the \
                            light end rises less than a twentieth of a cell over the second half of the run \
                            (the elastic stretch moves it by about 1e-5 m)"
        .into();
    match result {
        Ok((_, _, _, bad)) if bad > 0 => spec.not_run(&format!("{bad} steps stopped their contact solve unconverged")),
        Ok((total, late, stretch, _)) => {
            let sticks = late.abs() < STICK_SLIP;
            let holds = sticks == (ratio < 1.0);
            // A verdict, not a distance: the error is 0 when the strip does what the threshold
            // says and 1 when not; the measured value is the late slip against the stick bound.
            spec.measured(STICK_SLIP, late.abs(), if holds { 0.0 } else { 1.0 }, |_| {
                format!(
                    "the light end rose {:.3e} m in all, {:.3e} m over the second half: it {}",
                    total.abs(),
                    late.abs(),
                    if sticks { "sticks" } else { "slides" }
                )
            })
            .with(&[
                ("slip_m", total.abs()),
                ("late_slip_m", late.abs()),
                ("threshold_length_m", threshold),
                ("hanging_length_m", long),
                ("max_stretch", stretch),
            ])
            .timed(t0.elapsed().as_secs_f64())
        }
        Err(e) => spec.not_run(&e),
    }
}
