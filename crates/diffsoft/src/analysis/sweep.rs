//! `rho(G19)` and `rho(G21)` over a log-spaced range of time steps.

use rayon::prelude::*;
use serde::Serialize;

use super::spectral::EigenMethod;
use super::{rho_split, AnalysisError, IterationSystem, Spectrum};

/// One time step of a sweep.
#[derive(Debug, Clone, Copy, Serialize, schemars::JsonSchema)]
pub struct SweepPoint {
    /// Time step (s).
    pub dt: f64,
    /// `rho(G19)` (1).
    pub rho_plain: f64,
    /// `rho(G21)` (1).
    pub rho_split: f64,
}

/// `count` log-spaced values from `lo` to `hi` inclusive.
///
/// ```
/// use diffsoft::analysis::sweep::log_space;
///
/// let dts = log_space(1e-4, 1e-1, 4);
/// assert_eq!(dts.len(), 4);
/// assert!((dts[1] - 1e-3).abs() < 1e-15 && (dts[3] - 1e-1).abs() < 1e-15);
/// assert_eq!(log_space(0.5, 2.0, 1), vec![0.5]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn log_space(lo: f64, hi: f64, count: usize) -> Vec<f64> {
    if count == 1 {
        return vec![lo];
    }
    let (a, b) = (lo.ln(), hi.ln());
    (0..count)
        .map(|i| (a + (b - a) * i as f64 / (count - 1) as f64).exp())
        .collect()
}

/// Spectral radii of both schemes at each time step (time steps in parallel).
///
/// ```
/// use diffsoft::analysis::spectral::EigenMethod;
/// use diffsoft::analysis::sweep::{default_range, log_space, sweep};
/// use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
/// use diffsoft::mesh::generate::BoxSpec;
///
/// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let sys = IterationSystem::new(&mesh, 1000.0, 1e5, &Attachments::default())?;
/// let spectrum = Spectrum::compute(&sys, EigenMethod::Dense)?;
/// let (lo, hi) = default_range(&spectrum);
/// let points = sweep(&sys, &spectrum, &log_space(lo, hi, 5), EigenMethod::Dense)?;
/// assert_eq!(points.len(), 5);
/// // (19) diverges at large steps; (21) converges at every one on this mesh.
/// assert!(points[0].rho_plain < 1.0 && points[4].rho_plain > 1.0);
/// assert!(points.iter().all(|p| p.rho_split < 1.0));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn sweep(
    sys: &IterationSystem,
    spectrum: &Spectrum,
    dts: &[f64],
    method: EigenMethod,
) -> Result<Vec<SweepPoint>, AnalysisError> {
    dts.par_iter()
        .map(|&dt| {
            Ok(SweepPoint {
                dt,
                rho_plain: spectrum.rho_plain(dt),
                rho_split: rho_split(sys, dt, method)?,
            })
        })
        .collect()
}

/// A default range: two decades below `h*_19` to two decades above the larger critical step.
pub fn default_range(spectrum: &Spectrum) -> (f64, f64) {
    let h19 = spectrum.critical_dt_plain();
    let top = spectrum.critical_dt_split().unwrap_or(h19).max(h19);
    (h19 * 1e-2, top * 1e2)
}
