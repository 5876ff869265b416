//! The shared global system of a model at one step size ([`System`]): the assembled matrix
//! ([`GlobalSystem`]), its sparse Cholesky factor and the certificates issued on it, built
//! once and used by a run's iterations, its backward pass, its replays and other runs on the
//! same matrix ([`Systems`]).

use std::ops::Deref;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};
use std::time::Instant;

use super::assembled::GlobalSystem;
use super::certificate::{Certificate, CertifyPolicy};
use super::direct::{CholeskyFactor, Direct};
use super::global::{InnerControl, SolverKind};
use super::SolverError;
use crate::analysis::spectral::EigenMethod;
use crate::analysis::{split_extremes, IterationSystem};
use crate::model::Model;

/// A model's global system at one step size, shared: the assembled `M/h^2 + L` (Eq. 5,
/// [`GlobalSystem`], which it dereferences to), its sparse Cholesky factor (computed on first
/// use) and the results of certifying iterations on it (the extremes of `G21` per
/// eigensolver). A run's iterations, its backward pass and its replays hold it by `Arc`; runs
/// of the same model and step size share it through [`Systems`].
pub(crate) struct System {
    global: GlobalSystem,
    /// The step `h_e` the matrix is assembled for (s).
    h: f64,
    /// The factor and the time it took to compute (ms).
    factor: OnceLock<Result<(Arc<CholeskyFactor>, f64), SolverError>>,
    /// `(eigensolver, (smallest, largest))` eigenvalues of `G21` computed so far.
    extremes: Mutex<Vec<(EigenMethod, (f64, f64))>>,
    /// The certificates issued on this system, by what they read besides it.
    certificates: Mutex<Vec<(CertKey, Certificate)>>,
    /// How many times the extremes of `G21` were computed (tests).
    #[cfg(test)]
    extremes_computed: std::sync::atomic::AtomicUsize,
}

/// What certifying a solver reads besides the system: the request, how it is checked, and the
/// model features that force the direct solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CertKey {
    /// The requested solver.
    pub solver: SolverKind,
    /// The certification policy.
    pub certify: CertifyPolicy,
    /// The eigensolver.
    pub eigen_method: EigenMethod,
    /// The inner iteration cap.
    pub inner_max_iterations: usize,
    /// The inner tolerance (relative).
    pub inner_tolerance: f64,
    /// The model has collisions between bodies.
    pub collision: bool,
    /// The model has a skeleton.
    pub skeleton: bool,
}

impl std::fmt::Debug for System {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("System")
            .field("free", &self.global.n())
            .field("h", &self.h)
            .field("factored", &self.factor.get().is_some())
            .finish()
    }
}

impl Deref for System {
    type Target = GlobalSystem;
    fn deref(&self) -> &GlobalSystem {
        &self.global
    }
}

impl System {
    fn from_global(global: GlobalSystem, h: f64) -> Self {
        Self {
            global,
            h,
            factor: OnceLock::new(),
            extremes: Mutex::new(Vec::new()),
            certificates: Mutex::new(Vec::new()),
            #[cfg(test)]
            extremes_computed: std::sync::atomic::AtomicUsize::new(0),
        }
    }

    /// The step the matrix is assembled for (s).
    pub(crate) fn h(&self) -> f64 {
        self.h
    }

    /// The sparse Cholesky factor (computed on the first call) and the time its computation
    /// took (ms).
    pub(crate) fn factor(&self) -> Result<(Arc<CholeskyFactor>, f64), SolverError> {
        self.factor
            .get_or_init(|| {
                let t0 = Instant::now();
                let f = CholeskyFactor::new(&self.global)?;
                Ok((Arc::new(f), t0.elapsed().as_secs_f64() * 1e3))
            })
            .clone()
    }

    /// A direct solver on the shared factor.
    pub(crate) fn direct(&self, control: InnerControl) -> Result<Direct, SolverError> {
        let (f, _) = self.factor()?;
        Ok(Direct::with_factor(f, self.global.n(), control))
    }

    /// The matrices of the paper's iterations on this system (Eqs. 19, 21).
    pub(crate) fn iteration_system(&self) -> Result<IterationSystem, SolverError> {
        let g = &self.global;
        IterationSystem::from_parts(g.l.clone(), g.mass.clone(), g.attachment.clone())
            .map_err(|e| SolverError::input(e.to_string()))
    }

    /// The smallest and largest eigenvalue of `G21` with eigensolver `method`, computed once
    /// per eigensolver and kept with the system. The computation holds the system's lock, so
    /// runs that ask at once wait for one computation instead of each repeating it (on a
    /// 52 728-tet mesh it takes about 5 s).
    pub(crate) fn split_extremes(&self, method: EigenMethod) -> Result<(f64, f64), SolverError> {
        let mut known = self.extremes.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(&(_, p)) = known.iter().find(|(m, _)| *m == method) {
            return Ok(p);
        }
        let pair = split_extremes(&self.iteration_system()?, self.h, method)
            .map_err(|e| SolverError::Certification(e.to_string()))?;
        #[cfg(test)]
        self.extremes_computed
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        known.push((method, pair));
        Ok(pair)
    }
}

impl System {
    /// The certificate for `key`: the one issued before on this system, or `certify()`'s
    /// (then kept), with the direct solver `certify` factored for it, if any.
    pub(crate) fn certified(
        &self,
        key: CertKey,
        certify: impl FnOnce() -> Result<(Certificate, Option<Direct>), SolverError>,
    ) -> Result<(Certificate, Option<Direct>), SolverError> {
        let known = self
            .certificates
            .lock()
            .ok()
            .and_then(|c| c.iter().find(|(k, _)| *k == key).map(|(_, c)| c.clone()));
        if let Some(c) = known {
            return Ok((c, None));
        }
        let (cert, direct) = certify()?;
        if let Ok(mut c) = self.certificates.lock() {
            c.push((key, cert.clone()));
        }
        Ok((cert, direct))
    }
}

/// Largest number of systems a [`Systems`] keeps (the oldest is dropped first).
const SYSTEMS_KEPT: usize = 8;

/// The systems of one model's runs, shared: [`Simulator::with_systems`](super::Simulator::with_systems)
/// assembles its matrix and takes the `System` built earlier for an identical matrix and step
/// (its factor and certification results with it) instead of factoring and certifying again.
/// A sweep over solver settings, or a finite-difference check that runs the same scene many
/// times, holds one.
///
/// ```
/// use diffsoft::solver::Systems;
/// let systems = Systems::new();
/// assert_eq!(systems.len(), 0);
/// ```
#[derive(Debug, Clone, Default)]
pub struct Systems {
    entries: Arc<Mutex<Vec<Arc<System>>>>,
}

impl Systems {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// How many systems it holds.
    pub fn len(&self) -> usize {
        self.entries.lock().map_or(0, |e| e.len())
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The system of `model` at step `h`: a held one whose assembled matrix is identical, or a
    /// new one (then held).
    pub(crate) fn get(&self, model: &Model, h: f64) -> Result<Arc<System>, SolverError> {
        let global = GlobalSystem::new(model, h)?;
        let Ok(mut entries) = self.entries.lock() else {
            return Ok(Arc::new(System::from_global(global, h)));
        };
        if let Some(s) = entries
            .iter()
            .find(|s| s.h.to_bits() == h.to_bits() && s.global == global)
        {
            return Ok(Arc::clone(s));
        }
        let s = Arc::new(System::from_global(global, h));
        if entries.len() >= SYSTEMS_KEPT {
            entries.remove(0);
        }
        entries.push(Arc::clone(&s));
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs that ask a shared system for the extremes of `G21` at once get the same pair from
    /// one computation (the trade-off sweep starts several runs per step size together).
    #[test]
    fn concurrent_requests_for_the_extremes_compute_them_once() {
        let model = crate::model::fixtures::free_box([4, 2, 2], [0.4, 0.1, 0.1]).unwrap();
        let systems = Systems::new();
        let sys = systems.get(&model, 1e-2).unwrap();
        let start = std::sync::Barrier::new(4);
        let pairs: Vec<(f64, f64)> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    s.spawn(|| {
                        start.wait();
                        sys.split_extremes(EigenMethod::Dense).unwrap()
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(pairs.iter().all(|p| p == &pairs[0]), "{pairs:?}");
        assert!(pairs[0].0 < pairs[0].1 && pairs[0].1 < 1.0, "{pairs:?}");
        assert_eq!(sys.extremes_computed.load(std::sync::atomic::Ordering::Relaxed), 1);
        // A later run on the same system (through the set) reads the kept pair.
        let again = systems.get(&model, 1e-2).unwrap();
        assert_eq!(again.split_extremes(EigenMethod::Dense).unwrap(), pairs[0]);
        assert_eq!(sys.extremes_computed.load(std::sync::atomic::Ordering::Relaxed), 1);
    }
}
