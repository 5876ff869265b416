//! Spectral radii of the iterations (19) and (21) on ~10k and ~100k tets (Krylov), and the
//! dense solver on a paper-size mesh for comparison.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use diffsoft::analysis::spectral::{largest_eigenvalue, spectral_radius, EigenMethod};
use diffsoft::analysis::{Attachments, IterationSystem, Spectrum};
use diffsoft::mesh::generate::box_with_about;
use std::hint::black_box;

fn spectral(c: &mut Criterion) {
    let mut g = c.benchmark_group("spectral");
    g.sample_size(10);
    for (target, method) in [
        (5_000usize, EigenMethod::Dense),
        (10_000, EigenMethod::Krylov),
        (100_000, EigenMethod::Krylov),
    ] {
        let mesh = box_with_about(target, 1.0).jitter(0.15, 1).build().unwrap();
        let tets = mesh.num_tets();
        let sys = IterationSystem::new(&mesh, 1e3, 1e5, &Attachments::default()).unwrap();
        let s = Spectrum::compute(&sys, EigenMethod::Krylov).unwrap();
        let dt = 2.0 * s.critical_dt_plain();
        let tag = format!("{tets}_{method:?}");
        // rho(G19) = h^2 lambda_max(M^-1 L): one largest-eigenvalue computation.
        g.bench_function(BenchmarkId::new("rho_g19", &tag), |b| {
            b.iter(|| largest_eigenvalue(black_box(&sys.op_minv_l()), 0.0, method).unwrap())
        });
        // rho(G21) at one time step.
        g.bench_function(BenchmarkId::new("rho_g21", &tag), |b| {
            b.iter(|| spectral_radius(black_box(&sys.op_g21(dt)), method).unwrap())
        });
        // All three eigenvalues behind h*_19, h*_21 and the h -> inf limit.
        g.bench_function(BenchmarkId::new("critical_steps", &tag), |b| {
            b.iter(|| Spectrum::compute(black_box(&sys), method).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, spectral);
criterion_main!(benches);
