//! Hertz contact: the contact radius of an elastic hemisphere resting on its pole on a rigid,
//! frictionless ground under its own weight, `a = (3 F R / (4 E*))^(1/3)`.
//!
//! Hertz's solution depends only on the radius of curvature at the contact, the force and the
//! moduli (the half-space approximation, valid for `a << R`), so the lower half of a ball carries
//! it as well as the whole ball at half the cost. Its mesh maps a graded half-cube onto the
//! hemisphere (`p -> R p |p|_inf / |p|_2`), with cells clustered at the pole so that the contact
//! disc spans several vertex rings.

use std::time::Instant;

use nalgebra::Vector3;

use super::case::{moduli, Case, Spec};
use super::closed::hertz_radius;
use super::common::{body, rel};
use diffsoft::base::Material;
use diffsoft::base::{Choice, MaterialModel};
use diffsoft::contact::pair::boundary_faces;
use diffsoft::contact::Obstacle;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::TetMesh;
use diffsoft::model::ModelBuilder;

const R: f64 = 0.1;

const RHO: f64 = 1000.0;
const G: f64 = 9.81;

/// The monotone grading of `[0, 1]` onto itself with slope `beta` at 0: `t (beta + (1 - beta) t^4)`
/// (nearly uniform cells of relative size `beta` out to about `t = 0.5`).
fn grade(t: f64, beta: f64) -> f64 {
    t * (beta + (1.0 - beta) * t.powi(4))
}

/// The hemisphere `|x - c| <= R, y <= c_y` with its pole at the origin: `n x n/2 x n` cells of the
/// half-cube `[-1, 1] x [-1, 0] x [-1, 1]`, graded towards the pole's axis (slope `beta`) and the
/// pole, mapped onto the half-ball and shifted up by `R`.
///
/// The mesh is mirror-symmetric in `x` and in `z` (one quadrant's tets mirrored into the other
/// three), so its lumped masses are too, and the resting body does not tilt: a tilt would be a
/// rocking mode of the hemisphere on its pole, an order of magnitude slower to settle than the
/// contact's own.
pub fn hemisphere(n: usize, beta: f64) -> TetMesh {
    let h = (n / 2).max(1);
    let quadrant = BoxSpec::new([h, h, h], [1.0, 1.0, 1.0])
        .origin([0.0, -1.0, 0.0])
        .build()
        .expect("a valid box");
    // Vertices of the four mirror images, merged on the mirror planes by their lattice index.
    let key = |p: &Vector3<f64>, sx: f64, sz: f64| {
        let l = |t: f64| (t * h as f64).round() as i64;
        (l(sx * p.x), l(p.y), l(sz * p.z))
    };
    let mut index: std::collections::HashMap<(i64, i64, i64), usize> = std::collections::HashMap::new();
    let mut vertices: Vec<Vector3<f64>> = Vec::new();
    let mut tets = Vec::new();
    for (sx, sz) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
        let ids: Vec<usize> = quadrant
            .vertices
            .iter()
            .map(|p| {
                *index.entry(key(p, sx, sz)).or_insert_with(|| {
                    vertices.push(Vector3::new(sx * p.x, p.y, sz * p.z));
                    vertices.len() - 1
                })
            })
            .collect();
        for t in &quadrant.tets {
            let mut t = t.map(|v| ids[v]);
            // One mirror reverses the orientation.
            if sx * sz < 0.0 {
                t.swap(2, 3);
            }
            tets.push(t);
        }
    }
    let vertices = vertices
        .iter()
        .map(|p| {
            let g = |t: f64| t.signum() * grade(t.abs(), beta);
            // Towards y = -1 (the pole).
            let y = grade(1.0 + p.y, beta) - 1.0;
            let q = Vector3::new(g(p.x), y, g(p.z));
            let l2 = q.norm();
            let mapped = if l2 > 0.0 { q * (q.amax() / l2) } else { q };
            mapped * R + Vector3::new(0.0, R, 0.0)
        })
        .collect();
    TetMesh::new(vertices, tets).expect("the mapped hemisphere is a valid mesh")
}

/// One resting hemisphere: the contact radius's bracket, contact vertices, contact edge length,
/// load, Newton iterations, pseudo-time steps, converged.
type HertzRun = (f64, f64, usize, f64, f64, usize, usize, bool);

/// The pseudo-time step of [`settle`] (s).
const SETTLE_DT: f64 = 0.01;
/// Newton iterations per pseudo-time step.
const SETTLE_ITERATIONS: usize = 60;
/// [`settle`] stops when a step moves no vertex by more than this (m).
const SETTLE_CHANGE: f64 = 1e-9;

/// Where [`settle`] ends.
struct Settled {
    q: Vec<Vector3<f64>>,
    iterations: usize,
    steps: usize,
    converged: bool,
}

/// The resting state of `model` on its ground by pseudo-time continuation: implicit steps of
/// [`SETTLE_DT`] with Newton's method and the contact active set, each from rest (velocities
/// set to zero), until a step moves no vertex by more than [`SETTLE_CHANGE`].
///
/// The fixed point of these steps is the static equilibrium with contact. Each step leaves
/// `1 / (1 + (omega h)^2)` of the distance to it in a mode of frequency `omega`; the slowest is
/// the body bouncing on its contact (`omega^2 = 3 g / (2 delta)` with Hertz's approach `delta`:
/// about 80 rad/s here), so a step removes about 40% and twenty steps reach 1e-9 m. One static
/// step (`h = 100 s`) does not work: its first iterate, the inertial target, lies `h^2 g` below the
/// ground, where every vertex is a contact candidate and the active set stalls.
///
/// An intermediate step may stop at [`SETTLE_ITERATIONS`] while a ring of vertices joins the
/// contact (the active set can cycle on a vertex with zero gap and zero force); the continuation
/// goes on from where it stopped, and the result is converged only when the last step is.
fn settle(model: diffsoft::model::Model) -> Result<Settled, String> {
    let n = model.n();
    let mut q = model.rest().to_vec();
    let settings = diffsoft::solver::Settings {
        max_iterations: SETTLE_ITERATIONS,
        ..super::common::dynamic_settings(SETTLE_DT, diffsoft::solver::Integrator::ImplicitEuler)
    };
    let mut sim = diffsoft::solver::Simulator::new(model, settings).map_err(|e| e.to_string())?;
    let (mut iterations, mut steps) = (0, 0);
    while steps < 100 {
        sim.set_state(q.clone(), vec![Vector3::zeros(); n])
            .map_err(|e| e.to_string())?;
        let st = sim.step().map_err(|e| e.to_string())?;
        iterations += st.iterations;
        steps += 1;
        let next = &sim.state().q;
        let change = next.iter().zip(&q).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        q.copy_from_slice(next);
        if change <= SETTLE_CHANGE {
            return Ok(Settled {
                q,
                iterations,
                steps,
                converged: st.converged,
            });
        }
    }
    Ok(Settled {
        q,
        iterations,
        steps,
        converged: false,
    })
}

/// The hemisphere's mesh parameters.
const CELLS: usize = 16;
const BETA: f64 = 0.3;

/// Contact radius estimates from the bottom surface: `(a_low, a_high, rings, h)`: the radii of the
/// discs with the area of the surface triangles with all, resp. at least one, vertex on the
/// ground; the number of contact vertices; the mean edge length of the triangles in contact.
fn contact_radius(q: &[Vector3<f64>], faces: &[[usize; 3]], tol: f64) -> (f64, f64, usize, f64) {
    let on = |i: usize| q[i].y <= tol;
    let area = |f: &[usize; 3]| {
        // Projected on the ground.
        let p = |i: usize| Vector3::new(q[f[i]].x, 0.0, q[f[i]].z);
        0.5 * (p(1) - p(0)).cross(&(p(2) - p(0))).norm()
    };
    let (mut all, mut any, mut edges, mut count) = (0.0, 0.0, 0.0, 0usize);
    for f in faces {
        let k = f.iter().filter(|&&i| on(i)).count();
        if k == 3 {
            all += area(f);
            for e in 0..3 {
                edges += (q[f[e]] - q[f[(e + 1) % 3]]).norm();
                count += 1;
            }
        }
        if k > 0 {
            any += area(f);
        }
    }
    let contact: std::collections::BTreeSet<usize> = faces.iter().flatten().copied().filter(|&i| on(i)).collect();
    (
        (all / std::f64::consts::PI).sqrt(),
        (any / std::f64::consts::PI).sqrt(),
        contact.len(),
        edges / count.max(1) as f64,
    )
}

/// The Hertz cases of `model`: E = 7.6e5 Pa, nu = 0.4, rho = 1000 kg/m^3, R = 0.1 m, on a
/// frictionless ground, settled by [`settle`].
pub fn cases(model: MaterialModel) -> Vec<Case> {
    let t0 = Instant::now();
    let material = Material {
        youngs_modulus: 7.6e5,
        poisson_ratio: 0.4,
    };
    let mesh = hemisphere(CELLS, BETA);
    let faces = boundary_faces(&mesh.tets);
    let run = || -> Result<HertzRun, String> {
        let spec = body("hemisphere", mesh.clone(), material, model, RHO)?;
        let m = ModelBuilder::new()
            .gravity(Vector3::new(0.0, -G, 0.0))
            .body(spec)
            .obstacle(Obstacle::plane("ground", Vector3::zeros(), Vector3::y(), 0.0))
            .build()
            .map_err(|e| e.to_string())?;
        let weight: f64 = m.mass().iter().sum::<f64>() * G;
        let s = settle(m)?;
        let (lo, hi, n, h) = contact_radius(&s.q, &faces, 1e-9 * R);
        Ok((lo, hi, n, h, weight, s.iterations, s.steps, s.converged))
    };
    let result = run();
    let seconds = t0.elapsed().as_secs_f64();
    let mut variants = vec![(moduli(model, true), model.small_strain_response(material), true)];
    if model == MaterialModel::Projective {
        variants.insert(0, ("E, nu".to_string(), material, false));
    }
    let mut out = Vec::new();
    for (k, (label, m, expected)) in variants.into_iter().enumerate() {
        let mut spec = Spec::new("hertz", "hemisphere", model.name(), &label);
        spec.setup = format!(
            "hemisphere R = 0.1 m resting on its pole on a rigid frictionless plane under its own weight (rho = \
             1000 kg/m^3, g = 9.81 m/s^2), E = 7.6e5 Pa, nu = 0.4, {} model; {} tets mapped from a {CELLS} x {} x \
             {CELLS} half-cube graded towards the pole (cells of about {:.1} mm there), mirror-symmetric in x and z; settled \
             by implicit steps of 0.01 s from rest with Newton's method and the contact active set until a step \
             moves no vertex by more than 1e-9 m; contact vertices within 1e-10 m of the ground",
            model.name(),
            mesh.num_tets(),
            CELLS / 2,
            2.0 * BETA / CELLS as f64 * R * 1e3
        );
        spec.quantity = "contact radius: the mean of the radii of the discs with the area of the surface triangles \
                         with all and with at least one vertex on the ground (m)"
            .into();
        spec.formula = if expected && model == MaterialModel::Projective {
            "a = (3 F R / (4 E*))^(1/3), E* = E_eff / (1 - nu_eff^2), F the weight".into()
        } else {
            "a = (3 F R / (4 E*))^(1/3), E* = E / (1 - nu^2), F the weight".into()
        };
        spec.source =
            "Hertz 1882; Johnson, Contact Mechanics (1985), section 4.2: a sphere on a rigid half-space".into();
        spec.expected_to_hold = expected;
        spec.tolerance = 0.08;
        spec.tolerance_basis = "the contact edge is quantised by the vertex rings: the two area radii bracket it, \
                                and their mean is within a quarter of a ring (h ~ a/4 here: about 6%); Hertz's \
                                half-space approximation is O((a/R)^2) at a/R = 0.15: 8%"
            .into();
        match &result {
            Ok((_, _, _, _, _, _, steps, false)) => {
                out.push(spec.not_run(&format!("the settling did not converge in {steps} pseudo-time steps")))
            }
            Ok((lo, hi, n, h, weight, its, steps, _)) => {
                let a_ref = hertz_radius(*weight, R, m.youngs_modulus, m.poisson_ratio);
                let a = 0.5 * (lo + hi);
                let err = rel(a, a_ref);
                out.push(
                    spec.measured(a_ref, a, err, |s| {
                        if s.expected_to_hold {
                            format!(
                                "contact radius between {lo:.4e} and {hi:.4e} m vs {a_ref:.4e} m ({n} contact vertices)"
                            )
                        } else {
                            format!(
                                "expected: the projective model responds with E_eff, nu_eff: the contact radius is \
                                 {:.3}x the closed form with E, nu",
                                a / a_ref
                            )
                        }
                    })
                    .with(&[
                        ("radius_low_m", *lo),
                        ("radius_high_m", *hi),
                        ("contact_vertices", *n as f64),
                        ("contact_edge_m", *h),
                        ("force_n", *weight),
                        ("a_over_r", a_ref / R),
                        ("newton_iterations", *its as f64),
                        ("settle_steps", *steps as f64),
                    ])
                    .timed(if k == 0 { seconds } else { 0.0 }),
                );
            }
            Err(e) => out.push(spec.not_run(e)),
        }
    }
    out
}
