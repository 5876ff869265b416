//! The contact phase of a step (docs/method.md section 4, Eqs. C1-C6): candidate contacts from
//! the start and predicted positions, then after each round of iterations the new penetrations
//! (obstacles) and violated pairs (between bodies) or, when no pair is violated, the pairs that
//! passed through each other during the round (Eq. C6), added as contacts for the next round.

use nalgebra::Vector3;

use super::assembled::GlobalSystem;
use super::free_contact::{FreeContact, Stencil};
use crate::contact::pair::{BodyCollision, Detector, PairContact, Query as PairQuery};
use crate::contact::{self, Contact};
use crate::model::Model;

/// A pair's linearised gap at the end of a step may fall this far (times the thickness) below
/// zero before the pair is added as a new contact.
pub const PAIR_TOLERANCE: f64 = 1e-3;

/// The obstacle index that marks a contact between two bodies.
pub const PAIR_OBSTACLE: usize = usize::MAX;

/// The contacts of the current step and the buffers of their detection (sized on first use).
#[derive(Debug, Clone)]
pub(crate) struct StepContacts {
    /// Obstacle contacts (global numbering).
    pub obstacle: Vec<Contact>,
    /// Contacts on free vertices (obstacles and pairs), as the global solvers take them.
    pub free: Vec<FreeContact>,
    /// Obstacle contacts on bone vertices: `(bone-vertex index, contact)`.
    pub rigid: Vec<(usize, Contact)>,
    /// Contacts between bodies.
    pub pairs: Vec<PairContact>,
    in_contact: Vec<bool>,
    /// Vertices that take no contacts: Dirichlet vertices.
    excluded: Vec<bool>,
    detector: Detector,
}

impl StepContacts {
    /// Buffers for `model`.
    pub(crate) fn new(model: &Model) -> Self {
        Self {
            obstacle: Vec::new(),
            free: Vec::new(),
            rigid: Vec::new(),
            pairs: Vec::new(),
            in_contact: vec![false; model.n()],
            excluded: model.fixed.clone(),
            detector: Detector::default(),
        }
    }

    /// The candidates of a step from `q_start` to the predicted `pred` (within `margin`, or
    /// crossing an obstacle; pairs closer than the thickness plus `margin`).
    pub(crate) fn candidates(
        &mut self,
        model: &Model,
        sys: &GlobalSystem,
        q_start: &[Vector3<f64>],
        pred: &[Vector3<f64>],
        margin: f64,
    ) {
        self.obstacle.clear();
        self.free.clear();
        self.rigid.clear();
        if !model.obstacles.is_empty() {
            contact::detect(
                &model.obstacles,
                &self.excluded,
                q_start,
                pred,
                margin,
                &mut self.obstacle,
            );
            for i in 0..self.obstacle.len() {
                let c = self.obstacle[i];
                self.sort(sys, c);
            }
        }
        self.pairs.clear();
        if let Some(col) = &model.collision {
            self.detector
                .detect(col, q_start, pred, PairQuery::Candidates { margin }, &mut self.pairs);
            for p in &self.pairs {
                if let Some(fc) = pair_contact(p, sys, q_start, &col.settings) {
                    self.free.push(fc);
                }
            }
        }
    }

    /// Surface edges of one body that cross a face of another at `q`, the end of a step (0
    /// without collisions between bodies): a contact the step missed.
    pub(crate) fn crossings_at(&mut self, model: &Model, q: &[Vector3<f64>]) -> usize {
        model
            .collision
            .as_ref()
            .map_or(0, |col| self.detector.crossing_count(col, q))
    }

    /// An obstacle contact into the free or the bone-vertex list.
    fn sort(&mut self, sys: &GlobalSystem, c: Contact) {
        if sys.index[c.vertex] != usize::MAX {
            self.free.push(FreeContact::single(sys.index[c.vertex], c));
        } else {
            self.rigid.push((sys.rigid_index[c.vertex], c));
        }
    }

    /// After a round of iterations ending at `q` (all vertices): add every violated pair (or,
    /// without one, every pair that passed through another on the way, Eq. C6) and every new
    /// penetration of an obstacle as a contact. Returns whether any was added.
    pub(crate) fn add_violations(
        &mut self,
        model: &Model,
        sys: &GlobalSystem,
        q_start: &[Vector3<f64>],
        q: &[Vector3<f64>],
    ) -> bool {
        let pairs_before = self.pairs.len();
        if let Some(col) = &model.collision {
            self.detector.remember(&self.pairs, true);
            let tolerance = PAIR_TOLERANCE * col.settings.thickness;
            self.detector
                .detect(col, q_start, q, PairQuery::Violations { tolerance }, &mut self.pairs);
            for p in &self.pairs[pairs_before..] {
                if let Some(fc) = pair_contact(p, sys, q_start, &col.settings) {
                    self.free.push(fc);
                }
            }
        }
        let before = self.obstacle.len();
        for c in &self.obstacle {
            self.in_contact[c.vertex] = true;
        }
        for (i, (a, x)) in q_start.iter().zip(q).enumerate() {
            if self.excluded[i] || self.in_contact[i] {
                continue;
            }
            for (oi, o) in model.obstacles.iter().enumerate() {
                if let Some((d, normal, point)) = o.query(a, x, 0.0) {
                    if d < 0.0 {
                        let c = Contact {
                            vertex: i,
                            obstacle: oi,
                            normal,
                            point,
                            anchor: *a,
                            friction: o.friction,
                        };
                        self.obstacle.push(c);
                        self.sort(sys, c);
                        break;
                    }
                }
            }
        }
        for c in &self.obstacle {
            self.in_contact[c.vertex] = false;
        }
        self.obstacle.len() != before || self.pairs.len() != pairs_before
    }
}

/// A pair between bodies as a contact on its free vertices (Eq. C3): Dirichlet vertices move
/// into the plane's offset and the anchor (`None` when every vertex of the pair is fixed).
fn pair_contact(
    p: &PairContact,
    sys: &GlobalSystem,
    q_start: &[Vector3<f64>],
    col: &BodyCollision,
) -> Option<FreeContact> {
    let mut stencil = Stencil {
        len: 0,
        index: [0; 4],
        coef: [0.0; 4],
    };
    let mut offset = Vector3::zeros();
    let mut anchor = Vector3::zeros();
    for (&v, &c) in p.vertices.iter().zip(&p.coefs) {
        let k = sys.index[v];
        if k == usize::MAX {
            offset += q_start[v] * c;
        } else {
            stencil.index[stencil.len as usize] = k;
            stencil.coef[stencil.len as usize] = c;
            stencil.len += 1;
            anchor += q_start[v] * c;
        }
    }
    (stencil.len > 0).then(|| FreeContact {
        index: stencil.index[0],
        contact: Contact {
            vertex: p.vertices[0],
            obstacle: PAIR_OBSTACLE,
            normal: p.normal,
            point: p.normal * col.thickness - offset,
            anchor,
            friction: col.friction,
        },
        stencil,
        pair: Some(*p),
    })
}
