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
        let row = |j: usize| -> nalgebra::Vector3<f64> {
            let (a, b) = (self.col_ptr[j], self.col_ptr[j + 1]);
            let mut s = nalgebra::Vector3::zeros();
            for (&i, &v) in self.row_idx[a..b].iter().zip(&self.values[a..b]) {
                s += v * x[i];
            }
            s
        };
        if self.n >= 8_000 {
            y.par_iter_mut().enumerate().for_each(|(j, yj)| *yj = row(j));
        } else {
            for (j, yj) in y.iter_mut().enumerate() {
                *yj = row(j);
            }
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
