//! Small dense general systems (the active-set method's contact equations, a few hundred
//! unknowns), solved by faer's blocked LU with partial pivoting in a caller-owned matrix. The
//! permutation and the workspace grow to the largest system seen and are reused, so a solve of
//! a size seen before allocates nothing.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::perm::PermRef;
use faer::{MatMut, MatRef, Par};

/// A pivot this small against the matrix's largest entry marks the system as singular.
const SINGULAR_PIVOT: f64 = 1e-13;

/// Workspace of [`DenseLu::solve`].
#[derive(Default)]
pub(crate) struct DenseLu {
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    mem: Option<MemBuffer>,
    /// The system size `mem` was sized for.
    capacity: usize,
}

impl std::fmt::Debug for DenseLu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DenseLu").field("capacity", &self.capacity).finish()
    }
}

impl Clone for DenseLu {
    /// A fresh workspace (it holds no state between solves).
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl DenseLu {
    /// Solve the row-major `k x k` system `a x = rhs` in place (`a` is overwritten by its
    /// factor, `rhs` by the solution). False if a pivot is negligible against the largest
    /// entry or the matrix is not finite.
    pub(crate) fn solve(&mut self, a: &mut [f64], rhs: &mut [f64], k: usize) -> bool {
        self.factor(a, k) && self.solve_factored(a, rhs, k)
    }

    /// Factor the row-major `k x k` matrix `a` in place; its factor (and this workspace's
    /// permutation) then solve any number of right-hand sides with
    /// [`DenseLu::solve_factored`]. False if a pivot is negligible against the largest entry
    /// or the matrix is not finite.
    pub(crate) fn factor(&mut self, a: &mut [f64], k: usize) -> bool {
        if k == 0 {
            return true;
        }
        let scale = a[..k * k].iter().fold(0.0f64, |s, v| s.max(v.abs()));
        if !(scale > 0.0 && scale.is_finite()) {
            return false;
        }
        if k > self.capacity || self.mem.is_none() {
            let req = StackReq::any_of(&[
                factor::lu_in_place_scratch::<usize, f64>(k, k, Par::Seq, Default::default()),
                solve::solve_transpose_in_place_scratch::<usize, f64>(k, 1, Par::Seq),
            ]);
            self.mem = Some(MemBuffer::new(req));
            self.perm.resize(k, 0);
            self.perm_inv.resize(k, 0);
            self.capacity = k;
        }
        let mem = self.mem.as_mut().expect("sized above");
        // The row-major matrix read column-major is its transpose: factor `A^T = P^T L U` and
        // solve `A x = b` as the transposed system of that factor.
        let mut at = MatMut::from_column_major_slice_mut(&mut a[..k * k], k, k);
        factor::lu_in_place(
            at.as_mut(),
            &mut self.perm[..k],
            &mut self.perm_inv[..k],
            Par::Seq,
            MemStack::new(mem),
            Default::default(),
        );
        !(0..k).any(|i| at[(i, i)].abs().is_nan() || at[(i, i)].abs() <= SINGULAR_PIVOT * scale)
    }

    /// Solve `a x = rhs` in place with the factor [`DenseLu::factor`] left in `lu` (the last
    /// matrix this workspace factored, of size `k`). False if the solution is not finite.
    pub(crate) fn solve_factored(&mut self, lu: &[f64], rhs: &mut [f64], k: usize) -> bool {
        if k == 0 {
            return true;
        }
        let Some(mem) = self.mem.as_mut().filter(|_| k <= self.capacity) else {
            return false;
        };
        let lu = MatRef::from_column_major_slice(&lu[..k * k], k, k);
        let perm = PermRef::new_checked(&self.perm[..k], &self.perm_inv[..k], k);
        solve::solve_transpose_in_place(
            lu,
            lu,
            perm,
            MatMut::from_column_major_slice_mut(&mut rhs[..k], k, 1),
            Par::Seq,
            MemStack::new(mem),
        );
        rhs[..k].iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn residual(a: &[f64], x: &[f64], b: &[f64]) -> f64 {
        let k = x.len();
        (0..k)
            .map(|r| ((0..k).map(|c| a[r * k + c] * x[c]).sum::<f64>() - b[r]).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn solves_a_system_that_needs_pivoting() {
        let a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x = [1.0, -2.0, 0.5];
        let b: Vec<f64> = (0..3).map(|r| (0..3).map(|c| a[r * 3 + c] * x[c]).sum()).collect();
        let (mut f, mut u) = (a.clone(), b.clone());
        assert!(DenseLu::default().solve(&mut f, &mut u, 3));
        for (u, v) in u.iter().zip(x) {
            assert!((u - v).abs() < 1e-14, "{u} vs {v}");
        }
    }

    /// One factor solves several right-hand sides, each to the same accuracy as a fresh
    /// factor-and-solve.
    #[test]
    fn one_factor_solves_several_right_hand_sides() {
        let k = 70usize;
        let a: Vec<f64> = (0..k * k)
            .map(|i| {
                let (r, c) = (i / k, i % k);
                ((r * 7 + c * 29) % 11) as f64 / 11.0 - 0.5 + if r == c { 3.0 } else { 0.0 }
            })
            .collect();
        let mut lu = DenseLu::default();
        let mut f = a.clone();
        assert!(lu.factor(&mut f, k));
        for shift in [0.0, 1.3, -4.0] {
            let x: Vec<f64> = (0..k).map(|i| (i as f64 * 0.21 + shift).cos()).collect();
            let b: Vec<f64> = (0..k).map(|r| (0..k).map(|c| a[r * k + c] * x[c]).sum()).collect();
            let mut u = b.clone();
            assert!(lu.solve_factored(&f, &mut u, k));
            assert!(residual(&a, &u, &b) < 1e-13, "{}", residual(&a, &u, &b));
            let mut fresh = (a.clone(), b.clone());
            assert!(DenseLu::default().solve(&mut fresh.0, &mut fresh.1, k));
            assert!(u.iter().zip(&fresh.1).all(|(p, q)| (p - q).abs() < 1e-13));
        }
    }

    /// A non-symmetric system larger than faer's block size, solved twice with one workspace
    /// (the second time at a smaller size), and a singular one refused.
    #[test]
    fn solves_blocked_sizes_and_refuses_singular_systems() {
        let mut lu = DenseLu::default();
        for k in [150usize, 37] {
            let a: Vec<f64> = (0..k * k)
                .map(|i| {
                    let (r, c) = (i / k, i % k);
                    ((r * 31 + c * 17) % 13) as f64 / 13.0 - 0.4 + if r == c { 2.0 } else { 0.0 }
                })
                .collect();
            let x: Vec<f64> = (0..k).map(|i| (i as f64 * 0.37).sin()).collect();
            let b: Vec<f64> = (0..k).map(|r| (0..k).map(|c| a[r * k + c] * x[c]).sum()).collect();
            let (mut f, mut u) = (a.clone(), b.clone());
            assert!(lu.solve(&mut f, &mut u, k));
            assert!(residual(&a, &u, &b) < 1e-12, "k = {k}: {}", residual(&a, &u, &b));
        }
        let mut singular = vec![1.0, 2.0, 2.0, 4.0];
        let mut b = vec![1.0, 2.0];
        assert!(!lu.solve(&mut singular, &mut b, 2));
        let mut nan = vec![1.0, f64::NAN, 0.0, 1.0];
        assert!(!lu.solve(&mut nan, &mut b, 2));
    }
}
