//! What the core tests share: the helpers of `diffsoft::testing` and random boxes for the
//! property tests.

pub use diffsoft::testing::*;

/// Random structured boxes (1-3 cells per axis, either cell split) with edge lengths in `size`
/// and vertex jitter in `jitter` (fraction of the cell size; below 0.25 keeps tets valid).
pub fn jittered_boxes(
    size: std::ops::Range<f64>,
    jitter: std::ops::Range<f64>,
) -> impl proptest::strategy::Strategy<Value = diffsoft::mesh::TetMesh> {
    use diffsoft::mesh::generate::{BoxSpec, CellSplit};
    use proptest::prelude::*;
    (
        1usize..4,
        1usize..4,
        1usize..4,
        size.clone(),
        size.clone(),
        size,
        jitter,
        any::<u64>(),
        any::<bool>(),
    )
        .prop_map(|(a, b, c, x, y, z, jit, seed, kuhn)| {
            BoxSpec::new([a, b, c], [x, y, z])
                .split(if kuhn { CellSplit::Kuhn6 } else { CellSplit::Five })
                .jitter(jit, seed)
                .build()
                .expect("jitter below 0.25 keeps tets valid")
        })
}
