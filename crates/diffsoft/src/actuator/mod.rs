//! Actuators of a body (docs/method.md section 5, appendix D): groups of pneumatic cells and
//! muscle fibres, each group driven by one activation.
//!
//! A group owns tets. A pneumatic group adds, per tet, the constraint of Eqs. 39-40 with
//! weight `k_p V` (the tet's singular values pulled to a product `a`); a muscle group adds, per
//! tet, a fibre along a rest direction `m` with weight `k_m V`, pulled to length `1 - a`
//! ([`crate::kernel::actuator`]). Both are ordinary projective constraints: their weights
//! enter the constant global matrix once, and each local step projects them in parallel.
//! Activations are piecewise-linear time series ([`Schedule`]) or set per step through
//! [`Simulator::set_activation`](crate::solver::Simulator::set_activation).
//!
//! A model without actuators has `Model::actuators == None` and runs no actuator code.
//!
//! Where tets come from:
//! * [`tets_of_vertices`]: the tets with at least `min_shared` vertices in a vertex group (the
//!   paper's drone lists pneumatic "Volume Verts");
//! * [`fibres_along`]: a uniform direction for a set of tets;
//! * [`fibres_from_polyline`]: the tets whose centroid lies within `radius` of a polyline, each
//!   with the direction of its nearest segment (the paper's `octopus.muscle`).

use nalgebra::Vector3;
use serde::Serialize;

use crate::base::InputError;
use crate::base::Schedule;
use crate::mesh::TetMesh;

/// The kind of a group.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ActuatorKind {
    /// Pneumatic cells: activation = target volume ratio, `a > 0`.
    Pneumatic,
    /// Muscle fibres: activation in `[0, 1]`, fibre length `1 - a`.
    Muscle,
}

impl ActuatorKind {
    /// Whether `a` is an admissible activation.
    pub fn admits(&self, a: f64) -> bool {
        match self {
            ActuatorKind::Pneumatic => a.is_finite() && a > 0.0,
            ActuatorKind::Muscle => (0.0..=1.0).contains(&a),
        }
    }

    /// The admissible range, in words.
    pub fn range(&self) -> &'static str {
        match self {
            ActuatorKind::Pneumatic => "finite and > 0",
            ActuatorKind::Muscle => "in [0, 1]",
        }
    }
}

/// A group as given to the model builder (tets in body numbering).
#[derive(Debug, Clone)]
pub struct ActuatorSpec {
    /// Name (activations are set by name).
    pub name: String,
    /// Kind.
    pub kind: ActuatorKind,
    /// Stiffness `k` (Pa): the weight per unit rest volume.
    pub stiffness: f64,
    /// Activation over time.
    pub activation: Schedule,
    /// The tets, with their fibre direction for muscles (ignored for pneumatic cells).
    pub cells: Vec<(usize, Vector3<f64>)>,
}

impl ActuatorSpec {
    /// A pneumatic group on `tets`.
    ///
    /// ```
    /// use diffsoft::actuator::{ActuatorKind, ActuatorSpec};
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Schedule, Settings, Simulator};
    ///
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let all: Vec<usize> = (0..mesh.num_tets()).collect();
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let mut body = BodySpec::new("balloon", mesh, material, MassSpec::Density(1000.0));
    /// // Activation 2: every tet is pulled toward twice its volume.
    /// body.actuators.push(ActuatorSpec::pneumatic("inflate", &all, 1e5, Schedule::constant(2.0)));
    /// let model = ModelBuilder::new().body(body).build()?;
    /// let groups = &model.actuators().ok_or("no actuators")?.groups;
    /// assert_eq!((groups[0].kind, groups.len()), (ActuatorKind::Pneumatic, 1));
    ///
    /// let mut sim = Simulator::new(model, Settings::default())?;
    /// for _ in 0..5 {
    ///     sim.step()?;
    /// }
    /// let width = sim.state().q.iter().map(|q| q.x).fold(f64::MIN, f64::max)
    ///     - sim.state().q.iter().map(|q| q.x).fold(f64::MAX, f64::min);
    /// assert!(width > 0.101, "the box grew: {width}");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn pneumatic(name: &str, tets: &[usize], stiffness: f64, activation: Schedule) -> Self {
        Self {
            name: name.to_string(),
            kind: ActuatorKind::Pneumatic,
            stiffness,
            activation,
            cells: tets.iter().map(|&t| (t, Vector3::zeros())).collect(),
        }
    }

    /// A muscle group from `(tet, direction)` fibres.
    ///
    /// ```
    /// use diffsoft::actuator::{fibres_along, ActuatorKind, ActuatorSpec};
    /// use diffsoft::mesh::generate::BoxSpec;
    /// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder, Schedule};
    /// use nalgebra::Vector3;
    ///
    /// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
    /// let all: Vec<usize> = (0..mesh.num_tets()).collect();
    /// let material = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
    /// let mut body = BodySpec::new("arm", mesh, material, MassSpec::Density(1000.0));
    /// // Fibres along x (normalised by the model), contracting to 70 % of their length.
    /// let fibres = fibres_along(&all, Vector3::new(2.0, 0.0, 0.0));
    /// body.actuators.push(ActuatorSpec::muscle("biceps", fibres, 1e5, Schedule::constant(0.3)));
    /// let model = ModelBuilder::new().body(body).build()?;
    /// let act = model.actuators().ok_or("no actuators")?;
    /// assert_eq!(act.groups[0].kind, ActuatorKind::Muscle);
    /// assert_eq!(act.group("biceps"), Some(0));
    /// assert!(act.cells.iter().all(|c| c.direction == Vector3::x()));
    ///
    /// // A muscle activation outside [0, 1] is refused when the model is built.
    /// let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
    /// let mut body = BodySpec::new("arm", mesh, material, MassSpec::Density(1000.0));
    /// body.actuators.push(ActuatorSpec::muscle("biceps", vec![(0, Vector3::x())], 1e5, Schedule::constant(1.5)));
    /// assert!(ModelBuilder::new().body(body).build().is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn muscle(name: &str, fibres: Vec<(usize, Vector3<f64>)>, stiffness: f64, activation: Schedule) -> Self {
        Self {
            name: name.to_string(),
            kind: ActuatorKind::Muscle,
            stiffness,
            activation,
            cells: fibres,
        }
    }
}

/// A group in the assembled model.
#[derive(Debug, Clone, Serialize)]
pub struct ActuatorGroup {
    /// Name.
    pub name: String,
    /// Body it belongs to.
    pub body: String,
    /// Kind.
    pub kind: ActuatorKind,
    /// Stiffness (Pa).
    pub stiffness: f64,
    /// Activation over time.
    pub activation: Schedule,
    /// Its cells' range in [`Actuators::cells`].
    pub cells: std::ops::Range<usize>,
}

/// One actuated tet.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Cell {
    /// Tet (global numbering).
    pub tet: usize,
    /// Group index.
    pub group: usize,
    /// Weight `k V`.
    pub weight: f64,
    /// Unit rest direction of a muscle fibre (zero for a pneumatic cell).
    pub direction: Vector3<f64>,
}

/// All actuators of a model.
#[derive(Debug, Clone, Serialize)]
pub struct Actuators {
    /// Groups.
    pub groups: Vec<ActuatorGroup>,
    /// Cells, grouped.
    pub cells: Vec<Cell>,
}

impl Actuators {
    /// Index of the group called `name`.
    pub fn group(&self, name: &str) -> Option<usize> {
        self.groups.iter().position(|g| g.name == name)
    }

    /// Append a body's groups (`t0`: its first tet; `volumes`: rest volume of every tet of the
    /// model so far, global numbering).
    pub(crate) fn push_body(
        &mut self,
        body: &str,
        specs: Vec<ActuatorSpec>,
        t0: usize,
        num_tets: usize,
        volumes: &[f64],
    ) -> Result<(), InputError> {
        for spec in specs {
            let what = format!("body '{body}', actuator '{}'", spec.name);
            let bad = |m: String| Err(InputError::new(format!("{what}: {m}")));
            crate::base::check_name("actuator", &spec.name).map_err(|e| e.context(&format!("body '{body}'")))?;
            if self.groups.iter().any(|g| g.name == spec.name) {
                return bad("duplicate actuator name".into());
            }
            if !(spec.stiffness.is_finite() && spec.stiffness > 0.0) {
                return bad(format!(
                    "stiffness must be finite and positive, got {}",
                    crate::base::number(spec.stiffness)
                ));
            }
            spec.activation.validate(&format!("{what} activation"))?;
            if let Some(a) = spec.activation.values.iter().find(|a| !spec.kind.admits(**a)) {
                return bad(format!(
                    "activation {} out of range ({})",
                    crate::base::number(*a),
                    spec.kind.range()
                ));
            }
            if spec.cells.is_empty() {
                return bad("no tets".into());
            }
            let group = self.groups.len();
            let c0 = self.cells.len();
            let mut listed = std::collections::HashSet::with_capacity(spec.cells.len());
            for (t, d) in spec.cells {
                if t >= num_tets {
                    return bad(format!("tet {t} out of range ({num_tets} tets)"));
                }
                // A tet listed twice would be actuated twice over.
                if !listed.insert(t) {
                    return bad(format!("tet {t} is listed twice"));
                }
                let direction = match spec.kind {
                    ActuatorKind::Pneumatic => Vector3::zeros(),
                    ActuatorKind::Muscle => match crate::base::unit_vector(d) {
                        Some(u) => u,
                        None => {
                            return bad(format!(
                                "tet {t}: fibre direction must be finite and non-zero, got [{}, {}, {}]",
                                d.x, d.y, d.z
                            ))
                        }
                    },
                };
                self.cells.push(Cell {
                    tet: t + t0,
                    group,
                    weight: spec.stiffness * volumes[t + t0],
                    direction,
                });
            }
            self.groups.push(ActuatorGroup {
                name: spec.name,
                body: body.to_string(),
                kind: spec.kind,
                stiffness: spec.stiffness,
                activation: spec.activation,
                cells: c0..self.cells.len(),
            });
        }
        Ok(())
    }
}

/// The tets with at least `min_shared` of their vertices in `vertices` (body numbering).
///
/// ```
/// use diffsoft::actuator::tets_of_vertices;
/// use diffsoft::mesh::generate::BoxSpec;
///
/// let mesh = BoxSpec::new([2, 1, 1], [0.2, 0.1, 0.1]).build()?;
/// // The vertices of the cell at x < 0.1 (and its face at x = 0.1).
/// let left: Vec<usize> = (0..mesh.num_vertices()).filter(|&v| mesh.vertices[v].x < 0.15).collect();
/// let tets = tets_of_vertices(&mesh, &left, 4);
/// assert_eq!(tets.len(), 6);
/// assert!(tets.iter().all(|&t| mesh.tets[t].iter().all(|&v| mesh.vertices[v].x < 0.15)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn tets_of_vertices(mesh: &TetMesh, vertices: &[usize], min_shared: usize) -> Vec<usize> {
    let mut mark = vec![false; mesh.num_vertices()];
    for &v in vertices {
        if v < mark.len() {
            mark[v] = true;
        }
    }
    (0..mesh.num_tets())
        .filter(|&t| mesh.tets[t].iter().filter(|&&v| mark[v]).count() >= min_shared)
        .collect()
}

/// Centroid of tet `t`.
pub fn centroid(mesh: &TetMesh, t: usize) -> Vector3<f64> {
    mesh.tets[t].iter().map(|&v| mesh.vertices[v]).sum::<Vector3<f64>>() / 4.0
}

/// Every tet of `tets` with the same fibre direction.
///
/// ```
/// use diffsoft::actuator::fibres_along;
/// use nalgebra::Vector3;
///
/// let fibres = fibres_along(&[3, 5], Vector3::y());
/// assert_eq!(fibres, vec![(3, Vector3::y()), (5, Vector3::y())]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn fibres_along(tets: &[usize], direction: Vector3<f64>) -> Vec<(usize, Vector3<f64>)> {
    tets.iter().map(|&t| (t, direction)).collect()
}

/// Distance from `p` to segment `[a, b]`.
fn segment_distance(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let len2 = ab.norm_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * s - p).norm()
}

/// Distance from the centroid of every tet to the nearest segment of `polyline`, with that
/// segment's unit direction (`None` for a polyline without a segment of positive length).
pub fn nearest_segments(mesh: &TetMesh, polyline: &[Vector3<f64>]) -> Option<Vec<(f64, Vector3<f64>)>> {
    let segments: Vec<(Vector3<f64>, Vector3<f64>)> = polyline
        .windows(2)
        .filter(|w| (w[1] - w[0]).norm() > 0.0)
        .map(|w| (w[0], w[1]))
        .collect();
    if segments.is_empty() {
        return None;
    }
    Some(
        (0..mesh.num_tets())
            .map(|t| {
                let c = centroid(mesh, t);
                let (d, (a, b)) = segments
                    .iter()
                    .map(|s| (segment_distance(&c, &s.0, &s.1), *s))
                    .min_by(|x, y| x.0.total_cmp(&y.0))
                    .expect("non-empty");
                (d, (b - a).normalize())
            })
            .collect(),
    )
}

/// The tets whose centroid lies within `radius` of `polyline`, each with the direction of its
/// nearest segment.
///
/// ```
/// use diffsoft::actuator::fibres_from_polyline;
/// use diffsoft::mesh::generate::BoxSpec;
/// use nalgebra::Vector3;
///
/// let mesh = BoxSpec::new([4, 1, 1], [0.4, 0.1, 0.1]).build()?;
/// // A line along the beam's axis: every tet's centroid is within 0.05 of it.
/// let axis = [Vector3::new(0.0, 0.05, 0.05), Vector3::new(0.4, 0.05, 0.05)];
/// let fibres = fibres_from_polyline(&mesh, &axis, 0.05);
/// assert_eq!(fibres.len(), mesh.num_tets());
/// assert!(fibres.iter().all(|(_, m)| *m == Vector3::x()));
/// // A polyline without a segment of positive length gives no fibres.
/// assert!(fibres_from_polyline(&mesh, &axis[..1], 1.0).is_empty());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn fibres_from_polyline(mesh: &TetMesh, polyline: &[Vector3<f64>], radius: f64) -> Vec<(usize, Vector3<f64>)> {
    nearest_segments(mesh, polyline)
        .map(|near| {
            near.into_iter()
                .enumerate()
                .filter(|(_, (d, _))| *d <= radius)
                .map(|(t, (_, m))| (t, m))
                .collect()
        })
        .unwrap_or_default()
}
