//! Memory and time of the backward pass for growing horizons.

use anyhow::Result;
use serde::Serialize;

use diffsoft::diff::{self, DiffError, Mode, Options};
use diffsoft::testing::Case;

/// Memory and time of the backward pass for growing horizons.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct MemoryPoint {
    /// Scene.
    pub scene: String,
    /// Steps.
    pub steps: usize,
    /// Mode.
    pub mode: Mode,
    /// Budget for keeping whole steps' recordings instead of replaying them (bytes; 0: pure
    /// checkpointing, as the paper).
    pub store_budget_bytes: usize,
    /// Steps kept (not replayed).
    pub stored_steps: usize,
    /// Bytes of kept recordings.
    pub stored_bytes: usize,
    /// Bytes of checkpoints.
    pub checkpoint_bytes: usize,
    /// Peak heap growth during the gradient evaluation, which runs on one thread (bytes,
    /// counted on that thread, so other work running meanwhile does not show, and after the
    /// thread's lifetime buffers of the dense kernels are reserved; `null` without the counting
    /// allocator of the `diffsoft` binary).
    pub peak_heap_bytes: Option<usize>,
    /// Forward (ms).
    pub forward_ms: f64,
    /// Backward (ms).
    pub backward_ms: f64,
    /// Backward / forward (1).
    pub ratio: f64,
    /// Wall-clock runs made of this point; the times above are those of the run with the
    /// median ratio (three for the points a cost verdict reads, one otherwise).
    pub timed_runs: usize,
}

/// Memory and time of the backward pass on `case` over `steps` steps, measured on the calling
/// thread ([`diffsoft::alloc::thread_peak`]): run it single-threaded (a [`crate::pool`] task).
pub fn memory_point(case: &Case, steps: usize, opts: Options) -> Result<MemoryPoint, DiffError> {
    let mut controls = case.controls.clone();
    if let Some(t) = controls.torques.as_mut() {
        // Hold the last torques for longer horizons.
        let last = t.last().cloned().unwrap_or_default();
        t.resize(steps, last);
    }
    // The thread's lifetime buffers of the dense kernels first: they are not the gradient's.
    diffsoft::alloc::reserve_thread_buffers();
    let (g, peak) = diffsoft::alloc::thread_peak(|| {
        diff::gradient(&case.model, &case.settings, steps, &controls, case.loss.as_ref(), opts)
    });
    let g = g?;
    Ok(MemoryPoint {
        scene: case.name.clone(),
        steps,
        mode: opts.mode,
        store_budget_bytes: opts.store_bytes,
        stored_steps: g.stats.stored_steps,
        stored_bytes: g.stats.stored_bytes,
        checkpoint_bytes: g.stats.checkpoint_bytes,
        peak_heap_bytes: peak,
        forward_ms: g.stats.forward_ms,
        backward_ms: g.stats.backward_ms,
        ratio: g.stats.backward_ms / g.stats.forward_ms,
        timed_runs: 1,
    })
}
