//! Large deflection of a cantilever under its own weight against the elastica
//! ([`closed::elastica`]), with the bending stiffness calibrated on the same mesh at a small load
//! so that locking cancels.

use std::time::Instant;

use nalgebra::Vector3;

use super::case::{Case, Spec};
use super::closed;
use super::common::Static;
use super::common::{body, boxed, clamp, mean_displacement, mean_position, one_body, select_vertices, solve_static};
use diffsoft::base::Material;
use diffsoft::base::{Choice, MaterialModel};

/// The load parameters `alpha = q L^3 / (E I)` compared.
pub const ALPHAS: [f64; 3] = [1.0, 2.0, 4.0];

const L: f64 = 1.0;
const B: f64 = 0.05;
const RHO: f64 = 1000.0;

/// The beam of `model` under gravity `g` (m/s^2), solved statically from `start`.
fn solve(model: MaterialModel, material: Material, g: f64, start: Option<Vec<Vector3<f64>>>) -> Result<Static, String> {
    let mesh = boxed([40, 2, 2], [L, B, B], [0.0, -B / 2.0, -B / 2.0]);
    let mut spec = body("beam", mesh.clone(), material, model, RHO)?;
    let root = select_vertices(&mesh.vertices, |x| x.x < 1e-9);
    clamp(&mut spec, &root, 1e6 * material.youngs_modulus * B / 2.0);
    solve_static(one_body(spec, g)?, start, 1e-10)
}

/// Tip position over `L` and rotation of the tip face: `(v/L, (L - x)/L, theta)`, with `v` and `x`
/// of the face's centroid and `theta` the rotation of its edge `y = -B/2 -> y = B/2`.
fn tip(s: &Static) -> (f64, f64, f64) {
    let face = select_vertices(&s.rest, |x| x.x > L - 1e-9);
    let c = mean_position(&s.q, &face);
    let top: Vec<usize> = face.iter().copied().filter(|&i| s.rest[i].y > B / 2.0 - 1e-9).collect();
    let bottom: Vec<usize> = face
        .iter()
        .copied()
        .filter(|&i| s.rest[i].y < -B / 2.0 + 1e-9)
        .collect();
    let d = mean_position(&s.q, &top) - mean_position(&s.q, &bottom);
    (-c.y / L, (L - c.x) / L, d.x.atan2(d.y))
}

/// The elastica cases of `model`: a 1 x 0.05 x 0.05 m beam (40 x 2 x 2 Kuhn cells, 960 tets),
/// E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m^3, clamped at x = 0; the bending stiffness `EI_h` of the
/// mesh from the static deflection at `alpha = 0.01` (Euler-Bernoulli), then the gravity that
/// gives each `alpha = q L^3 / (EI_h)` in turn, each solve starting from the previous one.
pub fn cases(model: MaterialModel) -> Vec<Case> {
    let t0 = Instant::now();
    let material = Material {
        youngs_modulus: 1e7,
        poisson_ratio: 0.3,
    };
    let area = B * B;
    let inertia = B.powi(4) / 12.0;
    let e_resp = model.small_strain_response(material).youngs_modulus;
    let spec_of = |alpha: f64| {
        let mut spec = Spec::new("elastica", &format!("alpha{alpha}"), model.name(), "calibrated EI");
        spec.setup = format!(
            "beam 1 x 0.05 x 0.05 m along x (40 x 2 x 2 Kuhn cells, 960 tets), clamped at x = 0 (attached with \
             weight 1e6 E h), E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m^3, {} model; the mesh's bending stiffness \
             EI_h from the static tip deflection at alpha = 0.01 (EI_h = q L^4 / (8 w)), then gravity set so that \
             q L^3 / EI_h = {alpha}, loaded in the sequence alpha = 1, 2, 4 (each static Newton solve from the \
             previous shape)",
            model.name()
        );
        spec.quantity = "tip deflection v/L (error: the larger of the tip position error over the tip \
                         displacement and the tip rotation's relative error)"
            .into();
        spec.formula = "the inextensible elastica under self-weight: theta'' = -alpha (1 - s) cos(theta), \
                        theta(0) = 0, theta'(1) = 0, s = arc length / L"
            .into();
        spec.source = "large-deflection cantilever under a uniformly distributed load (Bisshopp and Drucker 1945 \
                       for a tip load; self-weight: Frisch-Fay, Flexible Bars, 1962); solved here by shooting \
                       and checked against the reference values (derivations)"
            .into();
        spec.tolerance = 0.02;
        spec.tolerance_basis = "calibrating EI_h on the same mesh cancels locking to first order; what is left is \
                                the change of locking and shear with the deformed shape, the beam's axial \
                                strain (up to alpha b / (4 L) = 5% at the root fibres at alpha = 4) and the \
                                section's finite size (b/L = 0.05): 2%"
            .into();
        spec
    };
    // Calibration at alpha = 0.01 with the model's small-strain modulus (its value cancels).
    let g_of = |alpha: f64, ei: f64| alpha * ei / (RHO * area * L.powi(3));
    let g_small = g_of(0.01, e_resp * inertia);
    let calibration = solve(model, material, g_small, None).map(|s| {
        let face = select_vertices(&s.rest, |x| x.x > L - 1e-9);
        -mean_displacement(&s.q, &s.rest, &face).y
    });
    let w_small = match calibration {
        Ok(w) => w,
        Err(e) => return ALPHAS.iter().map(|&a| spec_of(a).not_run(&e)).collect(),
    };
    let q_small = RHO * g_small * area;
    let ei_h = q_small * L.powi(4) / (8.0 * w_small);
    let locking = ei_h / (e_resp * inertia);
    let calibration_seconds = t0.elapsed().as_secs_f64();
    let mut cases = Vec::new();
    let mut start = None;
    for alpha in ALPHAS {
        let t = Instant::now();
        let reference = closed::elastica(alpha);
        let spec = spec_of(alpha);
        match solve(model, material, g_of(alpha, ei_h), start.take()) {
            Ok(s) => {
                let (v, u, th) = tip(&s);
                let displacement = reference.tip_deflection.hypot(reference.tip_shortening);
                let position = (v - reference.tip_deflection).hypot(u - reference.tip_shortening) / displacement;
                let rotation = (th - reference.tip_rotation).abs() / reference.tip_rotation;
                let err = position.max(rotation);
                let converged = s.converged;
                let its = s.iterations;
                cases.push(
                    spec.measured(reference.tip_deflection, v, err, |_| {
                        format!(
                            "v/L {v:.5} vs {:.5}, (L-x)/L {u:.5} vs {:.5}, rotation {th:.4} vs {:.4} rad (converged: \
                             {converged})",
                            reference.tip_deflection, reference.tip_shortening, reference.tip_rotation
                        )
                    })
                    .with(&[
                        ("tip_shortening", u),
                        ("tip_shortening_reference", reference.tip_shortening),
                        ("tip_rotation_rad", th),
                        ("tip_rotation_reference_rad", reference.tip_rotation),
                        ("position_error", position),
                        ("rotation_error", rotation),
                        ("calibrated_ei_over_e_i", locking),
                        ("newton_iterations", its as f64),
                    ])
                    .timed(t.elapsed().as_secs_f64() + if alpha == ALPHAS[0] { calibration_seconds } else { 0.0 }),
                );
                start = Some(s.q);
            }
            Err(e) => cases.push(spec.not_run(&e)),
        }
    }
    cases
}
