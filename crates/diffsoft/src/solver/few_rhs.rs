//! Dense kernels for one to three right-hand sides (a vertex's axes): the products and
//! triangular solves of a supernodal Cholesky solve, where the factor's values are read once
//! and the right-hand sides stay in cache. General matrix-product code packs its operands for
//! many columns; with three, that packing costs as much as the product, and this code does
//! without it.
//!
//! Every matrix here is column-major with unit row stride (the factor's supernodes, the
//! solve's buffers); each function checks that. The summation order of every entry is fixed
//! by the shapes alone, so splitting a product by rows between threads gives the same bits.
//! Each kernel is also built for AVX2 and chosen at run time when the CPU has it (without
//! FMA, so both builds round alike).

use faer::{MatMut, MatRef};

/// The columns of `m` as slices (`K` of them).
#[inline(always)]
fn columns<const K: usize>(m: MatRef<'_, f64>) -> [&[f64]; K] {
    assert!(
        m.ncols() == K && (m.nrows() <= 1 || m.row_stride() == 1),
        "few_rhs: not column-major"
    );
    std::array::from_fn(|j| {
        m.col(j)
            .try_as_col_major()
            .expect("few_rhs: unit row stride")
            .as_slice()
    })
}

/// The columns of `m` as disjoint mutable slices (`K` of them).
#[inline(always)]
fn columns_mut<const K: usize>(m: MatMut<'_, f64>) -> [&mut [f64]; K] {
    let (n, cs) = (m.nrows(), m.col_stride());
    assert!(
        m.ncols() == K && (n <= 1 || m.row_stride() == 1),
        "few_rhs: not column-major"
    );
    assert!(K <= 1 || cs.unsigned_abs() >= n, "few_rhs: overlapping columns");
    let ptr = m.as_ptr_mut();
    // SAFETY: column j starts at ptr + j * cs and holds n contiguous values (unit row stride);
    // |cs| >= n, so the K slices are disjoint, and they borrow `m` for their lifetime.
    std::array::from_fn(|j| unsafe { std::slice::from_raw_parts_mut(ptr.offset(j as isize * cs), n) })
}

/// Column `c` of `a` (unit row stride) as a slice.
fn col(a: MatRef<'_, f64>, c: usize) -> &[f64] {
    a.col(c)
        .try_as_col_major()
        .expect("few_rhs: unit row stride")
        .as_slice()
}

/// An AVX2 build of a kernel generic over the number of right-hand sides, and the function
/// that picks it at run time.
macro_rules! avx2_dispatch {
    ($name:ident => $body:ident ( $($arg:ident : $ty:ty),* )) => {
        fn $name<const K: usize>($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2<const K: usize>($($arg: $ty),*) {
                    $body::<K>($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, checked just above.
                    return unsafe { avx2::<K>($($arg),*) };
                }
            }
            $body::<K>($($arg),*)
        }
    };
}

avx2_dispatch!(product_n => product_n_body(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64));
avx2_dispatch!(product_t => product_t_body(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64));
avx2_dispatch!(lower_solve_k => lower_solve_body(l: MatRef<'_, f64>, x: MatMut<'_, f64>));
avx2_dispatch!(lower_transposed_solve_k => lower_transposed_solve_body(l: MatRef<'_, f64>, x: MatMut<'_, f64>));

macro_rules! by_width {
    ($k:expr, $f:ident ( $($arg:expr),* )) => {
        match $k {
            0 => {}
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            k => panic!("few_rhs: {k} right-hand sides (at most 3)"),
        }
    };
}

/// `dst += alpha a src` (`a` is `rows x cols`, `src` `cols x k`, `dst` `rows x k`, `k <= 3`).
pub(crate) fn add_product(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    assert!(dst.nrows() == a.nrows() && src.nrows() == a.ncols() && dst.ncols() == src.ncols());
    by_width!(dst.ncols(), product_n(dst, a, src, alpha));
}

#[inline(always)]
fn product_n_body<const K: usize>(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    let rows = a.nrows();
    if rows == 0 {
        return;
    }
    let src = columns::<K>(src);
    let dst = columns_mut::<K>(dst);
    let cols = a.ncols();
    let mut c = 0;
    // Four columns of `a` at a time: each entry of `dst` is loaded and stored once per four
    // columns, and every value of `a` is read from memory once.
    while c + 4 <= cols {
        let (a0, a1, a2, a3) = (col(a, c), col(a, c + 1), col(a, c + 2), col(a, c + 3));
        for j in 0..K {
            let s = [src[j][c], src[j][c + 1], src[j][c + 2], src[j][c + 3]].map(|v| alpha * v);
            for ((((d, &x0), &x1), &x2), &x3) in dst[j].iter_mut().zip(a0).zip(a1).zip(a2).zip(a3) {
                *d += x0 * s[0] + x1 * s[1] + x2 * s[2] + x3 * s[3];
            }
        }
        c += 4;
    }
    while c < cols {
        let a0 = col(a, c);
        for j in 0..K {
            let s = alpha * src[j][c];
            for (d, &x0) in dst[j].iter_mut().zip(a0) {
                *d += x0 * s;
            }
        }
        c += 1;
    }
}

/// `dst += alpha a^T src` (`a` is `rows x cols`, `src` `rows x k`, `dst` `cols x k`, `k <= 3`).
pub(crate) fn add_transposed_product(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    assert!(dst.nrows() == a.ncols() && src.nrows() == a.nrows() && dst.ncols() == src.ncols());
    by_width!(dst.ncols(), product_t(dst, a, src, alpha));
}

#[inline(always)]
fn product_t_body<const K: usize>(dst: MatMut<'_, f64>, a: MatRef<'_, f64>, src: MatRef<'_, f64>, alpha: f64) {
    let rows = a.nrows();
    if rows == 0 {
        return;
    }
    let src = columns::<K>(src).map(|s| &s[..rows]);
    let mut dst = columns_mut::<K>(dst);
    for c in 0..a.ncols() {
        let d = dots::<K>(&col(a, c)[..rows], src);
        for (dj, v) in dst.iter_mut().zip(d) {
            dj[c] += alpha * v;
        }
    }
}

/// Partial sums per dot product: enough independent additions in flight to hide their latency.
const LANES: usize = 8;

/// `a . src[j]` for each `j`, with [`LANES`] partial sums each (lane `l` sums the products of
/// rows `l, l + 8, ...` in order), combined in a fixed order; rows past the last multiple of
/// eight are added at the end. The AVX2 build computes exactly these sums (no FMA).
#[inline(always)]
fn dots<const K: usize>(a: &[f64], src: [&[f64]; K]) -> [f64; K] {
    let n = a.len();
    let body = n - n % LANES;
    let src = src.map(|s| &s[..n]);
    let acc = lane_sums::<K>(&a[..body], src.map(|s| &s[..body]));
    std::array::from_fn(|j| {
        let p = &acc[j];
        let mut t = ((p[0] + p[4]) + (p[2] + p[6])) + ((p[1] + p[5]) + (p[3] + p[7]));
        for i in body..n {
            t += a[i] * src[j][i];
        }
        t
    })
}

/// The lane sums of [`dots`] over `a` (a multiple of [`LANES`] long).
#[inline(always)]
fn lane_sums<const K: usize>(a: &[f64], src: [&[f64]; K]) -> [[f64; LANES]; K] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { lane_sums_avx2::<K>(a, src) };
        }
    }
    lane_sums_plain::<K>(a, src)
}

/// [`lane_sums`] without SIMD intrinsics (the same sums in the same order).
#[inline(always)]
fn lane_sums_plain<const K: usize>(a: &[f64], src: [&[f64]; K]) -> [[f64; LANES]; K] {
    let mut acc = [[0.0f64; LANES]; K];
    for (i, x) in a.chunks_exact(LANES).enumerate() {
        for (acc_j, s) in acc.iter_mut().zip(src) {
            let s = &s[i * LANES..(i + 1) * LANES];
            for l in 0..LANES {
                acc_j[l] += x[l] * s[l];
            }
        }
    }
    acc
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn lane_sums_avx2<const K: usize>(a: &[f64], src: [&[f64]; K]) -> [[f64; LANES]; K] {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    assert!(a.len().is_multiple_of(LANES) && src.iter().all(|s| s.len() == a.len()));
    let mut lo: [__m256d; K] = [_mm256_setzero_pd(); K];
    let mut hi: [__m256d; K] = [_mm256_setzero_pd(); K];
    let pa = a.as_ptr();
    let ps = src.map(|s| s.as_ptr());
    let mut i = 0;
    while i < a.len() {
        // SAFETY: i + 8 <= a.len() == every src's length (asserted above); unaligned loads.
        let (x0, x1) = (_mm256_loadu_pd(pa.add(i)), _mm256_loadu_pd(pa.add(i + 4)));
        for j in 0..K {
            let (s0, s1) = (_mm256_loadu_pd(ps[j].add(i)), _mm256_loadu_pd(ps[j].add(i + 4)));
            lo[j] = _mm256_add_pd(lo[j], _mm256_mul_pd(x0, s0));
            hi[j] = _mm256_add_pd(hi[j], _mm256_mul_pd(x1, s1));
        }
        i += LANES;
    }
    let mut out = [[0.0f64; LANES]; K];
    for j in 0..K {
        _mm256_storeu_pd(out[j].as_mut_ptr(), lo[j]);
        _mm256_storeu_pd(out[j].as_mut_ptr().add(4), hi[j]);
    }
    out
}

/// `L y = x` in place for a dense lower triangle `l` (`m x m`, its upper part not read).
pub(crate) fn lower_solve(l: MatRef<'_, f64>, x: MatMut<'_, f64>) {
    assert!(l.nrows() == l.ncols() && x.nrows() == l.nrows());
    by_width!(x.ncols(), lower_solve_k(l, x));
}

#[inline(always)]
fn lower_solve_body<const K: usize>(l: MatRef<'_, f64>, x: MatMut<'_, f64>) {
    let mut x = columns_mut::<K>(x);
    for c in 0..l.ncols() {
        let lc = col(l, c);
        for xj in x.iter_mut() {
            let v = xj[c] / lc[c];
            xj[c] = v;
            for (d, &a) in xj[c + 1..].iter_mut().zip(&lc[c + 1..]) {
                *d -= a * v;
            }
        }
    }
}

/// `L^T y = x` in place for a dense lower triangle `l` (`m x m`, its upper part not read).
pub(crate) fn lower_transposed_solve(l: MatRef<'_, f64>, x: MatMut<'_, f64>) {
    assert!(l.nrows() == l.ncols() && x.nrows() == l.nrows());
    by_width!(x.ncols(), lower_transposed_solve_k(l, x));
}

#[inline(always)]
fn lower_transposed_solve_body<const K: usize>(l: MatRef<'_, f64>, x: MatMut<'_, f64>) {
    let mut x = columns_mut::<K>(x);
    for c in (0..l.ncols()).rev() {
        let lc = col(l, c);
        for xj in x.iter_mut() {
            let (head, tail) = xj.split_at_mut(c + 1);
            let [d] = dots::<1>(&lc[c + 1..], [&*tail]);
            head[c] = (head[c] - d) / lc[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::Mat;

    fn mat(r: usize, c: usize, seed: usize) -> Mat<f64> {
        Mat::from_fn(r, c, |i, j| (((i * 31 + j * 17 + seed * 7) % 23) as f64 - 11.0) / 7.0)
    }

    /// The AVX2 lane sums are bit for bit the plain ones (so a machine without AVX2 computes
    /// the same solution).
    #[test]
    fn avx2_lane_sums_equal_the_plain_ones() {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let a: Vec<f64> = (0..64).map(|i| ((i * 37 % 19) as f64 - 9.0) / 3.0).collect();
            let s: Vec<f64> = (0..64).map(|i| ((i * 11 % 23) as f64 - 11.0) / 7.0).collect();
            let t: Vec<f64> = (0..64).map(|i| 1.0 / (1.0 + i as f64)).collect();
            let plain = lane_sums_plain::<2>(&a, [&s, &t]);
            // SAFETY: AVX2 is available (checked above).
            let simd = unsafe { lane_sums_avx2::<2>(&a, [&s, &t]) };
            assert_eq!(plain.map(|l| l.map(f64::to_bits)), simd.map(|l| l.map(f64::to_bits)));
        }
    }

    /// The kernels agree with plain loops (relative 1e-13) for 1-3 right-hand sides and
    /// shapes that exercise the four-column blocks, their remainders and empty matrices.
    #[test]
    fn kernels_agree_with_plain_loops() {
        for k in 1..=3 {
            for (rows, cols) in [(0, 3), (5, 0), (1, 1), (7, 5), (13, 9), (40, 21), (67, 6)] {
                let a = mat(rows, cols, 1);
                let (src_n, src_t) = (mat(cols, k, 2), mat(rows, k, 3));
                let mut dn = mat(rows, k, 4);
                let mut dt = mat(cols, k, 5);
                let (mut wn, mut wt) = (dn.clone(), dt.clone());
                add_product(dn.as_mut(), a.as_ref(), src_n.as_ref(), -0.5);
                add_transposed_product(dt.as_mut(), a.as_ref(), src_t.as_ref(), 2.0);
                for j in 0..k {
                    for i in 0..rows {
                        wn[(i, j)] += -0.5 * (0..cols).map(|c| a[(i, c)] * src_n[(c, j)]).sum::<f64>();
                    }
                    for c in 0..cols {
                        wt[(c, j)] += 2.0 * (0..rows).map(|i| a[(i, c)] * src_t[(i, j)]).sum::<f64>();
                    }
                }
                assert!(
                    (&dn - &wn).norm_max() <= 1e-13 * (1.0 + wn.norm_max()),
                    "N {rows}x{cols} k {k}"
                );
                assert!(
                    (&dt - &wt).norm_max() <= 1e-13 * (1.0 + wt.norm_max()),
                    "T {rows}x{cols} k {k}"
                );
            }
            for m in [1, 4, 9, 30] {
                // A well-conditioned lower triangle; the upper part holds garbage never read.
                let l = Mat::from_fn(m, m, |i, j| match i.cmp(&j) {
                    std::cmp::Ordering::Equal => 3.0 + i as f64 * 0.1,
                    std::cmp::Ordering::Greater => ((i + 2 * j) % 5) as f64 * 0.1 - 0.2,
                    std::cmp::Ordering::Less => f64::NAN,
                });
                let b = mat(m, k, 6);
                let (mut y, mut z) = (b.clone(), b.clone());
                lower_solve(l.as_ref(), y.as_mut());
                lower_transposed_solve(l.as_ref(), z.as_mut());
                for j in 0..k {
                    for i in 0..m {
                        let ly: f64 = (0..=i).map(|c| l[(i, c)] * y[(c, j)]).sum();
                        let ltz: f64 = (i..m).map(|r| l[(r, i)] * z[(r, j)]).sum();
                        assert!((ly - b[(i, j)]).abs() < 1e-13, "L y = b, m {m} k {k}");
                        assert!((ltz - b[(i, j)]).abs() < 1e-13, "L^T z = b, m {m} k {k}");
                    }
                }
            }
        }
    }
}
