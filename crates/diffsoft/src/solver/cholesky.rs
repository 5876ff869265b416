//! Small dense symmetric positive definite systems, factored and solved in place in caller-owned
//! buffers (no allocation): Anderson's least-squares normal equations and the skeleton's
//! reduced Newton matrix. `a` is `k x k` in row-major order (for a symmetric matrix stored
//! column-major, as nalgebra does, the same calls work on the transpose, which is the matrix).

/// Cholesky `a = L L^T` in place: `L` overwrites the lower triangle (the upper one is not read);
/// `false` if `a` is not positive definite.
pub(crate) fn factor(a: &mut [f64], k: usize) -> bool {
    for j in 0..k {
        let mut d = a[j * k + j];
        for p in 0..j {
            d -= a[j * k + p] * a[j * k + p];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        a[j * k + j] = d;
        for i in j + 1..k {
            let mut v = a[i * k + j];
            for p in 0..j {
                v -= a[i * k + p] * a[j * k + p];
            }
            a[i * k + j] = v / d;
        }
    }
    true
}

/// Solve `L L^T x = b` in place with the factor of [`factor`].
pub(crate) fn solve(l: &[f64], b: &mut [f64], k: usize) {
    for i in 0..k {
        let mut v = b[i];
        for p in 0..i {
            v -= l[i * k + p] * b[p];
        }
        b[i] = v / l[i * k + i];
    }
    for i in (0..k).rev() {
        let mut v = b[i];
        for p in i + 1..k {
            v -= l[p * k + i] * b[p];
        }
        b[i] = v / l[i * k + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-made SPD system is solved; an indefinite one is refused.
    #[test]
    fn solves_a_known_system_and_refuses_an_indefinite_one() {
        let x = [1.0, -2.0, 0.5];
        let a = [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let mut b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum()).collect();
        let mut l = a;
        assert!(factor(&mut l, 3));
        solve(&l, &mut b, 3);
        for (got, want) in b.iter().zip(x) {
            assert!((got - want).abs() < 1e-14, "{got} vs {want}");
        }
        assert!(!factor(&mut [1.0, 2.0, 2.0, 1.0], 2));
    }
}
