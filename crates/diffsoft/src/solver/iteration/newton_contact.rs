//! Obstacle contacts in Newton's method (docs/method.md section 6.5, Eq. S6): a primal active
//! set on the step's candidate contacts, which reaches the fixed point of the projective-dynamics
//! step with contacts.
//!
//! At that fixed point every contact `j` on free vertex `v` has the impulse
//! `lambda_j = (grad E)_v` (the force the obstacle exerts: `A x = b + sum_j e_j lambda_j`) and
//! obeys Coulomb's law on the end-of-step position ([`crate::contact::project`]'s fixed point,
//! which does not depend on the projection's weight): separated (`gap >= 0`, no impulse),
//! sticking (on the plane, at the anchor's tangential position, `|lambda_T| <= mu lambda_N`), or
//! sliding (on the plane, `lambda_T = mu lambda_N u` with `u` against the slip).
//!
//! With each contact's state held, a Newton iteration minimises
//! `E(x) - sum_slide f_j . x_v` with the sliding contacts' friction forces `f_j = mu lambda_N u`
//! held from the previous iterate, over the positions that satisfy the held constraints: a
//! sticking vertex is fixed at its target, a sliding one moves in the plane. Directions and
//! gradients are projected onto that subspace (`P`), and conjugate gradients run with the
//! projected preconditioner `P A^-1 P`. The line search stops where a separated candidate
//! would cross its plane, and that contact joins the set (sliding, with no friction force until
//! its impulse is known). After each iteration every contact's impulse is projected onto its
//! Coulomb cone as a projective-dynamics global step does, at `x_hat = x_v - lambda_j / w_v`
//! with `w_v = 1 / (A^-1)_vv` ([`crate::contact::project`]); the projection gives the state
//! (separate, stick, slide) and a sliding contact's friction force to hold. Its fixed point is
//! Coulomb's law at `x` whatever the weight. Two rules of a primal active-set method keep the
//! states from switching back and forth: a held contact separates only once the held problem
//! has settled (the last iteration moved no more than the tolerance), and no state changes
//! where the change would move the vertex by less than the tolerance.
//!
//! The set is seeded from one projective-dynamics iteration with contacts, whose impulses give
//! every contact's state. The step has converged when the positions change by less than the
//! tolerance, no state changed and the friction forces moved no vertex by more than the
//! tolerance.
//!
//! Only contacts of one vertex with an obstacle are handled here; contacts between bodies are
//! refused by [`super::newton::check_supported`].

use nalgebra::Vector3;

use crate::contact::{project, Contact, ContactState};
use crate::solver::free_contact::FreeContact;

/// A contact's state in the active set.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Separate,
    Stick,
    /// Sliding: on the plane, with the held friction force (against the slip).
    Slide,
}

/// The active set of a Newton step's contacts (buffers grow to the largest set seen).
#[derive(Debug, Clone, Default)]
pub(crate) struct NewtonContacts {
    state: Vec<State>,
    /// The impulses at the current iterate, `(grad E)_v` (the contact's free vertex).
    lambda: Vec<Vector3<f64>>,
    /// The held friction force of each sliding contact (zero otherwise).
    force: Vec<Vector3<f64>>,
}

/// The plane point below `p` (the vertex's position with zero gap).
fn on_plane(c: &Contact, p: &Vector3<f64>) -> Vector3<f64> {
    p - c.normal * c.normal.dot(&(p - c.point))
}

impl NewtonContacts {
    /// The impulses at the current iterate, one per contact.
    pub(crate) fn impulses(&self) -> &[Vector3<f64>] {
        &self.lambda
    }

    /// Seed the states from a projective-dynamics solve's impulses (one per contact): zero is
    /// separated, inside the cone sticking, on its boundary sliding.
    pub(crate) fn seed(&mut self, contacts: &[FreeContact], impulses: &[Vector3<f64>]) {
        self.state.clear();
        self.lambda.clear();
        self.force.clear();
        for (fc, l) in contacts.iter().zip(impulses) {
            let c = &fc.contact;
            let ln = c.normal.dot(l);
            let lt = l - c.normal * ln;
            let (state, force) = if ln <= 0.0 {
                (State::Separate, Vector3::zeros())
            } else if lt.norm() < c.friction * ln * (1.0 - 1e-9) || lt.norm() == 0.0 {
                (State::Stick, Vector3::zeros())
            } else {
                (State::Slide, lt * (c.friction * ln / lt.norm()))
            };
            self.state.push(state);
            self.lambda.push(*l);
            self.force.push(force);
        }
    }

    /// Put every held contact's vertex where its constraint says (a sticking one at its
    /// target, a sliding one onto its plane). Returns whether any moved.
    pub(crate) fn enforce(&self, contacts: &[FreeContact], x: &mut [Vector3<f64>]) -> bool {
        let mut moved = false;
        for (fc, s) in contacts.iter().zip(&self.state) {
            let (c, xv) = (&fc.contact, &mut x[fc.index]);
            let target = match s {
                State::Separate => continue,
                State::Stick => on_plane(c, &c.anchor),
                State::Slide => on_plane(c, xv),
            };
            if target != *xv {
                *xv = target;
                moved = true;
            }
        }
        moved
    }

    /// Remove the held components from a free vector (`v <- P v`).
    pub(crate) fn project(&self, contacts: &[FreeContact], v: &mut [Vector3<f64>]) {
        for (fc, s) in contacts.iter().zip(&self.state) {
            let n = fc.contact.normal;
            let vi = &mut v[fc.index];
            match s {
                State::Separate => {}
                State::Stick => *vi = Vector3::zeros(),
                State::Slide => *vi -= n * n.dot(vi),
            }
        }
    }

    /// The held friction forces' work `sum f_j . x_v` (subtracted from `E`).
    pub(crate) fn friction_work(&self, contacts: &[FreeContact], x: &[Vector3<f64>]) -> f64 {
        contacts
            .iter()
            .zip(&self.force)
            .map(|(fc, f)| f.dot(&x[fc.index]))
            .sum()
    }

    /// Record the impulses `(grad E)_v` from the full gradient, then turn it into the held
    /// problem's projected gradient `P (grad E - f)`.
    pub(crate) fn constrain_gradient(&mut self, contacts: &[FreeContact], grad: &mut [Vector3<f64>]) {
        for (((fc, l), f), s) in contacts.iter().zip(&mut self.lambda).zip(&self.force).zip(&self.state) {
            *l = if *s == State::Separate {
                Vector3::zeros()
            } else {
                grad[fc.index]
            };
            grad[fc.index] -= f;
        }
        self.project(contacts, grad);
    }

    /// The largest step `alpha <= 1` along `d` before a separated candidate crosses its plane,
    /// and that contact (`None`: no candidate blocks the full step).
    pub(crate) fn blocking(
        &self,
        contacts: &[FreeContact],
        x: &[Vector3<f64>],
        d: &[Vector3<f64>],
    ) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        for (j, (fc, s)) in contacts.iter().zip(&self.state).enumerate() {
            if *s != State::Separate {
                continue;
            }
            let c = &fc.contact;
            let rate = c.normal.dot(&d[fc.index]);
            if rate >= 0.0 {
                continue;
            }
            let gap = c.normal.dot(&(x[fc.index] - c.point)).max(0.0);
            let alpha = gap / -rate;
            if alpha < 1.0 && best.is_none_or(|(a, _)| alpha < a) {
                best = Some((alpha, j));
            }
        }
        best
    }

    /// Contact `j` joins the set (it reached its plane): sliding, with no friction force until
    /// its impulse is known (the next [`NewtonContacts::update`] then sticks it if the cone
    /// holds it).
    pub(crate) fn activate(&mut self, j: usize) {
        self.state[j] = State::Slide;
        self.force[j] = Vector3::zeros();
    }

    /// Take every state again at the iterate `x` (see the module docs): each contact's impulse
    /// is projected onto its Coulomb cone as a projective-dynamics global step does
    /// ([`crate::contact::project`] at `x_hat = x_v - lambda_j / w_v`, with the weight
    /// `w_v = 1 / (A^-1)_vv` from `inverse_diagonal(v)`), which gives its state and, for a
    /// sliding contact, the friction force to hold. The projection's fixed point is Coulomb's
    /// law at `x` whatever the weight, so the states settle where the step's do.
    ///
    /// A held contact separates only once the held problem is `settled` (the last iteration
    /// moved the positions by at most the tolerance): only at that problem's minimiser does a
    /// negative normal impulse mean that the vertex leaves the plane (a primal active-set
    /// method's rule; judged earlier, a contact can be released and blocked again in turn).
    /// A held contact also keeps its state where the change would move its vertex by at most
    /// `tolerance` (a grazing contact with a vanishing impulse, or one on the cone's boundary).
    /// Returns whether a state changed and the largest displacement the held forces' change
    /// would cause.
    pub(crate) fn update(
        &mut self,
        contacts: &[FreeContact],
        x: &[Vector3<f64>],
        tolerance: f64,
        settled: bool,
        mut inverse_diagonal: impl FnMut(usize) -> f64,
    ) -> (bool, f64) {
        let mut changed = false;
        let mut moved = 0.0f64;
        for (j, fc) in contacts.iter().enumerate() {
            let c = &fc.contact;
            let inv = inverse_diagonal(fc.index);
            let old = self.lambda[j];
            let x_hat = x[fc.index] - old * inv;
            let (l, st) = project(&x_hat, 1.0 / inv, c);
            let ln = c.normal.dot(&l);
            let lt = l - c.normal * ln;
            let old_n = c.normal.dot(&old);
            let old_t = (old - c.normal * old_n).norm();
            let next = match (self.state[j], st) {
                // Separating or starting to slide by less than the tolerance: keep.
                (State::Stick | State::Slide, ContactState::Separate) if !settled || -old_n * inv <= tolerance => {
                    self.state[j]
                }
                (State::Stick, ContactState::Slide) if (old_t - c.friction * old_n) * inv <= tolerance => State::Stick,
                // A sticking contact pulled off the plane while its tangential impulse is
                // outside the cone: its normal impulse is the tangential constraint's doing;
                // let it slide first.
                (State::Stick, ContactState::Separate) if old_t * inv > tolerance && old_t > c.friction * old_n => {
                    State::Slide
                }
                (_, ContactState::Separate) => State::Separate,
                (_, ContactState::Stick) => State::Stick,
                (_, ContactState::Slide) => State::Slide,
            };
            let force = match (next, st) {
                (State::Slide, ContactState::Slide) => lt,
                (State::Slide, _) => self.force[j],
                _ => Vector3::zeros(),
            };
            changed |= next != self.state[j];
            moved = moved.max((force - self.force[j]).norm() * inv);
            self.state[j] = next;
            self.force[j] = force;
        }
        (changed, moved)
    }
}
