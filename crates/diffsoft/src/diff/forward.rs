//! The forward pass of a gradient evaluation: run the simulation with the controls, sum the
//! loss, and keep what the backward pass needs: one state per step (checkpoints, as the paper
//! does), the activations, the joint states, and per mode the final contacts of each step
//! (implicit) or whole steps' recordings within a memory budget (unrolled). Checkpoints live in
//! flat arrays sized once, so the steps allocate nothing.

use nalgebra::Vector3;

use super::loss::{Loss, LossGrad};
use super::recording::Recording;
use super::{Controls, DiffError, Progress};
use crate::model::Model;
use crate::solver::free_contact::FreeContact;
use crate::solver::{Settings, Simulator, StepStats};

/// What a forward pass keeps for the backward pass.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Keep {
    /// Every step's state (checkpoints).
    pub states: bool,
    /// Every step's final contacts (implicit mode).
    pub contacts: bool,
    /// Whole steps' recordings within this budget (unrolled mode, see
    /// [`Options::store_bytes`](super::Options::store_bytes)).
    pub store_bytes: usize,
}

/// Per-step rows of fixed width in one flat array.
#[derive(Debug, Clone, Default)]
pub(crate) struct Flat<T> {
    width: usize,
    data: Vec<T>,
}

impl<T: Clone> Flat<T> {
    /// Room for `rows` rows of `width` entries.
    fn with_capacity(width: usize, rows: usize) -> Self {
        Self {
            width,
            data: Vec::with_capacity(width * rows),
        }
    }

    fn push(&mut self, row: &[T]) {
        debug_assert_eq!(row.len(), self.width);
        self.data.extend_from_slice(row);
    }

    /// Number of rows.
    pub(crate) fn len(&self) -> usize {
        self.data.len().checked_div(self.width).unwrap_or(0)
    }

    /// Row `i`.
    pub(crate) fn row(&self, i: usize) -> &[T] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    /// Row `i`, if stored.
    pub(crate) fn get(&self, i: usize) -> Option<&[T]> {
        (i < self.len() && self.width > 0).then(|| self.row(i))
    }

    fn bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<T>()
    }
}

/// Rows of varying length in one flat array, grown for the rest of a run at once when a row
/// does not fit, with room for rows twice as long (so a run whose rows keep about their length
/// allocates once or twice).
#[derive(Debug, Clone)]
pub(crate) struct Ragged<T> {
    data: Vec<T>,
    /// Row `k` is `offsets[k]..offsets[k+1]`.
    offsets: Vec<usize>,
}

impl<T> Default for Ragged<T> {
    fn default() -> Self {
        Self {
            data: Vec::new(),
            offsets: vec![0],
        }
    }
}

impl<T: Clone> Ragged<T> {
    /// Empty, with room for the offsets of `rows` rows.
    fn with_rows(rows: usize) -> Self {
        let mut offsets = Vec::with_capacity(rows + 1);
        offsets.push(0);
        Self {
            data: Vec::new(),
            offsets,
        }
    }

    /// Append `row`, reserving room for `rows_left` rows twice its length when it does not fit.
    fn push(&mut self, row: &[T], rows_left: usize) {
        if self.data.capacity() - self.data.len() < row.len() {
            self.data.reserve(2 * row.len() * rows_left.max(1));
        }
        self.data.extend_from_slice(row);
        self.offsets.push(self.data.len());
    }

    /// Row `k`, if stored.
    pub(crate) fn get(&self, k: usize) -> Option<&[T]> {
        Some(&self.data[*self.offsets.get(k)?..*self.offsets.get(k + 1)?])
    }

    fn bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<T>()
    }
}

/// Each step's final contacts and impulses (implicit mode).
#[derive(Debug, Clone, Default)]
pub(crate) struct StepContacts {
    contacts: Ragged<FreeContact>,
    impulses: Ragged<Vector3<f64>>,
}

impl StepContacts {
    /// Empty, with room for `steps` steps' offsets.
    fn with_steps(steps: usize) -> Self {
        Self {
            contacts: Ragged::with_rows(steps),
            impulses: Ragged::with_rows(steps),
        }
    }

    fn push(&mut self, contacts: &[FreeContact], impulses: &[Vector3<f64>], steps_left: usize) {
        self.contacts.push(contacts, steps_left);
        self.impulses.push(impulses, steps_left);
    }

    /// Step `k`'s contacts and impulses.
    pub(crate) fn get(&self, k: usize) -> Option<(&[FreeContact], &[Vector3<f64>])> {
        Some((self.contacts.get(k)?, self.impulses.get(k)?))
    }

    fn bytes(&self) -> usize {
        self.contacts.bytes() + self.impulses.bytes()
    }
}

/// The states of a forward run (checkpoints) and what the backward pass needs of each step.
#[derive(Debug, Clone)]
pub(crate) struct Forward {
    pub loss: f64,
    /// Positions before the first step and after each.
    pub q: Flat<Vector3<f64>>,
    /// Velocities before the first step and after each.
    pub v: Flat<Vector3<f64>>,
    /// Time before the first step and after each.
    pub time: Vec<f64>,
    /// Activations of each step.
    pub activations: Flat<f64>,
    /// Raw joint state before the first step and after each, with a skeleton.
    pub skeleton: Flat<f64>,
    /// The one-DoF joints' coordinates after each step (for joint losses).
    pub joints: Flat<f64>,
    /// Implicit mode with contacts: each step's final contact set and impulses.
    pub contacts: StepContacts,
    /// Unrolled mode: steps' recordings kept within the store budget (`None`: replay).
    pub stored: Vec<Option<Recording>>,
    pub stored_bytes: usize,
    pub iterations: usize,
    pub unconverged: usize,
    /// Steps with a global or contact solve that stopped unconverged (capped or stalled).
    pub capped: usize,
    /// Per step: whether it had such a solve.
    pub capped_steps: Vec<bool>,
    /// Steps unconverged or with such a solve.
    pub flagged: usize,
    /// Steps that ended with the surfaces of two bodies crossing, and the first of them
    /// (1-based) with its crossing edges.
    pub crossed: usize,
    /// `(step, crossing edges)` of the first such step.
    pub first_crossed: Option<(usize, usize)>,
    /// Steps with contacts linearised where they met (`StepStats::swept_pairs`), and
    /// `(step, such contacts)` of the first.
    pub swept: usize,
    /// See `swept`.
    pub first_swept: Option<(usize, usize)>,
    /// Steps that met the tolerance in their first iteration.
    pub one_iteration: usize,
    /// Steps that ended with a joint at one of its limits (a kink of the loss).
    pub at_limit: usize,
    /// The steps' estimated distances from their converged solutions
    /// ([`StepStats::distance_to_converged`]), those with contacts between bodies weighted by
    /// [`super::PAIR_CONTACT_GAP_WEIGHT`], summed, relative to the length scale.
    pub gap: f64,
}

impl Forward {
    /// Bytes of the checkpoints (states, activations, joint states, final contacts).
    pub(crate) fn checkpoint_bytes(&self) -> usize {
        self.q.bytes()
            + self.v.bytes()
            + self.activations.bytes()
            + self.skeleton.bytes()
            + self.joints.bytes()
            + self.contacts.bytes()
    }
}

/// Set the controls of step `step` (activations and torques) on `sim`.
pub(crate) fn set_controls(
    sim: &mut Simulator,
    model: &Model,
    controls: &Controls,
    step: usize,
) -> Result<(), DiffError> {
    if let (Some(acts), Some(act)) = (&controls.activations, &model.actuators) {
        let row = acts.get(step).ok_or_else(|| {
            DiffError::Input(format!(
                "activations given for {} steps, step {} needs one",
                acts.len(),
                step + 1
            ))
        })?;
        if row.len() != act.groups.len() {
            return Err(DiffError::Input(format!(
                "step {}: {} activations for {} actuator groups",
                step + 1,
                row.len(),
                act.groups.len()
            )));
        }
        for (g, a) in row.iter().enumerate() {
            sim.set_activation_of(g, *a)?;
        }
    }
    if let Some(torques) = &controls.torques {
        let sk = model
            .skeleton
            .as_ref()
            .ok_or_else(|| DiffError::Input("torques given, but the model has no skeleton".into()))?;
        let row = torques.get(step).ok_or_else(|| {
            DiffError::Input(format!(
                "torques given for {} steps, step {} needs one",
                torques.len(),
                step + 1
            ))
        })?;
        if row.len() != sk.dofs {
            return Err(DiffError::Input(format!(
                "step {}: {} torques for {} joint coordinates",
                step + 1,
                row.len(),
                sk.dofs
            )));
        }
        if let Some((_, b)) = sk.misplaced_torque(row) {
            return Err(DiffError::Input(format!(
                "step {}: bone '{}' has a {} joint; torques act on one-DoF joints",
                step + 1,
                b.name,
                b.joint.kind()
            )));
        }
        for b in sk.bones.iter().filter(|b| b.joint.dofs() == 1) {
            sim.set_torque_dof(b.dof_offset, Some(row[b.dof_offset]))?;
        }
    }
    Ok(())
}

/// Scratch of the loss terms (their gradients are not needed in the forward pass).
struct LossScratch {
    q: Vec<Vector3<f64>>,
    v: Vec<Vector3<f64>>,
    mass: Vec<f64>,
    joints: Vec<f64>,
}

impl LossScratch {
    fn term(&mut self, model: &Model, loss: &dyn Loss, n: usize, steps: usize, sim: &Simulator, joints: &[f64]) -> f64 {
        let s = sim.state();
        loss.joint_term(model, n, steps, joints, &mut self.joints)
            + loss.term(
                model,
                n,
                steps,
                &s.q,
                &s.v,
                LossGrad {
                    q: &mut self.q,
                    v: &mut self.v,
                    mass: &mut self.mass,
                },
            )
    }
}

/// Run `steps` steps of `sim` (set up for `model` and `settings`, at its initial state) with
/// `controls`, summing `loss`, keeping what `keep` asks for; `progress` hears of every step.
#[allow(clippy::too_many_arguments)]
pub(crate) fn forward(
    sim: &mut Simulator,
    model: &Model,
    settings: &Settings,
    steps: usize,
    controls: &Controls,
    loss: &dyn Loss,
    keep: Keep,
    progress: &mut dyn FnMut(Progress),
) -> Result<Forward, DiffError> {
    let Keep {
        states: keep,
        contacts: record_contacts,
        store_bytes,
    } = keep;
    loss.validate(model)?;
    if let Some((q, v)) = &controls.initial {
        sim.start_from(q, v)?;
    }
    let mut recording = None;
    if record_contacts {
        recording = Some(Recording::new(false));
    }
    let mut storing = keep && !record_contacts && store_bytes > 0;
    if storing {
        // Iterates only: decompositions are ~200 bytes per tet and iteration, and the backward
        // pass redoes them at a fraction of a replay's cost.
        let mut r = Recording::new(true);
        r.keep_decompositions = false;
        recording = Some(r);
    }
    let n = model.n();
    let rows = if keep { steps.saturating_add(1) } else { 1 };
    let groups = model.actuators.as_ref().map_or(0, |a| a.groups.len());
    let dofs = model.skeleton.as_ref().map_or(0, |s| s.dofs);
    let mut skel = Vec::new();
    sim.save_skeleton_state(&mut skel);
    // The trajectory is held for the backward pass: its size comes from `steps`, so it is checked
    // against the machine's memory before anything is reserved for it.
    let row_bytes = (2 * n * std::mem::size_of::<Vector3<f64>>())
        .saturating_add(8 * (skel.len() + groups + dofs))
        .saturating_add(std::mem::size_of::<StepStats>());
    crate::base::memory::check(&format!("{steps} steps of {n} vertices"), rows, row_bytes)?;
    let mut f = Forward {
        loss: 0.0,
        q: Flat::with_capacity(n, rows),
        v: Flat::with_capacity(n, rows),
        time: Vec::with_capacity(rows),
        activations: Flat::with_capacity(groups, steps),
        skeleton: Flat::with_capacity(skel.len(), rows),
        joints: Flat::with_capacity(dofs, if keep { steps } else { 0 }),
        contacts: StepContacts::with_steps(if record_contacts { steps } else { 0 }),
        stored: Vec::with_capacity(if storing { steps } else { 0 }),
        stored_bytes: 0,
        iterations: 0,
        unconverged: 0,
        capped: 0,
        capped_steps: Vec::with_capacity(steps),
        flagged: 0,
        crossed: 0,
        first_crossed: None,
        swept: 0,
        first_swept: None,
        one_iteration: 0,
        at_limit: 0,
        gap: 0.0,
    };
    f.q.push(&sim.state().q);
    f.v.push(&sim.state().v);
    f.time.push(0.0);
    if !skel.is_empty() {
        f.skeleton.push(&skel);
    }
    let mut scratch = LossScratch {
        q: vec![Vector3::zeros(); n],
        v: vec![Vector3::zeros(); n],
        mass: vec![0.0; n],
        joints: vec![0.0; dofs],
    };
    let mut joints = vec![0.0; dofs];
    for k in 0..steps {
        set_controls(sim, model, controls, k)?;
        let st = match recording.as_mut() {
            Some(r) => sim.step_observed(r)?,
            None => sim.step()?,
        };
        f.iterations += st.iterations;
        f.unconverged += usize::from(!st.converged);
        f.capped += usize::from(st.capped_solves > 0);
        f.capped_steps.push(st.capped_solves > 0);
        f.flagged += usize::from(!st.converged || st.capped_solves > 0);
        if st.pair_crossings > 0 {
            f.crossed += 1;
            f.first_crossed.get_or_insert((k + 1, st.pair_crossings));
        }
        if st.swept_pairs > 0 {
            f.swept += 1;
            f.first_swept.get_or_insert((k + 1, st.swept_pairs));
        }
        f.one_iteration += usize::from(st.converged && st.iterations == 1 && settings.tolerance > 0.0);
        // Contacts between bodies carry the stopping error into the derivative amplified.
        let weight = if st.pair_contacts > 0 {
            super::PAIR_CONTACT_GAP_WEIGHT
        } else {
            1.0
        };
        f.gap += st.distance_to_converged() * weight;
        if let Some(sk) = sim.skeleton() {
            joints.iter_mut().for_each(|j| *j = 0.0);
            sk.scalars(&mut joints);
            f.at_limit += usize::from(sk.joints_at_limit() > 0);
        }
        f.loss += scratch.term(model, loss, k + 1, steps, sim, &joints);
        if let Some(a) = sim.activations() {
            f.activations.push(a);
        }
        if keep {
            let s = sim.state();
            f.q.push(&s.q);
            f.v.push(&s.v);
            f.time.push(s.time);
            if !skel.is_empty() {
                skel.clear();
                sim.save_skeleton_state(&mut skel);
                f.skeleton.push(&skel);
            }
            f.joints.push(&joints);
        }
        if storing {
            let r = recording.as_ref().expect("recording enabled");
            let b = r.bytes();
            if f.stored_bytes + b <= store_bytes {
                f.stored_bytes += b;
                f.stored.push(Some(r.snapshot()));
            } else {
                storing = false;
                recording = None;
            }
        }
        if record_contacts {
            let r = recording.as_ref().expect("recording enabled");
            if r.iterative_contacts {
                return Err(DiffError::Unsupported(
                    "contacts were solved by an iterative global solver: gradients with contact need `solver: direct`"
                        .into(),
                ));
            }
            let (cs, imp) = r.last_solve();
            f.contacts.push(cs, imp, steps - k);
        }
        progress(Progress::Forward(k));
    }
    Ok(f)
}
