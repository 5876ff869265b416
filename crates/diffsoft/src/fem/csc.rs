//! A symmetric sparse matrix in compressed-column form with both triangles stored.

use rayon::prelude::*;

/// Symmetric `n x n` matrix, both triangles stored, rows sorted within each column.
#[derive(Debug, Clone, PartialEq)]
pub struct SymCsc {
    /// Dimension.
    pub n: usize,
    /// Column pointers, length `n + 1`.
    pub col_ptr: Vec<usize>,
    /// Row indices.
    pub row_idx: Vec<usize>,
    /// Values.
    pub values: Vec<f64>,
}

impl SymCsc {
    /// The diagonal.
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.n)
            .map(|j| {
                (self.col_ptr[j]..self.col_ptr[j + 1])
                    .find(|&k| self.row_idx[k] == j)
                    .map_or(0.0, |k| self.values[k])
            })
            .collect()
    }

    /// Entries `(i, v)` of column `j` (equal to row `j`).
    pub fn column(&self, j: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        (self.col_ptr[j]..self.col_ptr[j + 1]).map(move |k| (self.row_idx[k], self.values[k]))
    }

    /// `y = A x`; each entry is a gather over one column (the matrix is symmetric), in parallel
    /// for large `n`.
    pub fn matvec(&self, x: &[f64], y: &mut [f64]) {
        let row = |j: usize| -> f64 {
            let mut s = 0.0;
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                s += self.values[k] * x[self.row_idx[k]];
            }
            s
        };
        if self.n >= 20_000 {
            y.par_iter_mut().enumerate().for_each(|(j, yj)| *yj = row(j));
        } else {
            for (j, yj) in y.iter_mut().enumerate() {
                *yj = row(j);
            }
        }
    }

    /// `y = A x` for three right-hand sides stored as 3-vectors (the per-axis matrix applied
    /// to x, y and z at once); parallel for large `n`.
    #[inline]
    pub fn matvec3(&self, x: &[nalgebra::Vector3<f64>], y: &mut [nalgebra::Vector3<f64>]) {
        self.map_rows3(x, y, |_, s| s);
    }

    /// `out[j] = f(j, (A x)_j)` for three right-hand sides stored as 3-vectors, so a caller
    /// consumes each product where it is made instead of storing and re-reading it; parallel
    /// for large `n` when the pool has several threads. Each `(A x)_j` is summed over its
    /// column in storage order (the same bits as a plain loop), four columns interleaved so
    /// their twelve sums are independent chains instead of three.
    #[inline]
    pub(crate) fn map_rows3<T: Send>(
        &self,
        x: &[nalgebra::Vector3<f64>],
        out: &mut [T],
        f: impl Fn(usize, nalgebra::Vector3<f64>) -> T + Sync,
    ) {
        assert_eq!(out.len(), self.n, "map_rows3: output length");
        let threads = rayon::current_num_threads();
        if self.n >= 8_000 && threads > 1 {
            // About four blocks per thread (so sixteen threads still share a 10k-row matrix),
            // a multiple of four rows each and never so small that scheduling dominates.
            let block = (self.n / (4 * threads)).clamp(256, 4096) & !3;
            out.par_chunks_mut(block)
                .enumerate()
                .for_each(|(c, o)| self.rows3_into(c * block, x, o, &f));
        } else {
            self.rows3_into(0, x, out, &f);
        }
    }

    /// Rows `j0 .. j0 + out.len()` of [`Self::map_rows3`].
    #[inline(always)]
    fn rows3_into<T>(
        &self,
        j0: usize,
        x: &[nalgebra::Vector3<f64>],
        out: &mut [T],
        f: &impl Fn(usize, nalgebra::Vector3<f64>) -> T,
    ) {
        type V3 = nalgebra::Vector3<f64>;
        let (ptr, idx, val) = (&self.col_ptr[..], &self.row_idx[..], &self.values[..]);
        // The rest of a column's sum, in storage order.
        let tail = |mut s: V3, ir: &[usize], vr: &[f64]| {
            for (&i, &v) in ir.iter().zip(vr) {
                s += v * x[i];
            }
            s
        };
        let mut chunks = out.chunks_exact_mut(4);
        let mut j = j0;
        for o in &mut chunks {
            let col = |r: usize| {
                let (a, b) = (ptr[j + r], ptr[j + r + 1]);
                (&idx[a..b], &val[a..b])
            };
            let ((i0, v0), (i1, v1), (i2, v2), (i3, v3)) = (col(0), col(1), col(2), col(3));
            let common = i0.len().min(i1.len()).min(i2.len()).min(i3.len());
            let (mut s0, mut s1, mut s2, mut s3) = (V3::zeros(), V3::zeros(), V3::zeros(), V3::zeros());
            for t in 0..common {
                s0 += v0[t] * x[i0[t]];
                s1 += v1[t] * x[i1[t]];
                s2 += v2[t] * x[i2[t]];
                s3 += v3[t] * x[i3[t]];
            }
            o[0] = f(j, tail(s0, &i0[common..], &v0[common..]));
            o[1] = f(j + 1, tail(s1, &i1[common..], &v1[common..]));
            o[2] = f(j + 2, tail(s2, &i2[common..], &v2[common..]));
            o[3] = f(j + 3, tail(s3, &i3[common..], &v3[common..]));
            j += 4;
        }
        for o in chunks.into_remainder() {
            let (a, b) = (ptr[j], ptr[j + 1]);
            *o = f(j, tail(V3::zeros(), &idx[a..b], &val[a..b]));
            j += 1;
        }
    }

    /// The principal submatrix of the rows/columns with `keep[i]`, and the kept indices.
    ///
    /// ```
    /// use diffsoft::fem::StiffnessPattern;
    ///
    /// let p = StiffnessPattern::new(4, &[[0, 1, 2, 3]]);
    /// let values: Vec<f64> = (0..p.nnz()).map(|k| k as f64).collect();
    /// let m = p.to_sym_csc(values);
    /// let (sub, kept) = m.principal_submatrix(&[true, false, true, false]);
    /// assert_eq!(kept, vec![0, 2]);
    /// assert_eq!((sub.n, sub.values.len()), (2, 4));
    /// assert_eq!(sub.diagonal(), vec![m.diagonal()[0], m.diagonal()[2]]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn principal_submatrix(&self, keep: &[bool]) -> (SymCsc, Vec<usize>) {
        let mut new_index = vec![usize::MAX; self.n];
        let kept: Vec<usize> = (0..self.n).filter(|&i| keep[i]).collect();
        for (k, &i) in kept.iter().enumerate() {
            new_index[i] = k;
        }
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        for &j in &kept {
            for (i, v) in self.column(j) {
                if keep[i] {
                    row_idx.push(new_index[i]);
                    values.push(v);
                }
            }
            col_ptr.push(row_idx.len());
        }
        (
            SymCsc {
                n: kept.len(),
                col_ptr,
                row_idx,
                values,
            },
            kept,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::SymCsc;
    use nalgebra::Vector3;

    /// A symmetric pattern whose columns have different lengths (a band of varying width plus
    /// a dense first row and column), with irrational-looking values so summation order shows.
    fn irregular(n: usize) -> SymCsc {
        let mut cols: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
        let val = |i: usize, j: usize| ((i * 7 + j * 13) as f64 * 0.618_033_988_75).sin() + 1e-3 * (i + j) as f64;
        for (j, col) in cols.iter_mut().enumerate() {
            // Candidates: all rows for column 0, else row 0 and a band around the diagonal.
            let mut rows: Vec<usize> = if j == 0 {
                (0..n).collect()
            } else {
                std::iter::once(0).chain(j.saturating_sub(6)..(j + 7).min(n)).collect()
            };
            rows.dedup();
            for i in rows {
                let (lo, hi) = (i.min(j), i.max(j));
                if lo == 0 || hi - lo <= 1 + lo % 5 {
                    col.push((i, val(lo, hi)));
                }
            }
        }
        let (mut col_ptr, mut row_idx, mut values) = (vec![0], Vec::new(), Vec::new());
        for c in cols {
            for (i, v) in c {
                row_idx.push(i);
                values.push(v);
            }
            col_ptr.push(row_idx.len());
        }
        SymCsc {
            n,
            col_ptr,
            row_idx,
            values,
        }
    }

    /// The plain per-column sum `matvec3` must reproduce bit for bit.
    fn plain(a: &SymCsc, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        (0..a.n)
            .map(|j| {
                let mut s = Vector3::zeros();
                for (i, v) in a.column(j) {
                    s += v * x[i];
                }
                s
            })
            .collect()
    }

    fn check(n: usize) {
        let a = irregular(n);
        let x: Vec<_> = (0..n)
            .map(|i| {
                Vector3::new(
                    (i as f64 * 0.37).cos(),
                    (i as f64 * 1.3).sin() * 1e3,
                    1.0 / (1.0 + i as f64),
                )
            })
            .collect();
        let want = plain(&a, &x);
        let mut y = vec![Vector3::zeros(); n];
        a.matvec3(&x, &mut y);
        for (j, (g, w)) in y.iter().zip(&want).enumerate() {
            for k in 0..3 {
                assert_eq!(g[k].to_bits(), w[k].to_bits(), "n {n} row {j} axis {k}");
            }
        }
        // map_rows3 hands each row its own index and product.
        let mut tagged = vec![(0usize, Vector3::zeros()); n];
        a.map_rows3(&x, &mut tagged, |j, s| (j, s));
        for (j, (i, s)) in tagged.iter().enumerate() {
            assert_eq!(*i, j);
            assert_eq!(*s, want[j]);
        }
    }

    #[test]
    fn matvec3_is_the_plain_column_sum_bit_for_bit() {
        // Sizes not multiples of four, below and above the parallel threshold (8 000 rows;
        // on three threads 680-row blocks, the last one partial).
        for n in [1, 2, 3, 5, 6, 7, 9, 30, 1027] {
            check(n);
        }
        let serial = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let parallel = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        serial.install(|| check(8_195));
        parallel.install(|| check(8_195));
    }
}
