//! Assembly of the FEM operators (Eqs. 22-23) on ~10k and ~100k tets.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use diffsoft::fem::{Coefficient, FemOperators};
use diffsoft::mesh::generate::box_with_about;
use std::hint::black_box;

fn assembly(c: &mut Criterion) {
    let mut g = c.benchmark_group("assembly");
    g.sample_size(20);
    for target in [10_000usize, 100_000] {
        let mesh = box_with_about(target, 1.0).jitter(0.15, 1).build().unwrap();
        let tets = mesh.num_tets();
        // Geometry (P, P^-1, V, A per tet) and the sparsity pattern of L: once per mesh.
        g.bench_with_input(BenchmarkId::new("geometry_and_pattern", tets), &mesh, |b, m| {
            b.iter(|| FemOperators::new(black_box(m)).unwrap())
        });
        let fem = FemOperators::new(&mesh).unwrap();
        // Numeric assembly of L and the lumped mass into the fixed pattern.
        g.bench_with_input(BenchmarkId::new("laplacian_values", tets), &fem, |b, f| {
            b.iter(|| f.laplacian_values(black_box(Coefficient::Uniform(2e5))).unwrap())
        });
        g.bench_with_input(BenchmarkId::new("lumped_mass", tets), &fem, |b, f| {
            b.iter(|| f.lumped_mass(black_box(Coefficient::Uniform(1e3))).unwrap())
        });
        // Everything from a mesh to L: what "assembly" costs a user the first time.
        g.bench_with_input(BenchmarkId::new("mesh_to_l_total", tets), &mesh, |b, m| {
            b.iter(|| {
                FemOperators::new(black_box(m))
                    .unwrap()
                    .laplacian(Coefficient::Uniform(2e5))
                    .unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, assembly);
criterion_main!(benches);
