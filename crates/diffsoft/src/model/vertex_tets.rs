//! Vertex-to-tet adjacency.

/// For each vertex, the tets that contain it and its local index there (CSR).
#[derive(Debug, Clone)]
pub struct VertexTets {
    /// Offsets, length `n + 1`.
    pub offsets: Vec<usize>,
    /// `(tet, local corner)` pairs.
    pub entries: Vec<(u32, u8)>,
}

impl VertexTets {
    pub(crate) fn new(n: usize, tets: &[[usize; 4]]) -> Self {
        let mut count = vec![0usize; n + 1];
        for t in tets {
            for &v in t {
                count[v + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut entries = vec![(0u32, 0u8); count[n]];
        for (ti, t) in tets.iter().enumerate() {
            for (a, &v) in t.iter().enumerate() {
                entries[fill[v]] = (ti as u32, a as u8);
                fill[v] += 1;
            }
        }
        Self {
            offsets: count,
            entries,
        }
    }

    /// The `(tet, corner)` pairs of vertex `v`.
    pub fn of(&self, v: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[v]..self.offsets[v + 1]]
    }
}
