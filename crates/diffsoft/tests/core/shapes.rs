//! Obstacle shapes declare whether their contact normal is fixed within a contact; gradients
//! through a curved shape, whose normal turns with the vertex, are refused with a message that
//! names the obstacle (the backward pass holds normals fixed).

use diffsoft::base::InputError;
use diffsoft::contact::{Obstacle, Shape};
use diffsoft::diff::loss::CenterOfMass;
use diffsoft::mesh::generate::BoxSpec;
use diffsoft::{
    gradient, BodySpec, Controls, DiffError, MassSpec, Material, ModelBuilder, Options, Settings, SolverKind,
};
use nalgebra::Vector3;

/// A sphere: curved, so its contact normal depends on where the vertex is.
#[derive(Debug)]
struct Sphere {
    centre: Vector3<f64>,
    radius: f64,
}

impl Shape for Sphere {
    fn query(
        &self,
        _from: &Vector3<f64>,
        x: &Vector3<f64>,
        margin: f64,
        thickness: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        let d = x - self.centre;
        let r = d.norm();
        let gap = r - self.radius - thickness;
        (gap <= margin && r > 0.0).then(|| {
            let n = d / r;
            (gap, n, self.centre + n * (self.radius + thickness))
        })
    }

    fn validate(&self) -> Result<(), InputError> {
        Ok(())
    }

    fn kind(&self) -> &'static str {
        "sphere"
    }

    fn piecewise_planar(&self) -> bool {
        false
    }
}

#[test]
fn gradients_through_a_curved_obstacle_are_refused() {
    let mesh = BoxSpec::new([1, 1, 1], [0.1, 0.1, 0.1])
        .origin([0.0, 1.0005, 0.0])
        .build()
        .unwrap();
    let material = Material {
        youngs_modulus: 1e5,
        poisson_ratio: 0.3,
    };
    let model = ModelBuilder::new()
        .gravity(Vector3::new(0.0, -9.81, 0.0))
        .body(BodySpec::new("box", mesh, material, MassSpec::Density(1000.0)))
        .obstacle(Obstacle::new(
            "ball",
            Sphere {
                centre: Vector3::zeros(),
                radius: 1.0,
            },
            0.5,
            0.0,
        ))
        .build()
        .unwrap();
    let settings = Settings {
        solver: SolverKind::Direct,
        ..Settings::default()
    };
    // The forward runs: the shape answers contact queries.
    let mut sim = diffsoft::Simulator::new(model.clone(), settings.clone()).unwrap();
    sim.step().unwrap();
    let e = gradient(
        &model,
        &settings,
        3,
        &Controls::default(),
        &CenterOfMass {
            direction: Vector3::y(),
            time_average: false,
            vertices: None,
        },
        Options::default(),
    )
    .unwrap_err();
    assert!(matches!(e, DiffError::Unsupported(_)), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("'ball'") && msg.contains("curved sphere"), "{msg}");
}
