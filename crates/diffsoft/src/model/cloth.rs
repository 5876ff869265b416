//! The cloth part of the model builder: cloth bodies appended after the soft bodies, their
//! triangles and bending stencils assembled once the stiffness pattern is known.

use nalgebra::Vector3;

use super::Attachment;
use super::ModelBuilder;
use crate::base::InputError;
use crate::cloth::{Bends, Cloth, ClothBody, Incidence};
use crate::fem::FemOperators;

impl ModelBuilder {
    /// Append the cloth bodies' vertices to the per-vertex arrays (after the soft bodies).
    pub(super) fn add_cloth(
        &self,
        rest: &mut Vec<Vector3<f64>>,
        initial_velocity: &mut Vec<Vector3<f64>>,
        accel: &mut Vec<Vector3<f64>>,
        fixed: &mut Vec<bool>,
        attachments: &mut Vec<Attachment>,
        mass: &mut Vec<f64>,
    ) -> Result<Option<ClothParts>, InputError> {
        if self.cloths.is_empty() {
            return Ok(None);
        }
        let mut parts = ClothParts::default();
        for c in &self.cloths {
            let p = crate::cloth::prepare(c)?;
            let v0 = rest.len();
            let nb = c.surface.vertices.len();
            let t0 = parts.triangles.len();
            let what = format!("cloth '{}'", c.name);
            let mut is_fixed = vec![false; nb];
            for &v in &c.fixed {
                if v >= nb {
                    return Err(InputError::new(format!(
                        "{what}: fixed vertex {v} out of range ({nb} vertices)"
                    )));
                }
                is_fixed[v] = true;
            }
            for &(v, w) in &c.attachments {
                if v >= nb {
                    return Err(InputError::new(format!(
                        "{what}: attached vertex {v} out of range ({nb} vertices)"
                    )));
                }
                if !(w.is_finite() && w > 0.0) {
                    return Err(InputError::new(format!(
                        "{what}: attachment stiffness must be finite and positive, got {}",
                        crate::base::number(w)
                    )));
                }
                attachments.push(Attachment {
                    vertex: v + v0,
                    target: c.surface.vertices[v],
                    weight: w,
                });
            }
            fixed.extend(is_fixed);
            rest.extend(c.surface.vertices.iter().copied());
            initial_velocity.extend(std::iter::repeat_n(c.initial_velocity, nb));
            accel.extend(std::iter::repeat_n(
                if c.gravity { self.gravity } else { Vector3::zeros() },
                nb,
            ));
            let body_mass: f64 = p.mass.iter().sum();
            mass.extend(p.mass);
            for (tri, g) in c.surface.triangles.iter().zip(&p.geometry) {
                parts.triangles.push(tri.map(|v| v + v0));
                parts.w_stretch.push(c.stretching * g.area);
            }
            parts.geometry.extend(p.geometry);
            let bending_vertices = p.stencils.len();
            for (verts, coefs, area) in p.stencils {
                parts
                    .stencils
                    .push((verts.iter().map(|v| v + v0).collect(), coefs, c.bending * area));
            }
            parts.bodies.push(ClothBody {
                name: c.name.clone(),
                vertices: v0..v0 + nb,
                triangles: t0..parts.triangles.len(),
                stretching: c.stretching,
                bending: c.bending,
                area_density: c.area_density,
                mass: body_mass,
                area: p.area,
                bending_vertices,
                gravity: c.gravity,
            });
        }
        Ok(Some(parts))
    }
}

/// Cloth bodies gathered by the builder, before the pattern is known.
#[derive(Default)]
pub(super) struct ClothParts {
    bodies: Vec<ClothBody>,
    triangles: Vec<[usize; 3]>,
    geometry: Vec<crate::cloth::TriangleGeometry>,
    w_stretch: Vec<f64>,
    /// (global vertices, coefficients, weight) per bending stencil.
    stencils: Vec<(Vec<usize>, Vec<f64>, f64)>,
}

impl ClothParts {
    /// Rebuild the stiffness pattern with the cloth's elements and assemble the cloth.
    pub(super) fn assemble(self, fem: &mut FemOperators, rest: &[Vector3<f64>]) -> Cloth {
        let n = rest.len();
        let cliques: Vec<&[usize]> = self
            .triangles
            .iter()
            .map(|t| t.as_slice())
            .chain(self.stencils.iter().map(|s| s.0.as_slice()))
            .collect();
        let (pattern, slots) = crate::fem::StiffnessPattern::with_cliques(n, &fem.tets, &cliques);
        fem.pattern = pattern;
        let nt = self.triangles.len();
        let tri_slots = slots[..nt].iter().map(|s| std::array::from_fn(|k| s[k])).collect();
        let mut bends = Bends {
            offsets: vec![0],
            slot_offsets: vec![0],
            ..Default::default()
        };
        for ((verts, coefs, w), sl) in self.stencils.into_iter().zip(&slots[nt..]) {
            let (len, dir) = crate::cloth::rest_curvature(&verts, &coefs, rest);
            bends.vertices.extend(&verts);
            bends.coefs.extend(&coefs);
            bends.offsets.push(bends.vertices.len());
            bends.weight.push(w);
            bends.rest.push(len);
            bends.rest_dir.push(dir);
            bends.slots.extend(sl);
            bends.slot_offsets.push(bends.slots.len());
        }
        let vertex_triangles = Incidence::new(n, self.triangles.iter().map(|t| t.as_slice()));
        let vertex_bends = Incidence::new(
            n,
            (0..bends.len()).map(|i| &bends.vertices[bends.offsets[i]..bends.offsets[i + 1]]),
        );
        Cloth {
            bodies: self.bodies,
            triangles: self.triangles,
            geometry: self.geometry,
            w_stretch: self.w_stretch,
            bends,
            tri_slots,
            vertex_triangles,
            vertex_bends,
        }
    }
}
