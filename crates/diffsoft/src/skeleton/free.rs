//! Free (6-DoF) root joint ("ALL"; paper Eqs. 9-10). Its state is a rigid transform `T`; its
//! coordinates are an increment `(w, l)` (rotation vector, translation) applied from the left:
//! `T' = [I + [w]x] T + [0, l]` (Eq. 10), after which the rotation block is projected back onto
//! the rotations by SVD (`R = U V^T`). So `dq/dw = -[q]x`, `dq/dl = I` for every vertex of the
//! tree (Eq. 9).

use nalgebra::{Matrix3, Matrix4, Vector3};
use num_dual::Dual64;

use super::joint::{dual_matrix4, homogeneous, homogeneous_derivative, skew, Joint};

/// A free root joint; [`Free::default`] is the identity transform.
///
/// ```
/// use diffsoft::skeleton::free::Free;
/// use diffsoft::skeleton::Joint;
/// use nalgebra::{Matrix4, Vector4};
///
/// let mut root = Free::default();
/// assert_eq!(root.dofs(), 6);
/// assert_eq!(root.transform(), Matrix4::identity());
/// // A pure translation increment (w = 0, l = (1, 2, 3)).
/// root.update(&[0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
/// let q = root.transform() * Vector4::new(0.0, 0.0, 0.0, 1.0);
/// assert!((q - Vector4::new(1.0, 2.0, 3.0, 1.0)).norm() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Free {
    /// Current rotation (rest to world).
    pub rotation: Matrix3<f64>,
    /// Current translation.
    pub translation: Vector3<f64>,
}

impl Default for Free {
    fn default() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }
}

impl Free {
    /// Eq. 10 without the projection: `[I + [w]x] T + [0, l]`.
    pub fn increment<T: nalgebra::RealField + Copy>(t: &Matrix4<T>, w: &Vector3<T>, l: &Vector3<T>) -> Matrix4<T> {
        let lin = Matrix3::identity() + skew(w);
        let mut out = homogeneous(&lin, &Vector3::zeros()) * t;
        for i in 0..3 {
            out[(i, 3)] += l[i];
        }
        out
    }
}

impl Joint for Free {
    fn kind(&self) -> &'static str {
        "free"
    }
    fn dofs(&self) -> usize {
        6
    }
    fn transform(&self) -> Matrix4<f64> {
        homogeneous(&self.rotation, &self.translation)
    }
    fn derivative(&self, k: usize) -> Matrix4<f64> {
        if k < 3 {
            let e = skew(&Vector3::ith(k, 1.0));
            homogeneous_derivative(&(e * self.rotation), &(e * self.translation))
        } else {
            homogeneous_derivative(&Matrix3::zeros(), &Vector3::ith(k - 3, 1.0))
        }
    }
    fn update(&mut self, dz: &[f64]) {
        let w = Vector3::new(dz[0], dz[1], dz[2]);
        let l = Vector3::new(dz[3], dz[4], dz[5]);
        let t = Self::increment(&self.transform(), &w, &l);
        let m: Matrix3<f64> = t.fixed_view::<3, 3>(0, 0).into_owned();
        // Project back onto the rotations: R = U V^T with det = +1.
        let svd = crate::kernel::svd::svd3(&m);
        self.rotation = svd.rotation();
        self.translation = t.fixed_view::<3, 1>(0, 3).into_owned();
    }
    fn transform_dual(&self, z: &[Dual64]) -> Matrix4<Dual64> {
        let w = Vector3::new(z[0], z[1], z[2]);
        let l = Vector3::new(z[3], z[4], z[5]);
        Self::increment(&dual_matrix4(&self.transform()), &w, &l)
    }
    fn transform_after(&self, z: &[f64]) -> Matrix4<f64> {
        // The actual update, projection included (it changes the result only at second order,
        // so finite differences of it converge to `derivative` at order 2).
        let mut j = self.clone();
        j.update(z);
        j.transform()
    }
    fn coordinates(&self) -> Vec<f64> {
        let r = nalgebra::Rotation3::from_matrix_unchecked(self.rotation).scaled_axis();
        vec![
            r.x,
            r.y,
            r.z,
            self.translation.x,
            self.translation.y,
            self.translation.z,
        ]
    }
    fn set_coordinates(&mut self, c: &[f64]) {
        self.rotation = *nalgebra::Rotation3::from_scaled_axis(Vector3::new(c[0], c[1], c[2])).matrix();
        self.translation = Vector3::new(c[3], c[4], c[5]);
    }
    fn state_len(&self) -> usize {
        12
    }
    fn write_state(&self, out: &mut [f64]) {
        out[..9].copy_from_slice(self.rotation.as_slice());
        out[9..12].copy_from_slice(self.translation.as_slice());
    }
    fn read_state(&mut self, s: &[f64]) {
        self.rotation = Matrix3::from_column_slice(&s[..9]);
        self.translation = Vector3::from_column_slice(&s[9..12]);
    }
    fn derivative_dual(&self, z: &[Dual64], k: usize) -> Matrix4<Dual64> {
        // dA/dz_k = [e_k]x T (rotation) or the unit translation, at the moved state T(z).
        if k < 3 {
            let e = skew(&Vector3::ith(k, Dual64::from(1.0)));
            let t = self.transform_dual(z);
            let mut d = e.to_homogeneous() * t;
            for c in 0..4 {
                d[(3, c)] = Dual64::from(0.0);
            }
            d
        } else {
            dual_matrix4(&self.derivative(k))
        }
    }
    fn update_jacobians(&self, dz: &[f64], jz: &mut [f64], jdz: &mut [f64]) {
        // Chart at T: R -> (I + [a]x) R, t -> (I + [a]x) t + b. The update (Eq. 10) is
        // M = (I + [w]x) R, R' = polar(M), t' = (I + [w]x) t + l. The polar factor's differential
        // is dR' = R' [o]x with (tr(S) I - S) o = axial(R'^T dM - dM^T R'), S = R'^T M, and the
        // chart after the update reads a' = R' o, b' = dt' - a' x t'.
        let w = Vector3::new(dz[0], dz[1], dz[2]);
        let l = Vector3::new(dz[3], dz[4], dz[5]);
        let iw = Matrix3::identity() + skew(&w);
        let m = iw * self.rotation;
        let r1 = crate::kernel::svd::svd3(&m).rotation();
        let t1 = iw * self.translation + l;
        let s = r1.transpose() * m;
        let s = (s + s.transpose()) * 0.5;
        let k = Matrix3::identity() * s.trace() - s;
        let kinv = k.try_inverse().unwrap_or_else(Matrix3::zeros);
        let axial =
            |a: &Matrix3<f64>| Vector3::new(a[(2, 1)] - a[(1, 2)], a[(0, 2)] - a[(2, 0)], a[(1, 0)] - a[(0, 1)]) * 0.5;
        // Column j: the response to unit direction j of (a, b) [jz] or (w, l) [jdz].
        for j in 0..12 {
            let (dm, dt) = if j < 6 {
                // State perturbation.
                let e = Vector3::ith(j % 3, 1.0);
                if j < 3 {
                    (iw * skew(&e) * self.rotation, iw * skew(&e) * self.translation)
                } else {
                    (Matrix3::zeros(), iw * e)
                }
            } else {
                let e = Vector3::ith((j - 6) % 3, 1.0);
                if j < 9 {
                    (skew(&e) * self.rotation, skew(&e) * self.translation)
                } else {
                    (Matrix3::zeros(), e)
                }
            };
            let c = r1.transpose() * dm;
            let o = kinv * axial(&(c - c.transpose()));
            let a1 = r1 * o;
            let b1 = dt - a1.cross(&t1);
            let (dst, col) = if j < 6 { (&mut *jz, j) } else { (&mut *jdz, j - 6) };
            for row in 0..3 {
                dst[row * 6 + col] = a1[row];
                dst[(row + 3) * 6 + col] = b1[row];
            }
        }
    }
    fn boxed_clone(&self) -> Box<dyn Joint> {
        Box::new(self.clone())
    }
}
