//! Collisions between bodies: soft-soft, soft-cloth and cloth-cloth (docs/method.md section 4,
//! Eqs. C3, C5 and C6, with both sides moving).
//!
//! Each body's collision surface is its boundary triangles (a tet mesh) or its triangles
//! (cloth), with their edges and vertices. A step's candidate contacts are
//!
//! * **vertex-face** pairs (a surface vertex of one body, a triangle of another) whose distance
//!   at the start of the step, minus how far their vertices may move during it, is below the
//!   collision thickness plus a margin (each vertex keeps the closest pair per other body), and
//! * after the step's iterations, every **vertex-face** or **edge-edge** pair (surface edges of
//!   two bodies whose closest points are interior to both) that ended up violated; these join
//!   and the iterations resume (contact rounds);
//! * when a round leaves no violated pair, every vertex-face or edge-edge pair whose primitives
//!   passed through each other on the straight path from the step's start to the round's end
//!   ([`sweep`], Eq. C6), linearised where they met (*swept* pairs, which gradients refuse).
//!
//! A uniform spatial hash over the primitives' swept bounding boxes finds them in time linear in
//! the surface size.
//!
//! A [`PairContact`] linearises its pair at the start of the step: the relative coordinate
//! `r = sum_k c_k x_k` (`r = p - (u a + v b + w c)` for a vertex and the closest point of a face,
//! `r = (a + s (b - a)) - (c + t (d - c))` for two edges), with the coefficients `c_k` and the
//! unit normal `n` frozen at the start, and asks `n . r >= thickness`. The solver treats it
//! like an obstacle contact on `r` (the same Coulomb cone, [`super::project`]); its impulse acts
//! on every vertex of the pair with weight `c_k`, so both bodies feel it. Sticking means no
//! relative tangential motion of the pair during the step.
//!
//! The coefficients and the normal are smooth functions of the start positions within a
//! *regime* (which feature of the face is closest; interior edge points): [`PairContact::jacobian`]
//! differentiates them by forward-mode dual numbers for the backward pass.

mod geometry;
mod grid;
pub mod overlap;
pub mod sweep;

use nalgebra::Vector3;
use num_dual::Dual64;
use serde::Serialize;

use crate::base::{Body, InputError};
use crate::cloth::Cloth;
use grid::Grid;

pub use geometry::{edge_edge, geometry, segment_crosses, vertex_face, Regime};

/// Settings of collisions between bodies.
///
/// ```
/// use diffsoft::contact::pair::BodyCollision;
/// use diffsoft::mesh::generate::BoxSpec;
/// use diffsoft::{BodySpec, MassSpec, Material, ModelBuilder};
///
/// let m = Material { youngs_modulus: 1e5, poisson_ratio: 0.3 };
/// let a = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).build()?;
/// let b = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1]).origin([0.0, 0.2, 0.0]).build()?;
/// let model = ModelBuilder::new()
///     .body(BodySpec::new("a", a, m, MassSpec::Density(1000.0)))
///     .body(BodySpec::new("b", b, m, MassSpec::Density(1000.0)))
///     .collisions(BodyCollision { thickness: 1e-3, friction: 0.2 })
///     .build()?;
/// assert_eq!(model.n(), 16);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BodyCollision {
    /// Distance the surfaces are kept apart (m).
    pub thickness: f64,
    /// Coulomb friction coefficient between bodies (1).
    pub friction: f64,
}

impl BodyCollision {
    /// Check the parameters.
    pub fn validate(&self) -> Result<(), InputError> {
        if !(self.thickness.is_finite() && self.thickness > 0.0) {
            return Err(InputError::new(format!(
                "collision thickness must be finite and positive, got {}",
                crate::base::number(self.thickness)
            )));
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(InputError::new(format!(
                "collision friction must be finite and >= 0, got {}",
                crate::base::number(self.friction)
            )));
        }
        Ok(())
    }
}

/// The collision surfaces of every body (global vertex numbering).
#[derive(Debug, Clone)]
pub struct Colliders {
    /// Settings.
    pub settings: BodyCollision,
    /// Body names (soft bodies first, then cloth), indexed by the `*_body` arrays.
    pub names: Vec<String>,
    /// Surface triangles.
    pub triangles: Vec<[usize; 3]>,
    /// Body of each triangle.
    pub triangle_body: Vec<u32>,
    /// Surface edges.
    pub edges: Vec<[usize; 2]>,
    /// Body of each edge.
    pub edge_body: Vec<u32>,
    /// Surface vertices.
    pub vertices: Vec<usize>,
    /// Body of each surface vertex.
    pub vertex_body: Vec<u32>,
    /// Dirichlet vertices (a pair made only of them is skipped).
    pub fixed: Vec<bool>,
    /// Mean surface edge length at rest (sets the spatial hash's cell size).
    pub mean_edge: f64,
}

/// Boundary faces of a tet mesh (faces that belong to exactly one tet).
pub fn boundary_faces(tets: &[[usize; 4]]) -> Vec<[usize; 3]> {
    let mut faces: Vec<([usize; 3], [usize; 3])> = Vec::with_capacity(tets.len() * 4);
    for t in tets {
        for skip in 0..4 {
            let f: Vec<usize> = (0..4).filter(|&k| k != skip).map(|k| t[k]).collect();
            let face = [f[0], f[1], f[2]];
            let mut key = face;
            key.sort_unstable();
            faces.push((key, face));
        }
    }
    faces.sort_unstable_by_key(|f| f.0);
    let mut out = Vec::new();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        if j - i == 1 {
            out.push(faces[i].1);
        }
        i = j;
    }
    out
}

impl Colliders {
    /// Collect the surfaces of the soft bodies (`bodies`, `tets` in global numbering) and the
    /// cloth.
    pub fn new(
        settings: BodyCollision,
        bodies: &[Body],
        tets: &[[usize; 4]],
        cloth: Option<&Cloth>,
        fixed: &[bool],
        rest: &[Vector3<f64>],
    ) -> Result<Self, InputError> {
        let n = rest.len();
        settings.validate()?;
        let mut c = Self {
            settings,
            names: Vec::new(),
            triangles: Vec::new(),
            triangle_body: Vec::new(),
            edges: Vec::new(),
            edge_body: Vec::new(),
            vertices: Vec::new(),
            vertex_body: Vec::new(),
            fixed: fixed.to_vec(),
            mean_edge: 0.0,
        };
        let mut surfaces: Vec<(String, Vec<[usize; 3]>)> = bodies
            .iter()
            .map(|b| (b.name.clone(), boundary_faces(&tets[b.tets.clone()])))
            .collect();
        if let Some(cl) = cloth {
            for b in &cl.bodies {
                surfaces.push((b.name.clone(), cl.triangles[b.triangles.clone()].to_vec()));
            }
        }
        if surfaces.len() < 2 {
            return Err(InputError::new(format!(
                "collisions between bodies need at least two bodies, the scene has {}",
                surfaces.len()
            )));
        }
        let mut seen = vec![false; n];
        for (b, (name, tris)) in surfaces.into_iter().enumerate() {
            c.names.push(name);
            let mut edges: Vec<[usize; 2]> = Vec::with_capacity(tris.len() * 3);
            for t in &tris {
                for k in 0..3 {
                    let (i, j) = (t[k], t[(k + 1) % 3]);
                    edges.push([i.min(j), i.max(j)]);
                    if !seen[t[k]] {
                        seen[t[k]] = true;
                        c.vertices.push(t[k]);
                        c.vertex_body.push(b as u32);
                    }
                }
            }
            edges.sort_unstable();
            edges.dedup();
            c.edge_body.extend(std::iter::repeat_n(b as u32, edges.len()));
            c.edges.extend(edges);
            c.triangle_body.extend(std::iter::repeat_n(b as u32, tris.len()));
            c.triangles.extend(tris);
        }
        let s: f64 = c.edges.iter().map(|e| (rest[e[0]] - rest[e[1]]).norm()).sum();
        c.mean_edge = s / c.edges.len().max(1) as f64;
        Ok(c)
    }
}

/// What identifies a pair: its regime, whether it was linearised where it crossed, and its
/// vertices ([`PairContact::key`]).
pub type PairKey = (Regime, bool, [usize; 4]);

/// A linearised contact between two bodies (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PairContact {
    /// `[p, a, b, c]` (vertex and face) or `[a, b, c, d]` (edge `ab`, edge `cd`), global.
    pub vertices: [usize; 4],
    /// Coefficients of the relative coordinate `r = sum c_k x_k`.
    pub coefs: [f64; 4],
    /// Unit normal at the start of the step.
    pub normal: Vector3<f64>,
    /// Distance `n . r` at the start of the step.
    pub distance: f64,
    /// Closest features.
    pub regime: Regime,
    /// A pair that passed through each other during a round of the step, linearised where
    /// and when they met ([`sweep`], [`Query::Violations`]): its coefficients and normal
    /// depend on the round's end positions, not only the start, so gradients refuse a step
    /// with one.
    pub swept: bool,
}

impl PairContact {
    /// `r = sum c_k x_k`.
    pub fn relative(&self, x: &[Vector3<f64>]) -> Vector3<f64> {
        (0..4).fold(Vector3::zeros(), |acc, k| acc + x[self.vertices[k]] * self.coefs[k])
    }

    /// A key identifying the pair (its regime, whether it is swept, and its vertices): a
    /// vertex and a face may be a pair linearised at the start and another where they met
    /// ([`Query::Violations`]).
    pub fn key(&self) -> PairKey {
        (self.regime, self.swept, self.vertices)
    }

    /// Derivatives of the coefficients and the normal with respect to the start positions of
    /// the pair's four vertices, within its regime: `(dc_k/dq_{j,d}, dn/dq_{j,d})` indexed
    /// `[3 j + d]`.
    pub fn jacobian(&self, q: &[Vector3<f64>]) -> ([[f64; 4]; 12], [Vector3<f64>; 12]) {
        let mut dc = [[0.0; 4]; 12];
        let mut dn = [Vector3::zeros(); 12];
        for (j, (dcj, dnj)) in dc.chunks_mut(3).zip(dn.chunks_mut(3)).enumerate() {
            for d in 0..3 {
                let x: [Vector3<Dual64>; 4] = std::array::from_fn(|k| {
                    let mut v = q[self.vertices[k]].map(Dual64::from);
                    if k == j {
                        v[d].eps = 1.0;
                    }
                    v
                });
                let (c, n) = geometry(self.regime, &x);
                dcj[d] = std::array::from_fn(|k| c[k].eps);
                dnj[d] = n.map(|v| v.eps);
            }
        }
        (dc, dn)
    }
}

fn overlaps(a: &(Vector3<f64>, Vector3<f64>), b: &(Vector3<f64>, Vector3<f64>)) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// What a detection pass looks for.
#[derive(Debug, Clone, Copy)]
pub enum Query {
    /// Pairs that may come within the thickness plus `margin` while moving from `q0` to `q1`.
    Candidates {
        /// Extra distance (m).
        margin: f64,
    },
    /// Pairs (not already known) whose linearised gap at `q1` is below `-tolerance`; when
    /// there is none, the pairs whose primitives pass through each other moving linearly from
    /// `q0` to `q1`, ending on the other side ([`sweep`]), linearised where they meet (a pair
    /// already known as swept only where it met elsewhere).
    Violations {
        /// Allowed violation (m).
        tolerance: f64,
    },
}

/// Reusable buffers of the pair detection.
#[derive(Debug, Clone, Default)]
pub struct Detector {
    grid: Grid,
    tri_boxes: Vec<(Vector3<f64>, Vector3<f64>)>,
    edge_boxes: Vec<(Vector3<f64>, Vector3<f64>)>,
    stamp: Vec<u32>,
    epoch: u32,
    known: rustc_hash::FxHashSet<PairKey>,
    /// The swept pairs already in use: a pair that crossed again on a later round's path,
    /// where its earlier linearisation no longer holds it, is linearised again.
    known_swept: Vec<PairContact>,
    /// The closest pair found so far per other body (one query primitive at a time).
    best: Vec<Option<PairContact>>,
    /// The earliest crossing found so far per other body, with its time in the step.
    first: Vec<Option<(f64, PairContact)>>,
    /// Crossings found in a violations pass, handed over only when it finds no violation.
    swept: Vec<PairContact>,
    /// Candidate pairs tested exactly in the last pass (for the cost study).
    pub tested: usize,
}

fn swept_box(verts: &[usize], q0: &[Vector3<f64>], q1: &[Vector3<f64>], pad: f64) -> (Vector3<f64>, Vector3<f64>) {
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for &v in verts {
        lo = lo.inf(&q0[v]).inf(&q1[v]);
        hi = hi.sup(&q0[v]).sup(&q1[v]);
    }
    (lo.add_scalar(-pad), hi.add_scalar(pad))
}

/// Grid entries per box above which [`swept_boxes`] doubles the cell (a box straddling two
/// cells along each axis makes 8).
const ENTRIES_PER_BOX: usize = 8;

/// The padded boxes swept by `items` (edges or triangles) from `q0` to `q1`, into `boxes`, and
/// the grid cell for them: the mean box extent, or the rest mean edge if larger (a stretched
/// or fast surface does not spread each box over many cells), doubled up to twice while the
/// boxes would make more than [`ENTRIES_PER_BOX`] grid entries each on average. Boxes of very
/// different sizes (the paper's cloth_ball: a cloth wrapped around a collapsed ball) made about
/// 41 entries per box at the mean extent, and the detection took about 40% of a step with
/// contacts; a regular cloth's boxes make fewer than 8 and keep the mean extent, which suits
/// them better (docs/performance.md).
fn swept_boxes<const N: usize>(
    items: &[[usize; N]],
    q0: &[Vector3<f64>],
    q1: &[Vector3<f64>],
    pad: f64,
    mean_edge: f64,
    boxes: &mut Vec<(Vector3<f64>, Vector3<f64>)>,
) -> f64 {
    boxes.clear();
    let mut extent = 0.0;
    for item in items {
        let b = swept_box(item, q0, q1, pad);
        extent += (b.1 - b.0).max();
        boxes.push(b);
    }
    let mut cell = (extent / items.len().max(1) as f64)
        .max(mean_edge)
        .max(f64::MIN_POSITIVE);
    let limit = ENTRIES_PER_BOX * boxes.len();
    for _ in 0..2 {
        if grid_entries(boxes, cell, limit) <= limit {
            break;
        }
        cell *= 2.0;
    }
    cell
}

/// The grid entries `boxes` make with cells of size `cell`, counted up to just past `limit`.
fn grid_entries(boxes: &[(Vector3<f64>, Vector3<f64>)], cell: f64, limit: usize) -> usize {
    let inv = 1.0 / cell;
    let span = |lo: f64, hi: f64| ((hi * inv).floor() - (lo * inv).floor() + 1.0).max(1.0);
    let mut entries = 0.0;
    for (lo, hi) in boxes {
        entries += span(lo.x, hi.x) * span(lo.y, hi.y) * span(lo.z, hi.z);
        if entries > limit as f64 {
            return limit + 1;
        }
    }
    entries as usize
}

impl Detector {
    /// Find pairs between bodies moving from `q0` to `q1` (see [`Query`]); with
    /// [`Query::Violations`], pairs already in `known` (from [`Detector::remember`]) are skipped.
    /// Results are appended to `out`.
    pub fn detect(
        &mut self,
        col: &Colliders,
        q0: &[Vector3<f64>],
        q1: &[Vector3<f64>],
        query: Query,
        out: &mut Vec<PairContact>,
    ) {
        let th = col.settings.thickness;
        let pad = match query {
            Query::Candidates { margin } => 0.5 * (th + margin),
            Query::Violations { .. } => 0.5 * th,
        };
        self.tested = 0;
        self.best.clear();
        self.best.resize(col.names.len(), None);
        self.first.clear();
        self.first.resize(col.names.len(), None);
        let sweeps = matches!(query, Query::Violations { .. });
        let start = out.len();
        self.swept.clear();
        // Triangles, with the largest motion of their corners.
        self.triangle_grid(col, q0, q1, pad);
        let motion = |v: usize| (q1[v] - q0[v]).norm();
        for (vi, &p) in col.vertices.iter().enumerate() {
            let vb = swept_box(&[p], q0, q1, pad);
            self.next_epoch();
            let (grid, stamp, epoch, boxes) = (&self.grid, &mut self.stamp, self.epoch, &self.tri_boxes);
            let (best, first) = (&mut self.best, &mut self.first);
            let body = col.vertex_body[vi];
            let mut tested = 0;
            grid.query(&vb.0, &vb.1, |t| {
                let t = t as usize;
                if stamp[t] == epoch || col.triangle_body[t] == body || !overlaps(&vb, &boxes[t]) {
                    return;
                }
                stamp[t] = epoch;
                let tri = col.triangles[t];
                if col.fixed[p] && tri.iter().all(|&v| col.fixed[v]) {
                    return;
                }
                tested += 1;
                let verts = [p, tri[0], tri[1], tri[2]];
                if sweeps {
                    if let Some(c) = swept_crossing(q0, q1, verts, false, (&self.known, &self.known_swept)) {
                        keep_first(first, col.triangle_body[t], c);
                    }
                }
                let Some((regime, d0)) = vertex_face(&q0[p], &q0[tri[0]], &q0[tri[1]], &q0[tri[2]]) else {
                    return;
                };
                let moved = motion(p) + tri.iter().map(|&v| motion(v)).fold(0.0, f64::max);
                if let Some(c) = accept(col, q0, q1, verts, regime, d0, moved, query, &self.known) {
                    keep_closest(best, col.triangle_body[t], c);
                }
            });
            self.tested += tested;
            emit(best, first, out, &mut self.swept);
        }
        // Edges against edges of other bodies: only where a step ended with an edge through
        // a face (vertex-face contacts already keep nearby surfaces apart; edge-edge
        // candidates would mostly restate them and make the contact system redundant).
        if matches!(query, Query::Candidates { .. }) {
            return;
        }
        let cell = swept_boxes(&col.edges, q0, q1, pad, col.mean_edge, &mut self.edge_boxes);
        self.grid.build(cell, &self.edge_boxes);
        for (ei, e) in col.edges.iter().enumerate() {
            let eb = self.edge_boxes[ei];
            let body = col.edge_body[ei];
            self.next_epoch();
            let (grid, boxes, stamp, epoch) = (&self.grid, &self.edge_boxes, &mut self.stamp, self.epoch);
            let (best, first) = (&mut self.best, &mut self.first);
            let mut tested = 0;
            grid.query(&eb.0, &eb.1, |f| {
                let f = f as usize;
                // Each unordered pair once: the edge of the lower body queries.
                if stamp[f] == epoch || col.edge_body[f] <= body || !overlaps(&eb, &boxes[f]) {
                    return;
                }
                stamp[f] = epoch;
                let g = col.edges[f];
                if [e[0], e[1], g[0], g[1]].iter().all(|&v| col.fixed[v]) {
                    return;
                }
                tested += 1;
                let verts = [e[0], e[1], g[0], g[1]];
                if sweeps {
                    if let Some(c) = swept_crossing(q0, q1, verts, true, (&self.known, &self.known_swept)) {
                        keep_first(first, col.edge_body[f], c);
                    }
                }
                let Some((_, _, d0)) = edge_edge(&q0[e[0]], &q0[e[1]], &q0[g[0]], &q0[g[1]]) else {
                    return;
                };
                let moved = motion(e[0]).max(motion(e[1])) + motion(g[0]).max(motion(g[1]));
                if let Some(c) = accept(col, q0, q1, verts, Regime::EdgeEdge, d0, moved, query, &self.known) {
                    keep_closest(best, col.edge_body[f], c);
                }
            });
            self.tested += tested;
            emit(best, first, out, &mut self.swept);
        }
        // Swept pairs only when no violation is left (docs/method.md Eq. C6): a step that
        // needs none is what it was without them.
        if out.len() == start {
            out.append(&mut self.swept);
        }
    }

    /// A fresh stamp for one query's deduplication.
    fn next_epoch(&mut self) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.epoch = 1;
        }
    }

    /// Remember pairs already in use (for [`Query::Violations`]); `clear` forgets the old ones.
    pub fn remember(&mut self, pairs: &[PairContact], clear: bool) {
        if clear {
            self.known.clear();
            self.known_swept.clear();
        }
        for c in pairs {
            self.known.insert(c.key());
            if c.swept {
                self.known_swept.push(*c);
            }
        }
    }
}

/// Keep `c` if it is closer than the pair kept for its body; of two at the same distance (a
/// vertex nearest an edge is as near both faces on it), the one with the smaller vertex
/// indices, so that the choice does not depend on the order the grid visits them in.
fn keep_closest(best: &mut [Option<PairContact>], body: u32, c: PairContact) {
    let slot = &mut best[body as usize];
    if slot
        .as_ref()
        .is_none_or(|b| c.distance < b.distance || (c.distance == b.distance && c.vertices < b.vertices))
    {
        *slot = Some(c);
    }
}

/// Keep the crossing `c` at time `t` if it is earlier than the one kept for its body (ties to
/// the smaller vertex indices, as [`keep_closest`]).
fn keep_first(first: &mut [Option<(f64, PairContact)>], body: u32, (t, c): (f64, PairContact)) {
    let slot = &mut first[body as usize];
    if slot
        .as_ref()
        .is_none_or(|(s, b)| t < *s || (t == *s && c.vertices < b.vertices))
    {
        *slot = Some((t, c));
    }
}

/// Hand over the pairs kept per body, clearing the slots: the closest one to `out`, the
/// earliest crossing to `swept`.
fn emit(
    best: &mut [Option<PairContact>],
    first: &mut [Option<(f64, PairContact)>],
    out: &mut Vec<PairContact>,
    swept: &mut Vec<PairContact>,
) {
    out.extend(best.iter_mut().filter_map(|b| b.take()));
    swept.extend(first.iter_mut().filter_map(|f| f.take().map(|(_, c)| c)));
}

/// A pair whose primitives pass through each other while moving from `q0` to `q1`
/// ([`sweep`]), not already `known` with the same linearisation (a pair that met somewhere
/// else on this path than where it was linearised before is linearised again: its earlier
/// constraint held the end positions on its side while the primitives went through each
/// other), with its time of crossing: a swept pair linearised where
/// its primitives met (the meeting points' coefficients and the face's or the edges' normal
/// then, on the side the pair started on; regime [`Regime::Face`] or [`Regime::EdgeEdge`] for
/// its kind). Kept only with a positive gap at the start along that normal.
fn swept_crossing(
    q0: &[Vector3<f64>],
    q1: &[Vector3<f64>],
    verts: [usize; 4],
    edges: bool,
    (known, known_swept): (&rustc_hash::FxHashSet<PairKey>, &[PairContact]),
) -> Option<(f64, PairContact)> {
    let x0: [Vector3<f64>; 4] = std::array::from_fn(|k| q0[verts[k]]);
    let x1: [Vector3<f64>; 4] = std::array::from_fn(|k| q1[verts[k]]);
    let (hit, regime) = if edges {
        (sweep::edge_edge(&x0, &x1)?, Regime::EdgeEdge)
    } else {
        let hit = sweep::vertex_face(&x0, &x1)?;
        let side = (x0[2] - x0[1]).cross(&(x0[3] - x0[1])).dot(&(x0[0] - x0[1]));
        (hit, Regime::Face(if side > 0.0 { 1 } else { -1 }))
    };
    let c = PairContact {
        vertices: verts,
        coefs: hit.coefs,
        normal: hit.normal,
        distance: 0.0,
        regime,
        swept: true,
    };
    let distance = c.normal.dot(&c.relative(q0));
    let fine = distance.is_finite() && distance > 0.0;
    let same = |k: &PairContact| {
        k.key() == c.key()
            && (0..4).all(|i| (k.coefs[i] - c.coefs[i]).abs() <= SAME_LINEARISATION)
            && (k.normal - c.normal).amax() <= SAME_LINEARISATION
    };
    // The key tells in O(1) whether the pair is in use at all; only then are its
    // linearisations compared (a rare event: swept pairs are few).
    let new = !known.contains(&c.key()) || !known_swept.iter().any(same);
    (fine && new).then_some((hit.time, PairContact { distance, ..c }))
}

#[allow(clippy::too_many_arguments)]
fn accept(
    col: &Colliders,
    q0: &[Vector3<f64>],
    q1: &[Vector3<f64>],
    verts: [usize; 4],
    regime: Regime,
    d0: f64,
    moved: f64,
    query: Query,
    known: &rustc_hash::FxHashSet<PairKey>,
) -> Option<PairContact> {
    let th = col.settings.thickness;
    if let Query::Candidates { margin } = query {
        if d0 - moved >= th + margin {
            return None;
        }
    }
    if d0 <= 0.0 {
        return None;
    }
    let x: [Vector3<f64>; 4] = std::array::from_fn(|k| q0[verts[k]]);
    let (coefs, normal) = geometry(regime, &x);
    if !normal.iter().all(|v| v.is_finite()) {
        return None;
    }
    let c = PairContact {
        vertices: verts,
        coefs,
        normal,
        distance: d0,
        regime,
        swept: false,
    };
    if let Query::Violations { tolerance } = query {
        if known.contains(&c.key()) || normal.dot(&c.relative(q1)) - th >= -tolerance {
            return None;
        }
    }
    Some(c)
}

/// Largest difference of coefficients and normal components of two linearisations of one
/// swept pair that are the same (both are of order one).
const SAME_LINEARISATION: f64 = 1e-9;

/// Closeness of the bodies' surfaces at positions `q`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Probe {
    /// Smallest distance between primitives of different bodies within `reach` (`None`: none
    /// that close).
    pub min_distance: Option<f64>,
    /// Surface edges of one body that cross a triangle of another (0: no interpenetration).
    pub intersections: usize,
    /// Deepest crossing: over crossing edges, the smaller distance of its two ends to the
    /// crossed triangle's plane (m; 0 without crossings).
    pub penetration: f64,
}

impl Detector {
    /// Distances and crossings between the bodies' surfaces at `q`, looking `reach` far.
    pub fn probe(&mut self, col: &Colliders, q: &[Vector3<f64>], reach: f64) -> Probe {
        let mut probe = Probe::default();
        let mut best = f64::INFINITY;
        self.tri_boxes.clear();
        for t in &col.triangles {
            self.tri_boxes.push(swept_box(t, q, q, 0.5 * reach));
        }
        self.grid
            .build(col.mean_edge.max(reach).max(f64::MIN_POSITIVE), &self.tri_boxes);
        for (vi, &p) in col.vertices.iter().enumerate() {
            let vb = swept_box(&[p], q, q, 0.5 * reach);
            let body = col.vertex_body[vi];
            self.grid.query(&vb.0, &vb.1, |t| {
                let t = t as usize;
                if col.triangle_body[t] == body {
                    return;
                }
                let tri = col.triangles[t];
                if let Some((_, d)) = vertex_face(&q[p], &q[tri[0]], &q[tri[1]], &q[tri[2]]) {
                    best = best.min(d);
                }
            });
        }
        self.triangle_grid(col, q, q, 0.0);
        self.crossings(col, q, |_, _, depth| {
            probe.intersections += 1;
            probe.penetration = probe.penetration.max(depth);
        });
        // Edge-edge distances.
        self.edge_boxes.clear();
        for e in &col.edges {
            self.edge_boxes.push(swept_box(e, q, q, 0.5 * reach));
        }
        self.grid
            .build(col.mean_edge.max(reach).max(f64::MIN_POSITIVE), &self.edge_boxes);
        for (ei, e) in col.edges.iter().enumerate() {
            let body = col.edge_body[ei];
            let eb = self.edge_boxes[ei];
            self.grid.query(&eb.0, &eb.1, |f| {
                let f = f as usize;
                if col.edge_body[f] <= body || !overlaps(&eb, &self.edge_boxes[f]) {
                    return;
                }
                let g = col.edges[f];
                if let Some((_, _, d)) = edge_edge(&q[e[0]], &q[e[1]], &q[g[0]], &q[g[1]]) {
                    best = best.min(d);
                }
            });
        }
        probe.min_distance = (best <= reach).then_some(best);
        probe
    }

    /// The deepest crossing of a surface edge of one body through a triangle of another at
    /// `q` (`None`: the surfaces do not interpenetrate). A body wholly inside another, with no
    /// surface crossing, is not found.
    pub fn deepest_crossing(&mut self, col: &Colliders, q: &[Vector3<f64>]) -> Option<Crossing> {
        self.triangle_grid(col, q, q, 0.0);
        let mut deepest: Option<Crossing> = None;
        self.crossings(col, q, |e, t, depth| {
            if deepest.as_ref().is_none_or(|d| depth > d.depth) {
                deepest = Some(Crossing {
                    edge: col.edges[e],
                    edge_body: col.edge_body[e] as usize,
                    triangle_body: col.triangle_body[t] as usize,
                    depth,
                });
            }
        });
        deepest
    }

    /// How many surface edges of one body cross a triangle of another at `q` (0: the surfaces
    /// do not interpenetrate; a body wholly inside another is not counted).
    pub fn crossing_count(&mut self, col: &Colliders, q: &[Vector3<f64>]) -> usize {
        self.triangle_grid(col, q, q, 0.0);
        let mut count = 0;
        self.crossings(col, q, |_, _, _| count += 1);
        count
    }

    /// The grid of the triangles' boxes swept from `q0` to `q1` and padded by `pad`, its cell
    /// as [`swept_boxes`] chooses it, and the deduplication stamps sized for `col`.
    fn triangle_grid(&mut self, col: &Colliders, q0: &[Vector3<f64>], q1: &[Vector3<f64>], pad: f64) {
        let cell = swept_boxes(&col.triangles, q0, q1, pad, col.mean_edge, &mut self.tri_boxes);
        self.grid.build(cell, &self.tri_boxes);
        if self.stamp.len() != col.triangles.len().max(col.edges.len()) {
            self.stamp = vec![0; col.triangles.len().max(col.edges.len())];
            self.epoch = 0;
        }
    }

    /// Every pair of a surface edge and a triangle of another body that cross at `q`, once
    /// each (the grid built by [`Detector::triangle_grid`]): `f(edge, triangle, depth)`, the
    /// depth being the smaller distance of the edge's two ends to the triangle's plane.
    fn crossings(&mut self, col: &Colliders, q: &[Vector3<f64>], mut f: impl FnMut(usize, usize, f64)) {
        for (ei, e) in col.edges.iter().enumerate() {
            let eb = swept_box(e, q, q, 0.0);
            let body = col.edge_body[ei];
            self.next_epoch();
            let (grid, stamp, epoch, boxes) = (&self.grid, &mut self.stamp, self.epoch, &self.tri_boxes);
            grid.query(&eb.0, &eb.1, |t| {
                let t = t as usize;
                if stamp[t] == epoch || col.triangle_body[t] == body || !overlaps(&eb, &boxes[t]) {
                    return;
                }
                stamp[t] = epoch;
                let tri = col.triangles[t];
                if tri.contains(&e[0]) || tri.contains(&e[1]) {
                    return;
                }
                let (a, b, c) = (&q[tri[0]], &q[tri[1]], &q[tri[2]]);
                if segment_crosses(&q[e[0]], &q[e[1]], [a, b, c]) {
                    let n = (b - a).cross(&(c - a)).normalize();
                    let depth = n.dot(&(q[e[0]] - a)).abs().min(n.dot(&(q[e[1]] - a)).abs());
                    f(ei, t, depth);
                }
            });
        }
    }
}

/// A surface edge of one body through a triangle of another ([`Detector::deepest_crossing`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The edge's two vertices (global numbering).
    pub edge: [usize; 2],
    /// Body of the edge (index into [`Colliders::names`]).
    pub edge_body: usize,
    /// Body of the triangle.
    pub triangle_body: usize,
    /// The smaller distance of the edge's ends to the triangle's plane (m).
    pub depth: f64,
}

#[cfg(test)]
mod tests;
