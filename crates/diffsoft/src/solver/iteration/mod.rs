//! The iteration that solves one contact round of a step: the seam between a step's phases
//! (`step.rs`: inertial target, contacts, velocity update) and the method that minimises the
//! step's energy. Each method is a [`StepIteration`], chosen by value when a run is set up
//! ([`build`]); it keeps only its own scratch (factors, Hessians, search directions) and is
//! handed the run's state for each call in a [`StepContext`], as a physics pipeline is handed
//! the bodies it steps.
//!
//! * [`local_global::LocalGlobal`]: projective dynamics' local-global iterations (Eqs. 3, 5),
//!   with any global solver on the free vertices or the skeleton's reduced step (Eqs. 17-18),
//!   optionally Anderson-accelerated;
//! * [`newton::NewtonIteration`]: Newton's method on the step energy (Eqs. S3-S6);
//! * [`newton_skeletal::NewtonSkeletalIteration`]: Newton's method in the skeleton's reduced
//!   coordinates (Eqs. S7-S9).
//!
//! A later method (quasi-Newton, say) is one more implementation and one more arm of
//! [`build`]; nothing else in the step changes.

pub(crate) mod local_global;
pub(crate) mod newton;
mod newton_cg;

pub(crate) mod newton_contact;
mod newton_rules;
pub(crate) mod newton_skeletal;

use std::time::Instant;

use nalgebra::Vector3;

use super::anderson::Anderson;
use super::assembled::GlobalSystem;
use super::certificate::Certificate;
use super::certify;
use super::choose;
use super::contacts::StepContacts;
use super::direct::Direct;
use super::global::{InnerControl, SolverKind};
use super::integrator::Scheme;
use super::observer::StepObserver;
use super::stationary::Stationary;
use super::system::{CertKey, System};
use super::work::Work;
use super::{Settings, SolverError, StepStats};
use crate::base::Choice;
use crate::constraint::Constraints;
use crate::model::Model;
use crate::skeleton::Skeleton;

use local_global::{GlobalPhase, LocalGlobal, ReducedStep};

/// The run's state an iteration reads and writes: everything but the iteration's own scratch.
pub(crate) struct StepContext<'a> {
    /// The model.
    pub model: &'a Model,
    /// The run's settings.
    pub settings: &'a Settings,
    /// The step's scheme (implicit Euler or BDF2: `h`, `h_e`).
    pub scheme: &'a Scheme,
    /// The global system the iteration's factors were built for.
    pub system: &'a GlobalSystem,
    /// The constraint sets and their buffers (the local step).
    pub constraints: &'a mut Constraints,
    /// The step's activation per actuator group.
    pub activations: &'a [f64],
    /// The step's contacts.
    pub contacts: &'a StepContacts,
    /// The step's buffers: inertial target, right-hand side, iterate.
    pub work: &'a mut Work,
    /// The skeleton in its current state (`None` without bones).
    pub skeleton: Option<&'a mut Skeleton>,
    /// Simulated time at the end of the step (s).
    pub time: f64,
}

impl StepContext<'_> {
    /// Copy the free iterate into the full positions.
    pub(crate) fn scatter_iterate(&mut self) {
        let w = &mut *self.work;
        for (k, &v) in self.system.free.iter().enumerate() {
            w.full[v] = w.x[k];
        }
    }

    /// `tolerance x length scale`: the RMS change of the positions that ends the iteration (m).
    pub(crate) fn tolerance(&self) -> f64 {
        self.settings.absolute_tolerance(self.model)
    }
}

/// A method that solves one contact round of a step from the first iterate `begin_step` set
/// (`work.x`), leaving the result in `work.x` and `work.full`.
pub(crate) trait StepIteration: Send {
    /// Which solver runs.
    fn kind(&self) -> SolverKind;

    /// A step begins (before its first contact round).
    fn begin_step(&mut self) {}

    /// Iterate for the current contact set, adding to `stats` and telling `observer`.
    fn iterate(
        &mut self,
        cx: &mut StepContext<'_>,
        stats: &mut StepStats,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SolverError>;

    /// The contact impulses the last round ended with, one per contact on free vertices in
    /// their order (`None`: an iterative global solver projected them inside its iteration and
    /// keeps none).
    fn impulses(&self) -> Option<&[Vector3<f64>]>;

    /// The contact impulses for output (VTK frames): [`StepIteration::impulses`], or the last
    /// projection's of a solver that keeps none for the backward pass.
    fn contact_impulses(&self) -> Option<&[Vector3<f64>]> {
        self.impulses()
    }
}

/// Certify the requested solver for `system` (or take the certificate issued on it before for
/// the same request) and build the iteration that runs it.
pub(crate) fn build(
    model: &Model,
    settings: &Settings,
    system: &System,
) -> Result<(Box<dyn StepIteration>, Certificate), SolverError> {
    let h = system.h();
    // Models are built only through `ModelBuilder::build`, which refuses collisions between
    // bodies with a skeleton naming the scene's file and a bone.
    debug_assert!(
        model.collision.is_none() || model.skeleton.is_none(),
        "the model builder refuses collisions with a skeleton"
    );
    let control = InnerControl {
        tolerance: settings.inner_absolute_tolerance(model),
        max_iterations: settings.inner_max_iterations,
    };
    if let Some(body) = model.bodies.iter().find(|b| b.model.is_hyperelastic()) {
        // A hyperelastic energy has no projection: only Newton's method minimises it.
        match settings.solver {
            SolverKind::Newton => {}
            SolverKind::Auto => {
                let mut newton = settings.clone();
                newton.solver = SolverKind::Newton;
                let (it, mut cert) = build(model, &newton, system)?;
                cert.requested = SolverKind::Auto;
                cert.message = format!(
                    "auto: Newton's method, the solver of hyperelastic materials (body '{}' is {}); {}",
                    body.name,
                    body.model.name(),
                    cert.message
                );
                return Ok((it, cert));
            }
            other => {
                return Err(SolverError::input(format!(
                    "solver {} cannot handle material model {} (body '{}'): local-global iterations need projective constraints; use solver newton (or auto)",
                    other.name(),
                    body.model.name(),
                    body.name
                )))
            }
        }
    }
    if settings.solver == SolverKind::Newton {
        newton::check_supported(model, settings)?;
        return match &model.skeleton {
            Some(sk) => {
                let t0 = Instant::now();
                let step = ReducedStep::new(system, sk, control)?;
                let it = newton_skeletal::NewtonSkeletalIteration::new(model, system, sk, step, control);
                Ok((Box::new(it), newton_skeletal::certificate(settings, t0)))
            }
            None => {
                let t0 = Instant::now();
                let it = newton::Newton::new(model, system, control)?;
                Ok((Box::new(it), newton::certificate(settings, t0)))
            }
        };
    }
    let key = CertKey {
        solver: settings.solver,
        certify: settings.certify,
        eigen_method: settings.eigen_method,
        inner_max_iterations: settings.inner_max_iterations,
        inner_tolerance: settings.inner_tolerance,
        collision: model.collision.is_some(),
        skeleton: model.skeleton.is_some(),
    };
    let (cert, factored) = system.certified(key, || certify_global(model, settings, system, h, control))?;
    let anderson = (settings.anderson > 0).then(|| Anderson::new(settings.anderson, system.n()));
    let global = match (&model.skeleton, cert.used) {
        (Some(sk), _) => GlobalPhase::Reduced(ReducedStep::new(system, sk, control)?),
        (None, SolverKind::Direct) => GlobalPhase::Free(Box::new(match factored {
            Some(d) => d,
            None => system.direct(control)?,
        })),
        (None, kind) => GlobalPhase::Free(Box::new(Stationary::new(
            system,
            if kind == SolverKind::Chebyshev {
                SolverKind::Split
            } else {
                kind
            },
            cert.relaxation,
            cert.contact_relaxation,
            cert.chebyshev_rho,
            control,
        ))),
    };
    Ok((Box::new(LocalGlobal::new(global, anderson)), cert))
}

/// The direct solver's certificate when `why` forces it on a run that requested another.
fn forced_direct(settings: &Settings, system: &System, h: f64, why: &str) -> Result<Certificate, SolverError> {
    let mut c = certify::certify(
        system,
        h,
        SolverKind::Direct,
        settings.certify,
        settings.eigen_method,
        0,
    )?;
    c.requested = settings.solver;
    c.message = format!("{:?} requested, but {why}: direct sparse Cholesky", settings.solver);
    Ok(c)
}

/// Certify the requested solver (auto: choose it); with auto's choice of direct, its factor.
fn certify_global(
    model: &Model,
    settings: &Settings,
    system: &System,
    h: f64,
    control: InnerControl,
) -> Result<(Certificate, Option<Direct>), SolverError> {
    let requested = settings.solver;
    if model.collision.is_some() && requested != SolverKind::Direct {
        // A contact between two bodies couples several vertices through one impulse: the
        // projected Gauss-Seidel runs on the factored matrix's Delassus operator.
        let why = "contacts between bodies couple several vertices per impulse";
        return Ok((forced_direct(settings, system, h, why)?, None));
    }
    if model.skeleton.is_some() && requested != SolverKind::Direct {
        // The reduced step (Eqs. 17-18) eliminates the free vertices with the factored free
        // block, so a skeleton always runs on the direct solver; no eigenvalue check is needed.
        let why = "the skeleton's reduced step (Eqs. 17-18) factors the free block";
        return Ok((forced_direct(settings, system, h, why)?, None));
    }
    if requested == SolverKind::Auto {
        let base = Certificate::unchecked(requested, settings.certify, h);
        return choose::choose(system, base, settings.eigen_method, settings.inner_tolerance, control);
    }
    let cert = certify::certify(
        system,
        h,
        requested,
        settings.certify,
        settings.eigen_method,
        settings.inner_max_iterations,
    )?;
    Ok((cert, None))
}
