//! What the validation cases share: the material models and their small-strain moduli, the one
//! place that selects a model in the engine, meshes, and static solves with Newton's method.

use diffsoft::contact::pair::boundary_faces;

use nalgebra::Vector3;

use super::closed::{lame, Density};
use diffsoft::base::Material;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::mesh::TetMesh;
use diffsoft::model::{BodySpec, MassSpec, Model, ModelBuilder};
use diffsoft::solver::{CertifyPolicy, Settings, Simulator, SolverKind, StepStats};

use diffsoft::base::{Choice, MaterialModel};

/// The models in report order.
pub fn models() -> impl Iterator<Item = MaterialModel> {
    MaterialModel::ALL.iter().copied()
}

/// The energy density of `model` with `m` in principal stretches (for the uniaxial closed forms).
pub fn density(model: MaterialModel, m: Material) -> Density {
    let (mu, lambda) = lame(m.youngs_modulus, m.poisson_ratio);
    match model {
        MaterialModel::Projective => Density::Projective {
            e: m.youngs_modulus,
            nu: m.poisson_ratio,
        },
        MaterialModel::Corotated => Density::Corotated { mu, lambda },
        MaterialModel::NeoHookean => Density::NeoHookean { mu, lambda },
    }
}

/// A body of `mesh` with `material` under `model` and density `rho`.
pub fn body(name: &str, mesh: TetMesh, material: Material, model: MaterialModel, rho: f64) -> Result<BodySpec, String> {
    let mut spec = BodySpec::new(name, mesh, material, MassSpec::Density(rho));
    spec.model = model;
    Ok(spec)
}

/// Settings of a static solve: implicit steps of `dt = 100 s` with Newton's method to a
/// tolerance of `tolerance` of the length scale. A step's first iterate is the inertial target
/// `s = q + h v + h^2 g`, which a rigid translation by `h^2 g` away from equilibrium: bodies are
/// therefore clamped by stiff attachments ([`clamp`]), not by fixed vertices, so that this first
/// iterate is unstrained (a fixed face would stretch the layer next to it by `h^2 g`, from where
/// Newton's method on a hyperelastic energy needs many iterations). `h = 100 s` keeps `h^2 g`
/// (98 km) small enough for round-off (1e-11 m) and the inertia `M/h^2` small enough that each
/// step removes all but `1/(omega h)^2` of the distance to equilibrium (see [`solve_static`]).
pub fn static_settings(tolerance: f64) -> Settings {
    Settings {
        dt: 100.0,
        solver: SolverKind::Newton,
        certify: CertifyPolicy::Off,
        tolerance,
        max_iterations: 200,
        inner_tolerance: 1e-13,
        ..Settings::default()
    }
}

/// Attach `vertices` of `spec` to their rest positions with weight `weight` (N/m): a clamp that
/// gives way by force / weight.
pub fn clamp(spec: &mut BodySpec, vertices: &[usize], weight: f64) {
    spec.attachments = vertices.iter().map(|&i| (i, weight)).collect();
}

/// Settings of a dynamic run with Newton's method at step `dt` under `integrator`, to a tolerance
/// of 1e-10 of the length scale.
pub fn dynamic_settings(dt: f64, integrator: diffsoft::solver::Integrator) -> Settings {
    Settings {
        dt,
        integrator,
        solver: SolverKind::Newton,
        certify: CertifyPolicy::Off,
        tolerance: 1e-10,
        max_iterations: 100,
        inner_tolerance: 1e-13,
        ..Settings::default()
    }
}

/// The result of a static solve.
pub struct Static {
    /// Positions at equilibrium.
    pub q: Vec<Vector3<f64>>,
    /// Rest positions.
    pub rest: Vec<Vector3<f64>>,
    /// Newton iterations, summed over the load steps.
    pub iterations: usize,
    /// Whether every load step converged.
    pub converged: bool,
}

/// Solve `model` to static equilibrium from `start` (rest when `None`): steps of
/// [`static_settings`] at `tolerance`, each from rest (velocities set to zero), until a step
/// moves no vertex by more than `1e-6` of the largest displacement (at most 8 steps). The fixed
/// point of these steps is exactly the static equilibrium; each step leaves `1/(omega_1 h)^2` of
/// the distance to it, below 1e-6 for every body here, so two steps suffice.
pub fn solve_static(model: Model, start: Option<Vec<Vector3<f64>>>, tolerance: f64) -> Result<Static, String> {
    let rest = model.rest().to_vec();
    let n = model.n();
    let mut sim = Simulator::new(model, static_settings(tolerance)).map_err(|e| e.to_string())?;
    let mut q = start.unwrap_or_else(|| rest.clone());
    let (mut iterations, mut converged) = (0, true);
    for _ in 0..8 {
        sim.set_state(q.clone(), vec![Vector3::zeros(); n])
            .map_err(|e| e.to_string())?;
        let st: StepStats = sim.step().map_err(|e| e.to_string())?;
        iterations += st.iterations;
        converged &= st.converged;
        let next = &sim.state().q;
        let change = next.iter().zip(&q).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        let reach = next.iter().zip(&rest).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        q.copy_from_slice(next);
        if change <= 1e-6 * reach {
            break;
        }
    }
    Ok(Static {
        q,
        rest,
        iterations,
        converged,
    })
}

/// Build a model of one body under gravity `g` (along `-y` when positive).
pub fn one_body(spec: BodySpec, g: f64) -> Result<Model, String> {
    ModelBuilder::new()
        .gravity(Vector3::new(0.0, -g, 0.0))
        .body(spec)
        .build()
        .map_err(|e| e.to_string())
}

/// A box of `cells` Kuhn cells of `size` with its minimum corner at `origin`.
pub fn boxed(cells: [usize; 3], size: [f64; 3], origin: [f64; 3]) -> TetMesh {
    BoxSpec::new(cells, size).origin(origin).build().expect("a valid box")
}

/// Vertices of `mesh` on its boundary (a vertex of a face that only one tet has).
pub fn boundary_vertices(mesh: &TetMesh) -> Vec<bool> {
    let mut on = vec![false; mesh.num_vertices()];
    for f in boundary_faces(&mesh.tets) {
        for v in f {
            on[v] = true;
        }
    }
    on
}

/// Vertices with `pred(rest position)`.
pub fn select_vertices(rest: &[Vector3<f64>], pred: impl Fn(&Vector3<f64>) -> bool) -> Vec<usize> {
    (0..rest.len()).filter(|&i| pred(&rest[i])).collect()
}

/// Mean displacement of `set`.
pub fn mean_displacement(q: &[Vector3<f64>], rest: &[Vector3<f64>], set: &[usize]) -> Vector3<f64> {
    set.iter().map(|&i| q[i] - rest[i]).sum::<Vector3<f64>>() / set.len().max(1) as f64
}

/// Mean position of `set`.
pub fn mean_position(q: &[Vector3<f64>], set: &[usize]) -> Vector3<f64> {
    set.iter().map(|&i| q[i]).sum::<Vector3<f64>>() / set.len().max(1) as f64
}

/// `|a - b| / |b|`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}
