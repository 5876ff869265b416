//! Random skeletons for the joint and adjoint checks.

use nalgebra::{Rotation3, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use crate::skeleton::free::Free;
use crate::skeleton::prismatic::Prismatic;
use crate::skeleton::rotational::Rotational;
use crate::skeleton::{BoneSpec, Joint, Skeleton};

/// A random unit vector (rejection sampling in the unit cube, away from zero).
pub fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() > 0.1 {
            return v.normalize();
        }
    }
}

/// A random mixed chain: free root, then alternating rotational and prismatic joints, `depth`
/// joints below the root, each bone owning three random vertices; angles may sit near `+-pi`
/// and extensions may be large.
pub fn random_chain(depth: usize, rng: &mut ChaCha8Rng, near_pi: bool, long: bool) -> Skeleton {
    let mut rest = Vec::new();
    let mut specs = Vec::new();
    let mut next_vertices = |rng: &mut ChaCha8Rng| -> Vec<usize> {
        (0..3)
            .map(|_| {
                rest.push(Vector3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                ));
                rest.len() - 1
            })
            .collect()
    };
    let root = Free {
        rotation: *Rotation3::from_scaled_axis(unit(rng) * rng.random_range(0.0..3.0)).matrix(),
        translation: Vector3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        ),
    };
    specs.push(BoneSpec {
        name: "root".into(),
        parent: None,
        joint: Box::new(root),
        vertices: next_vertices(rng),
        torque: None,
    });
    for d in 0..depth {
        let joint: Box<dyn Joint> = if d % 2 == 0 {
            let mut r = Rotational::new(
                Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ),
                unit(rng),
            );
            r.angle = if near_pi && d % 4 == 0 {
                std::f64::consts::PI - 1e-7
            } else if near_pi {
                -std::f64::consts::PI + 1e-7
            } else {
                rng.random_range(-3.0..3.0)
            };
            Box::new(r)
        } else {
            let mut p = Prismatic::new(unit(rng));
            p.extension = if long {
                rng.random_range(-1e3..1e3)
            } else {
                rng.random_range(-1.0..1.0)
            };
            Box::new(p)
        };
        specs.push(BoneSpec {
            name: format!("bone{}", d + 1),
            parent: Some(d),
            joint,
            vertices: next_vertices(rng),
            torque: None,
        });
    }
    Skeleton::new(specs, &rest).expect("a valid chain")
}
