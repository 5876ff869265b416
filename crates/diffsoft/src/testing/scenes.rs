//! Scenes for the collision-detection benchmarks and studies.

use anyhow::{Context, Result};

use crate::base::Material;
use crate::cloth::ClothSpec;
use crate::contact::pair::BodyCollision;
use crate::mesh::generate::BoxSpec;
use crate::model::{BodySpec, MassSpec, Model, ModelBuilder};

/// A detection-cost cloth of `n x n` cells must have a cell and fit in memory (about 1 KB per
/// cloth vertex for the model, the collision structures and the detector).
pub fn check_cloth_size(n: usize) -> Result<()> {
    anyhow::ensure!(n >= 1, "cloth sizes must be at least 1 cell per side, got {n}");
    let vertices = n
        .checked_add(1)
        .and_then(|k| k.checked_mul(k))
        .with_context(|| format!("a cloth of {n} x {n} cells: the vertex count overflows"))?;
    crate::base::memory::check(&format!("a cloth of {n} x {n} cells"), vertices, 1024)?;
    Ok(())
}

/// A cloth grid of `n x n` cells (1 m square, in the plane y = 0) under a box of
/// `n/4 x n/8 x n/4` cells resting 0.5 mm above it: the collision surfaces for the cost study.
pub fn detection_scene(n: usize) -> Result<Model> {
    check_cloth_size(n)?;
    let m = (n / 4).max(1);
    let mesh = BoxSpec::new([m, (m / 2).max(1), m], [0.5, 0.25, 0.5])
        .origin([-0.23, 5e-4, -0.27])
        .build()?;
    let body = BodySpec::new(
        "box",
        mesh,
        Material {
            youngs_modulus: 1e4,
            poisson_ratio: 0.3,
        },
        MassSpec::Density(100.0),
    );
    Ok(ModelBuilder::new()
        .body(body)
        .cloth(ClothSpec::new("cloth", crate::cloth::grid(n, 1.0), 100.0, 0.0, 1.0))
        .collisions(BodyCollision {
            thickness: 1e-3,
            friction: 0.1,
        })
        .build()?)
}
