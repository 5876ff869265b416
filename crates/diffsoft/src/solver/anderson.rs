//! Anderson acceleration (type II, memory `m`) of the local-global fixed-point iteration
//! `x <- G(x)` (Walker & Ni 2011; used for projective dynamics by Peng et al. 2018).
//!
//! With residuals `f_k = G(x_k) - x_k` and the last `m` differences `dF`, `dG` of residuals and
//! of `G` values, the next iterate is `G(x_k) - dG gamma` with
//! `gamma = argmin |f_k - dF gamma|`. The caller guards it with the step's energy (which the
//! next local step computes anyway) and calls [`Anderson::reset`] when an accelerated iterate
//! raised it. Buffers are allocated once (the small least-squares system too: `mix` does not
//! allocate).

use nalgebra::Vector3;

use super::cholesky;

/// Anderson acceleration state.
#[derive(Debug, Clone)]
pub struct Anderson {
    m: usize,
    df: Vec<Vec<Vector3<f64>>>,
    dg: Vec<Vec<Vector3<f64>>>,
    f_prev: Vec<Vector3<f64>>,
    g_prev: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    /// The normal equations of the least-squares problem, `m x m` row-major, and their
    /// right-hand side (then the solution).
    gram: Vec<f64>,
    gamma: Vec<f64>,
    count: usize,
    next: usize,
    has_prev: bool,
}

impl Anderson {
    /// Memory `m` for iterates of `n` 3-vectors.
    pub fn new(m: usize, n: usize) -> Self {
        Self {
            m,
            df: vec![vec![Vector3::zeros(); n]; m],
            dg: vec![vec![Vector3::zeros(); n]; m],
            f_prev: vec![Vector3::zeros(); n],
            g_prev: vec![Vector3::zeros(); n],
            f: vec![Vector3::zeros(); n],
            gram: vec![0.0; m * m],
            gamma: vec![0.0; m],
            count: 0,
            next: 0,
            has_prev: false,
        }
    }

    /// Forget the history.
    pub fn reset(&mut self) {
        self.count = 0;
        self.next = 0;
        self.has_prev = false;
    }

    /// The last plain update `G(x_k)` (to fall back on).
    pub fn last_plain(&self) -> &[Vector3<f64>] {
        &self.g_prev
    }

    /// Given the iterate `u = x_k` and `g = G(x_k)`, write the accelerated next iterate to `out`.
    pub fn mix(&mut self, u: &[Vector3<f64>], g: &[Vector3<f64>], out: &mut [Vector3<f64>]) {
        for ((f, gi), ui) in self.f.iter_mut().zip(g).zip(u) {
            *f = gi - ui;
        }
        if self.has_prev {
            let slot = self.next;
            let (df, dg) = (&mut self.df[slot], &mut self.dg[slot]);
            for (i, gi) in g.iter().enumerate() {
                df[i] = self.f[i] - self.f_prev[i];
                dg[i] = gi - self.g_prev[i];
            }
            self.next = (self.next + 1) % self.m;
            self.count = (self.count + 1).min(self.m);
        }
        self.f_prev.copy_from_slice(&self.f);
        self.g_prev.copy_from_slice(g);
        self.has_prev = true;
        out.copy_from_slice(g);
        let k = self.count;
        if k == 0 {
            return;
        }
        let dot = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> f64 { a.iter().zip(b).map(|(x, y)| x.dot(y)).sum() };
        let (gram, gamma) = (&mut self.gram[..k * k], &mut self.gamma[..k]);
        for i in 0..k {
            gamma[i] = dot(&self.df[i], &self.f);
            for j in i..k {
                let v = dot(&self.df[i], &self.df[j]);
                gram[i * k + j] = v;
                gram[j * k + i] = v;
            }
        }
        let trace = (0..k).map(|i| gram[i * k + i]).sum::<f64>().max(f64::MIN_POSITIVE);
        for i in 0..k {
            gram[i * k + i] += 1e-10 * trace;
        }
        if !cholesky::factor(gram, k) {
            return;
        }
        cholesky::solve(gram, gamma, k);
        if !gamma.iter().all(|v| v.is_finite()) {
            return;
        }
        let gamma = &self.gamma[..k];
        for (j, c) in gamma.iter().enumerate() {
            for (o, d) in out.iter_mut().zip(&self.dg[j]) {
                *o -= d * *c;
            }
        }
    }
}
