//! The spatial hash of the pair detection: a uniform grid of axis-aligned boxes.

use nalgebra::Vector3;

/// A uniform spatial hash of axis-aligned boxes (reused between steps: no allocation once warm).
/// Each (cell, box) entry goes into a bucket chosen by hashing the cell's key, and the entries
/// are ordered by bucket with a counting sort (linear in the entries; a bucket holds its entries
/// in box order), so a query reads one bucket per cell.
#[derive(Debug, Clone, Default)]
pub(super) struct Grid {
    inv_cell: f64,
    /// Buckets are `2^bits`.
    bits: u32,
    /// Bucket `b`'s entries are `entries[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    /// `(cell key, box id)`, by bucket.
    entries: Vec<(u64, u32)>,
    /// The entries in box order, before the counting sort.
    unsorted: Vec<(u64, u32)>,
}

#[inline]
fn cell_key(i: i64, j: i64, k: i64) -> u64 {
    const M: u64 = (1 << 21) - 1;
    (((i as u64) & M) << 42) | (((j as u64) & M) << 21) | ((k as u64) & M)
}

impl Grid {
    fn cells(&self, lo: &Vector3<f64>, hi: &Vector3<f64>) -> ([i64; 3], [i64; 3]) {
        let f = |x: f64| (x * self.inv_cell).floor() as i64;
        ([f(lo.x), f(lo.y), f(lo.z)], [f(hi.x), f(hi.y), f(hi.z)])
    }

    /// The bucket of a cell key (Fibonacci hashing: the top `bits` of the key times 2^64/phi).
    #[inline]
    fn bucket(&self, key: u64) -> usize {
        if self.bits == 0 {
            return 0;
        }
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - self.bits)) as usize
    }

    /// Insert boxes `(lo, hi)` with ids; `cell` is the cell size.
    pub(super) fn build(&mut self, cell: f64, boxes: &[(Vector3<f64>, Vector3<f64>)]) {
        self.inv_cell = 1.0 / cell;
        self.unsorted.clear();
        for (id, (lo, hi)) in boxes.iter().enumerate() {
            let (a, b) = self.cells(lo, hi);
            for i in a[0]..=b[0] {
                for j in a[1]..=b[1] {
                    for k in a[2]..=b[2] {
                        self.unsorted.push((cell_key(i, j, k), id as u32));
                    }
                }
            }
        }
        // About one bucket per entry.
        self.bits = self.unsorted.len().max(1).next_power_of_two().trailing_zeros();
        let buckets = 1usize << self.bits;
        self.starts.clear();
        self.starts.resize(buckets + 1, 0);
        for e in &self.unsorted {
            let b = self.bucket(e.0);
            self.starts[b + 1] += 1;
        }
        for b in 0..buckets {
            self.starts[b + 1] += self.starts[b];
        }
        self.entries.clear();
        self.entries.resize(self.unsorted.len(), (0, 0));
        // Fill each bucket from its start (kept in `starts[b]` while filling, restored after).
        for i in 0..self.unsorted.len() {
            let e = self.unsorted[i];
            let b = self.bucket(e.0);
            let at = &mut self.starts[b];
            self.entries[*at as usize] = e;
            *at += 1;
        }
        for b in (1..=buckets).rev() {
            self.starts[b] = self.starts[b - 1];
        }
        self.starts[0] = 0;
    }

    /// Call `f` with every id whose cells meet the box (ids may repeat), cell by cell, each
    /// cell's ids in increasing order.
    pub(super) fn query(&self, lo: &Vector3<f64>, hi: &Vector3<f64>, mut f: impl FnMut(u32)) {
        if self.entries.is_empty() {
            return;
        }
        let (a, b) = self.cells(lo, hi);
        for i in a[0]..=b[0] {
            for j in a[1]..=b[1] {
                for k in a[2]..=b[2] {
                    let key = cell_key(i, j, k);
                    let bucket = self.bucket(key);
                    let (s, e) = (self.starts[bucket] as usize, self.starts[bucket + 1] as usize);
                    for entry in &self.entries[s..e] {
                        if entry.0 == key {
                            f(entry.1);
                        }
                    }
                }
            }
        }
    }
}
