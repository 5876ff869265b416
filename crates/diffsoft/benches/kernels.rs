//! Per-tet kernels of the local step: 3x3 SVD (fast cold, fast warm-started, nalgebra) and the
//! volume projection; and the sparse product `L x` (three right-hand sides) that every
//! stationary sweep makes, on the 52 728-tet cantilever's pattern, one thread.

use criterion::{criterion_group, criterion_main, Criterion};
use diffsoft::fem::StiffnessPattern;
use diffsoft::kernel::svd::{svd3, svd3_nalgebra, svd3_warm, svd3_warm_batch, LANES};
use diffsoft::kernel::volume::nearest_product;
use diffsoft::mesh::generate::BoxSpec;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::hint::black_box;

fn matrices(n: usize) -> Vec<Matrix3<f64>> {
    let mut seed = 3u64;
    let mut rnd = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n)
        .map(|_| {
            // Physical deformation gradients: a rotation times a moderate stretch.
            let r = Rotation3::from_scaled_axis(Vector3::new(rnd(), rnd(), rnd()) * 3.0);
            r.matrix() * (Matrix3::identity() + 0.2 * Matrix3::from_fn(|_, _| rnd()))
        })
        .collect()
}

fn kernels(c: &mut Criterion) {
    let fs = matrices(1024);
    let warm: Vec<Matrix3<f64>> = fs
        .iter()
        .map(|f| svd3(&(f * (Matrix3::identity() + Matrix3::repeat(1e-3)))).v)
        .collect();
    let mut g = c.benchmark_group("kernels_per_1024_tets");
    g.bench_function("svd3_fast_cold", |b| {
        b.iter(|| fs.iter().map(|f| svd3(black_box(f)).sigma[0]).sum::<f64>())
    });
    g.bench_function("svd3_fast_warm", |b| {
        b.iter(|| {
            fs.iter()
                .zip(&warm)
                .map(|(f, v)| svd3_warm(black_box(f), v).sigma[0])
                .sum::<f64>()
        })
    });
    g.bench_function("svd3_fast_warm_batch4", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (fc, vc) in fs.chunks_exact(LANES).zip(warm.chunks_exact(LANES)) {
                let f4: &[_; LANES] = fc.try_into().unwrap();
                let v4: &[_; LANES] = vc.try_into().unwrap();
                acc += svd3_warm_batch(black_box(f4), v4)
                    .iter()
                    .map(|s| s.sigma[0])
                    .sum::<f64>();
            }
            acc
        })
    });
    g.bench_function("svd3_nalgebra", |b| {
        b.iter(|| fs.iter().map(|f| svd3_nalgebra(black_box(f)).sigma[0]).sum::<f64>())
    });
    let sig: Vec<Vector3<f64>> = fs.iter().map(|f| svd3(f).sigma).collect();
    g.bench_function("volume_projection", |b| {
        b.iter(|| {
            sig.iter()
                .map(|s| nearest_product(black_box(s), 1.0).unwrap()[0])
                .sum::<f64>()
        })
    });
    g.finish();
}

fn sparse_matvec3(c: &mut Criterion) {
    // The trade-off study's cantilever: 52 x 13 x 13 cells, 10 388 vertices.
    let mesh = BoxSpec::new([52, 13, 13], [1.0, 0.25, 0.25]).build().unwrap();
    let n = mesh.vertices.len();
    let pattern = StiffnessPattern::new(n, &mesh.tets);
    let values: Vec<f64> = (0..pattern.nnz()).map(|k| 1.0 + (k % 7) as f64 * 0.1).collect();
    let l = pattern.to_sym_csc(values);
    let x: Vec<Vector3<f64>> = (0..n).map(|i| Vector3::new(i as f64, 1.0, 2.0)).collect();
    let mut y = vec![Vector3::zeros(); n];
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut g = c.benchmark_group("sparse");
    g.bench_function("matvec3_cantilever_52728_tets_1_thread", |b| {
        one.install(|| b.iter(|| l.matvec3(black_box(&x), &mut y)))
    });
    g.finish();
}

criterion_group!(benches, kernels, sparse_matvec3);
criterion_main!(benches);
