//! The sparsity pattern of the per-axis stiffness matrix, built once per mesh topology.

use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use rayon::prelude::*;

use super::SymCsc;

/// Compressed-column pattern of an `n x n` matrix coupling the vertices of each tet, with both
/// triangles stored and rows sorted within each column, plus for each tet the 16 value slots of
/// its local 4 x 4 block (row-major: slot `4a + b` is entry `(tet[a], tet[b])`).
#[derive(Debug, Clone)]
pub struct StiffnessPattern {
    /// Matrix dimension (number of vertices).
    pub n: usize,
    /// Column pointers, length `n + 1`.
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column.
    pub row_idx: Vec<usize>,
    /// Position of the diagonal entry of each column in `row_idx`.
    pub diag_slot: Vec<usize>,
    /// Per-tet value slots.
    pub tet_slots: Vec<[u32; 16]>,
}

impl StiffnessPattern {
    /// Build the pattern for `n` vertices and the given tets (sorting in parallel). Every
    /// vertex has a diagonal entry, also one that no tet uses.
    ///
    /// ```
    /// use diffsoft::fem::StiffnessPattern;
    ///
    /// // One tet on vertices 0..4, and vertex 4 that no tet uses.
    /// let p = StiffnessPattern::new(5, &[[0, 1, 2, 3]]);
    /// assert_eq!(p.nnz(), 16 + 1);
    /// assert_eq!(p.col_ptr.len(), 6);
    /// assert_eq!(p.row_idx[p.diag_slot[4]], 4);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(n: usize, tets: &[[usize; 4]]) -> Self {
        Self::with_cliques(n, tets, &[]).0
    }

    /// The pattern of the tets and of further elements coupling arbitrary vertex sets
    /// (cliques: cloth triangles, bending stencils), with each clique's `k x k` value slots
    /// (row-major).
    ///
    /// ```
    /// use diffsoft::fem::StiffnessPattern;
    ///
    /// // A tet and a triangle that shares an edge with it.
    /// let (p, slots) = StiffnessPattern::with_cliques(5, &[[0, 1, 2, 3]], &[&[2, 3, 4]]);
    /// assert_eq!(p.nnz(), 16 + 5); // vertex 4's diagonal and its couplings to 2 and 3
    /// assert_eq!(slots.len(), 1);
    /// assert_eq!(slots[0].len(), 9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_cliques(n: usize, tets: &[[usize; 4]], cliques: &[&[usize]]) -> (Self, Vec<Vec<u32>>) {
        let mut keys: Vec<u64> = tets
            .par_iter()
            .flat_map_iter(|t| {
                (0..16).map(move |s| {
                    let (row, col) = (t[s / 4] as u64, t[s % 4] as u64);
                    (col << 32) | row
                })
            })
            .collect();
        for c in cliques {
            for &a in *c {
                for &b in *c {
                    keys.push(((b as u64) << 32) | a as u64);
                }
            }
        }
        keys.extend((0..n as u64).map(|j| (j << 32) | j));
        keys.par_sort_unstable();
        keys.dedup();
        assert!(
            keys.len() < u32::MAX as usize && n < u32::MAX as usize,
            "mesh too large for 32-bit pattern slots"
        );
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::with_capacity(keys.len());
        for &k in &keys {
            col_ptr[(k >> 32) as usize + 1] += 1;
            row_idx.push((k & 0xffff_ffff) as usize);
        }
        for j in 0..n {
            col_ptr[j + 1] += col_ptr[j];
        }
        let find = |row: usize, col: usize| -> u32 {
            let (lo, hi) = (col_ptr[col], col_ptr[col + 1]);
            (lo + row_idx[lo..hi]
                .binary_search(&row)
                .expect("pattern holds every element entry")) as u32
        };
        let diag_slot: Vec<usize> = (0..n).map(|j| find(j, j) as usize).collect();
        let tet_slots = tets
            .par_iter()
            .map(|t| std::array::from_fn(|s| find(t[s / 4], t[s % 4])))
            .collect();
        let clique_slots = cliques
            .iter()
            .map(|c| c.iter().flat_map(|&a| c.iter().map(move |&b| find(a, b))).collect())
            .collect();
        (
            Self {
                n,
                col_ptr,
                row_idx,
                diag_slot,
                tet_slots,
            },
            clique_slots,
        )
    }

    /// Number of stored entries.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Diagonal of a matrix with this pattern.
    pub fn diagonal(&self, values: &[f64]) -> Vec<f64> {
        self.diag_slot.iter().map(|&k| values[k]).collect()
    }

    /// The matrix with these values as a [`SymCsc`] (copies the pattern).
    ///
    /// ```
    /// use diffsoft::fem::StiffnessPattern;
    ///
    /// let p = StiffnessPattern::new(4, &[[0, 1, 2, 3]]);
    /// let m = p.to_sym_csc(vec![1.0; p.nnz()]);
    /// assert_eq!(m.n, 4);
    /// assert_eq!(m.diagonal(), vec![1.0; 4]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn to_sym_csc(&self, values: Vec<f64>) -> SymCsc {
        assert_eq!(values.len(), self.nnz());
        SymCsc {
            n: self.n,
            col_ptr: self.col_ptr.clone(),
            row_idx: self.row_idx.clone(),
            values,
        }
    }

    /// Wrap values in a faer sparse matrix (copies the pattern).
    pub fn to_faer(&self, values: Vec<f64>) -> SparseColMat<usize, f64> {
        let symbolic =
            SymbolicSparseColMat::new_checked(self.n, self.n, self.col_ptr.clone(), None, self.row_idx.clone());
        SparseColMat::new(symbolic, values)
    }
}
