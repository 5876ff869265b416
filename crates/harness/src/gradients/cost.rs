//! Gradient accuracy against the forward solve's cost (iterations and time), and its plot.

use std::path::Path;

use anyhow::Result;
use serde::Serialize;

use crate::plot::{self, LogLogChart, Series};
use diffsoft::diff::{self, DiffError, DiffStats, Mode, Options, Param};
use diffsoft::solver::Settings;
use diffsoft::testing::{Case, Group};

/// Gradient error against a converged reference for one setting.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct CostPoint {
    /// Mode.
    pub mode: Mode,
    /// Local-global iterations per step (tolerance 0).
    pub iterations: usize,
    /// `max_k |g_k - g_ref_k| / max_k |g_ref_k|` over the checked scalar derivatives (1).
    pub gradient_error: f64,
    /// Loss error against the reference (m: the loss is a centre-of-mass coordinate).
    pub loss_error: f64,
    /// Forward + backward wall time (ms).
    pub wall_ms: f64,
    /// Backward alone (ms).
    pub backward_ms: f64,
}

/// Gradient accuracy against cost for one case.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct CostReport {
    /// Case.
    pub case: String,
    /// Parameters whose derivatives are compared.
    pub parameters: Vec<String>,
    /// Reference: unrolled gradient of a forward converged to relative change 1e-13 (loss unit per
    /// parameter unit, in the order of `parameters`).
    pub reference: Vec<f64>,
    /// Reference settings: iteration cap and tolerance.
    pub reference_iterations: usize,
    /// Points.
    pub points: Vec<CostPoint>,
}

/// Sweep the iteration cap for both modes and compare with the converged reference.
pub fn accuracy_vs_cost(case: &Case, caps: &[usize]) -> Result<CostReport, DiffError> {
    let params: Vec<Param> = case
        .groups
        .iter()
        .filter_map(|g| match g {
            Group::Scalar(p) => Some(*p),
            _ => None,
        })
        .collect();
    let grad = |settings: &Settings, mode: Mode| -> Result<(f64, Vec<f64>, DiffStats), DiffError> {
        let g = diff::gradient(
            &case.model,
            settings,
            case.steps,
            &case.controls,
            case.loss.as_ref(),
            Options::mode(mode),
        )?;
        Ok((
            g.loss,
            params.iter().map(|p| p.derivative(&case.model, &g)).collect(),
            g.stats,
        ))
    };
    let mut reference_settings = case.settings.clone();
    reference_settings.tolerance = 1e-13;
    reference_settings.max_iterations = 2000;
    let (l_ref, g_ref, _) = grad(&reference_settings, Mode::Unrolled)?;
    let scale = g_ref.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    let mut points = Vec::new();
    for &cap in caps {
        for mode in [Mode::Unrolled, Mode::Implicit] {
            let mut s = case.settings.clone();
            s.tolerance = 0.0;
            s.max_iterations = cap;
            let (l, g, st) = grad(&s, mode)?;
            let err = g.iter().zip(&g_ref).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max) / scale;
            points.push(CostPoint {
                mode,
                iterations: cap,
                gradient_error: err,
                loss_error: (l - l_ref).abs() / l_ref.abs().max(f64::MIN_POSITIVE),
                wall_ms: st.forward_ms + st.backward_ms,
                backward_ms: st.backward_ms,
            });
        }
    }
    Ok(CostReport {
        case: case.name.clone(),
        parameters: params.iter().map(|p| p.to_string()).collect(),
        reference: g_ref,
        reference_iterations: reference_settings.max_iterations,
        points,
    })
}

pub(super) fn write_cost_svg(path: &Path, costs: &[CostReport]) -> Result<()> {
    let mut series = Vec::new();
    for c in costs {
        for mode in [Mode::Unrolled, Mode::Implicit] {
            series.push(Series {
                label: format!("{} {:?}", c.case, mode).to_lowercase(),
                points: c
                    .points
                    .iter()
                    .filter(|p| p.mode == mode)
                    .map(|p| (p.wall_ms, p.gradient_error))
                    .collect(),
            });
        }
    }
    plot::write_svg(
        path,
        &LogLogChart {
            title: "Gradient error vs cost (iteration cap 1..100)".into(),
            x_label: "forward + backward wall time (ms)".into(),
            y_label: "relative gradient error vs converged reference".into(),
            series,
            vlines: Vec::new(),
            hlines: Vec::new(),
        },
    )?;
    Ok(())
}
