//! Embedded skeletons (paper Eqs. 6-18, appendix C): bones that own mesh vertices rigidly,
//! linked in a tree by joints.
//!
//! A bone `b` moves its vertices by its world transform `T_b = T_parent A_b` (Eq. 11), the
//! product of the joint transforms from the root down (`q_u = Q T_b V_u`, Eq. 6, with `V_u` the
//! vertex's rest position). The reduced coordinates are the free vertices plus one block per
//! joint (6 for a free root, 1 for rotational and prismatic joints, 0 for fixed ones). The
//! Jacobian `B = dq/dz` of the bone vertices is assembled with prefix and suffix products in one
//! pass per bone: `B_{u,v} = Q P_v (dA_v / dz_v) S_{v,b} V_u` (Eq. 12), `P_v` the product of the
//! transforms above joint `v`, `S_{v,b}` of those below it down to bone `b` (Eqs. 15-16). The
//! reduced global step itself lives in `solver::skeletal`.
//!
//! [`Joint`] is the interface; [`free`], [`rotational`], [`prismatic`] and [`fixed`] are the
//! joint types, one file each.

pub mod fixed;
pub mod free;
pub mod joint;
pub mod prismatic;
pub mod rotational;

pub use joint::Joint;

use crate::base::Schedule;

use nalgebra::{DMatrix, Matrix4, Vector3, Vector4};
use num_dual::Dual64;

use crate::base::InputError;

/// A bone as given by a scene.
#[derive(Debug)]
pub struct BoneSpec {
    /// Name.
    pub name: String,
    /// Parent bone index in the spec list (`None` for a root).
    pub parent: Option<usize>,
    /// The joint to the parent (or world).
    pub joint: Box<dyn Joint>,
    /// Rigidly attached vertices (global numbering).
    pub vertices: Vec<usize>,
    /// Torque on the joint's coordinate (1-DoF joints), N m or N.
    pub torque: Option<Schedule>,
}

/// A bone of a built skeleton.
#[derive(Debug)]
pub struct Bone {
    /// Name.
    pub name: String,
    /// Parent bone (earlier in the list).
    pub parent: Option<usize>,
    /// Joint.
    pub joint: Box<dyn Joint>,
    /// Attached vertices (global numbering).
    pub vertices: Vec<usize>,
    /// Their rest positions (homogeneous).
    pub rest: Vec<Vector4<f64>>,
    /// First reduced coordinate of the joint.
    pub dof_offset: usize,
    /// Torque schedule.
    pub torque: Option<Schedule>,
}

impl Clone for Bone {
    fn clone(&self) -> Self {
        Self {
            name: self.name.clone(),
            parent: self.parent,
            joint: self.joint.boxed_clone(),
            vertices: self.vertices.clone(),
            rest: self.rest.clone(),
            dof_offset: self.dof_offset,
            torque: self.torque.clone(),
        }
    }
}

/// Scratch of [`Skeleton::jacobian_derivative_matrix_with`]: per-bone dual-number transforms
/// and a chart increment.
#[derive(Debug, Clone, Default)]
pub struct DualScratch {
    world: Vec<Matrix4<Dual64>>,
    local: Vec<Matrix4<Dual64>>,
    z: Vec<Dual64>,
}

/// A skeleton (a forest of bones: several roots are allowed).
#[derive(Debug, Clone)]
pub struct Skeleton {
    /// Bones, parents before children.
    pub bones: Vec<Bone>,
    /// Number of reduced coordinates of the joints.
    pub dofs: usize,
    /// All bone vertices (global numbering), bone by bone.
    pub rigid: Vec<usize>,
    /// Torques set through the API per coordinate (`None`: the bone's schedule); see
    /// [`Skeleton::set_torque`].
    pub torque_override: Vec<Option<f64>>,
}

impl Skeleton {
    /// Build from specs: reorders parents before children, checks indices, that no vertex is in
    /// two bones, and torque schedules.
    ///
    /// ```
    /// use diffsoft::skeleton::{free::Free, rotational::Rotational, BoneSpec, Skeleton};
    /// use diffsoft::Schedule;
    /// use nalgebra::Vector3;
    ///
    /// let rest = [Vector3::zeros(), Vector3::x(), Vector3::x() * 2.0];
    /// // The child is listed first: the skeleton puts parents first.
    /// let arm = BoneSpec {
    ///     name: "arm".into(),
    ///     parent: Some(1),
    ///     joint: Box::new(Rotational::new(Vector3::x(), Vector3::z())),
    ///     vertices: vec![1, 2],
    ///     torque: Some(Schedule::constant(0.1)),
    /// };
    /// let free = || -> Box<dyn diffsoft::skeleton::Joint> { Box::new(Free::default()) };
    /// let body = BoneSpec { name: "body".into(), parent: None, joint: free(), vertices: vec![0], torque: None };
    /// let skeleton = Skeleton::new(vec![arm, body], &rest)?;
    /// assert_eq!(skeleton.bones[0].name, "body");
    /// assert_eq!(skeleton.dofs, 6 + 1);
    /// assert_eq!(skeleton.rigid, vec![0, 1, 2]);
    /// assert_eq!(skeleton.scalar_dof("arm")?, 6);
    ///
    /// // A vertex in two bones is refused.
    /// let a = BoneSpec { name: "a".into(), parent: None, joint: free(), vertices: vec![0], torque: None };
    /// let b = BoneSpec { name: "b".into(), parent: Some(0), joint: free(), vertices: vec![0], torque: None };
    /// assert!(Skeleton::new(vec![a, b], &rest).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(specs: Vec<BoneSpec>, rest: &[Vector3<f64>]) -> Result<Self, InputError> {
        let n = specs.len();
        for (i, s) in specs.iter().enumerate() {
            crate::base::check_name("bone", &s.name)?;
            if let Some(p) = s.parent {
                if p >= n {
                    return Err(InputError::new(format!(
                        "bone '{}': parent {p} does not exist ({n} bones)",
                        s.name
                    )));
                }
                if p == i {
                    return Err(InputError::new(format!("bone '{}' is its own parent", s.name)));
                }
            }
        }
        // Topological order (parents first); a cycle leaves bones unplaced.
        let mut order = Vec::with_capacity(n);
        let mut placed = vec![false; n];
        while order.len() < n {
            let before = order.len();
            for i in 0..n {
                if !placed[i] && specs[i].parent.is_none_or(|p| placed[p]) {
                    placed[i] = true;
                    order.push(i);
                }
            }
            if order.len() == before {
                let stuck: Vec<&str> = (0..n).filter(|&i| !placed[i]).map(|i| specs[i].name.as_str()).collect();
                return Err(InputError::new(format!("the bones {stuck:?} form a cycle")));
            }
        }
        let mut new_index = vec![0usize; n];
        for (k, &i) in order.iter().enumerate() {
            new_index[i] = k;
        }
        let mut owner = vec![usize::MAX; rest.len()];
        let names: Vec<String> = specs.iter().map(|s| s.name.clone()).collect();
        let mut slots: Vec<Option<BoneSpec>> = specs.into_iter().map(Some).collect();
        let mut bones = Vec::with_capacity(n);
        let mut rigid = Vec::new();
        let mut dofs = 0;
        for &i in &order {
            let s = slots[i].take().expect("each bone placed once");
            for &v in &s.vertices {
                if v >= rest.len() {
                    return Err(InputError::new(format!(
                        "bone '{}': vertex {v} out of range ({} vertices)",
                        s.name,
                        rest.len()
                    )));
                }
                if owner[v] == i {
                    return Err(InputError::new(format!("bone '{}' lists vertex {v} twice", s.name)));
                }
                if owner[v] != usize::MAX {
                    return Err(InputError::new(format!(
                        "vertex {v} belongs to two bones ('{}' and '{}')",
                        names[owner[v]], s.name
                    )));
                }
                owner[v] = i;
            }
            if let Some(t) = &s.torque {
                t.validate(&format!("bone '{}' torque", s.name))?;
                if s.joint.dofs() != 1 {
                    return Err(InputError::new(format!(
                        "bone '{}': torques act on 1-DoF joints, this one is {}",
                        s.name,
                        s.joint.kind()
                    )));
                }
            }
            rigid.extend(&s.vertices);
            let dof_offset = dofs;
            dofs += s.joint.dofs();
            bones.push(Bone {
                rest: s.vertices.iter().map(|&v| rest[v].push(1.0)).collect(),
                name: s.name,
                parent: s.parent.map(|p| new_index[p]),
                joint: s.joint,
                vertices: s.vertices,
                dof_offset,
                torque: s.torque,
            });
        }
        Ok(Self {
            bones,
            dofs,
            rigid,
            torque_override: vec![None; dofs],
        })
    }

    /// World transform `T_b` of every bone (Eq. 11).
    pub fn world_transforms(&self) -> Vec<Matrix4<f64>> {
        let mut w = Vec::with_capacity(self.bones.len());
        self.world_transforms_into(&mut w);
        w
    }

    /// [`Skeleton::world_transforms`] into `w` (no allocation once `w` has the capacity).
    pub fn world_transforms_into(&self, w: &mut Vec<Matrix4<f64>>) {
        w.clear();
        for b in &self.bones {
            let parent = b.parent.map_or(Matrix4::identity(), |p| w[p]);
            w.push(parent * b.joint.transform());
        }
    }

    /// Positions of the bone vertices (in [`Skeleton::rigid`] order): `q_u = Q T_b V_u` (Eq. 6).
    pub fn positions(&self, out: &mut [Vector3<f64>]) {
        self.positions_with(&mut Vec::with_capacity(self.bones.len()), out);
    }

    /// [`Skeleton::positions`] with the world transforms in the scratch `w` (no allocation once
    /// `w` has the capacity).
    pub fn positions_with(&self, w: &mut Vec<Matrix4<f64>>, out: &mut [Vector3<f64>]) {
        self.world_transforms_into(w);
        let mut k = 0;
        for (b, t) in self.bones.iter().zip(w.iter()) {
            for v in &b.rest {
                out[k] = (t * v).xyz();
                k += 1;
            }
        }
    }

    /// `B = dq/dz` of the bone vertices, `3 n_rigid x dofs` (Eqs. 12-16): for every bone, walk
    /// up its chain accumulating the suffix `S`, with the prefix `P_v` the parent's world
    /// transform.
    pub fn jacobian(&self, out: &mut DMatrix<f64>) {
        self.jacobian_with(&mut Vec::with_capacity(self.bones.len()), out);
    }

    /// [`Skeleton::jacobian`] with the world transforms in the scratch `w` (no allocation once
    /// `w` has the capacity).
    pub fn jacobian_with(&self, w: &mut Vec<Matrix4<f64>>, out: &mut DMatrix<f64>) {
        self.world_transforms_into(w);
        out.fill(0.0);
        let mut row0 = 0;
        for (bi, b) in self.bones.iter().enumerate() {
            let mut suffix = Matrix4::identity();
            let mut v = bi;
            loop {
                let joint = &self.bones[v];
                let prefix = joint.parent.map_or(Matrix4::identity(), |p| w[p]);
                for k in 0..joint.joint.dofs() {
                    let g = prefix * joint.joint.derivative(k) * suffix;
                    let col = joint.dof_offset + k;
                    for (j, x) in b.rest.iter().enumerate() {
                        let d = g * x;
                        for a in 0..3 {
                            out[(row0 + 3 * j + a, col)] = d[a];
                        }
                    }
                }
                suffix = joint.joint.transform() * suffix;
                match joint.parent {
                    Some(p) => v = p,
                    None => break,
                }
            }
            row0 += 3 * b.rest.len();
        }
    }

    /// Bone vertex positions after an increment `z` of coordinate `dof` only, evaluated with
    /// [`Joint::transform_after`] (finite differences).
    pub fn positions_after(&self, dof: usize, z: f64) -> Vec<Vector3<f64>> {
        let mut w: Vec<Matrix4<f64>> = Vec::with_capacity(self.bones.len());
        let mut out = Vec::new();
        for b in &self.bones {
            let parent = b.parent.map_or(Matrix4::identity(), |p| w[p]);
            let a = if dof >= b.dof_offset && dof < b.dof_offset + b.joint.dofs() {
                let mut inc = vec![0.0; b.joint.dofs()];
                inc[dof - b.dof_offset] = z;
                b.joint.transform_after(&inc)
            } else {
                b.joint.transform()
            };
            let t = parent * a;
            out.extend(b.rest.iter().map(|x| (t * x).xyz()));
            w.push(t);
        }
        out
    }

    /// Column `dof` of `B` by forward-mode dual numbers (an independent derivative).
    pub fn jacobian_column_dual(&self, dof: usize) -> Vec<Vector3<f64>> {
        let mut w: Vec<Matrix4<Dual64>> = Vec::with_capacity(self.bones.len());
        let mut out = Vec::new();
        for b in &self.bones {
            let parent = b.parent.map_or(Matrix4::identity(), |p| w[p]);
            let a = if dof >= b.dof_offset && dof < b.dof_offset + b.joint.dofs() {
                let mut inc = vec![Dual64::from(0.0); b.joint.dofs()];
                inc[dof - b.dof_offset] = Dual64::from(0.0).derivative();
                b.joint.transform_dual(&inc)
            } else {
                joint::dual_matrix4(&b.joint.transform())
            };
            let t = parent * a;
            out.extend(b.rest.iter().map(|x| {
                let q = t * x.map(Dual64::from);
                Vector3::new(q.x.eps, q.y.eps, q.z.eps)
            }));
            w.push(t);
        }
        out
    }

    /// Apply increments `dz` (length [`Skeleton::dofs`]) with each joint's update rule.
    pub fn update(&mut self, dz: &[f64]) {
        for b in &mut self.bones {
            let n = b.joint.dofs();
            if n > 0 {
                b.joint.update(&dz[b.dof_offset..b.dof_offset + n]);
            }
        }
    }

    /// Joint torques at time `t` (one entry per coordinate; zero where none); an override
    /// set by [`Skeleton::set_torque`] replaces the schedule.
    pub fn torques(&self, t: f64, out: &mut [f64]) {
        out.fill(0.0);
        for b in &self.bones {
            if let Some(s) = &b.torque {
                out[b.dof_offset] = s.at(t);
            }
        }
        for (o, v) in out.iter_mut().zip(&self.torque_override) {
            if let Some(v) = v {
                *o = *v;
            }
        }
    }

    /// Set (or with `None` release) the torque on coordinate `dof`, which must belong to a
    /// one-DoF joint, overriding its schedule.
    pub fn set_torque(&mut self, dof: usize, value: Option<f64>) -> Result<(), InputError> {
        let b = self
            .bones
            .iter()
            .find(|b| dof >= b.dof_offset && dof < b.dof_offset + b.joint.dofs())
            .ok_or_else(|| InputError::new(format!("coordinate {dof} does not exist ({} coordinates)", self.dofs)))?;
        if b.joint.dofs() != 1 {
            return Err(InputError::new(format!(
                "bone '{}': torques act on one-DoF joints, this one is {}",
                b.name,
                b.joint.kind()
            )));
        }
        if value.is_some_and(|v| !v.is_finite()) {
            return Err(InputError::new(format!("bone '{}': torque must be finite", b.name)));
        }
        self.torque_override[dof] = value;
        Ok(())
    }

    /// The first nonzero entry of `row` (one torque per reduced coordinate, `[coordinate]`) on a
    /// joint with other than one DoF, with its bone; `None` when the row is valid. Torques act on
    /// one-DoF joints only ([`Skeleton::set_torque`]): this is the one place that rule is
    /// written for whole rows, which the runs of `diff` and the Python package both apply. A
    /// NaN entry counts as nonzero. Entries past `row`'s end are not looked at (the callers
    /// check the row's length first).
    ///
    /// ```
    /// use diffsoft::skeleton::{free::Free, rotational::Rotational, BoneSpec, Skeleton};
    /// use nalgebra::Vector3;
    ///
    /// let rest = [Vector3::zeros(), Vector3::x()];
    /// let body = BoneSpec { name: "body".into(), parent: None, joint: Box::new(Free::default()), vertices: vec![0], torque: None };
    /// let arm = BoneSpec {
    ///     name: "arm".into(),
    ///     parent: Some(0),
    ///     joint: Box::new(Rotational::new(Vector3::zeros(), Vector3::z())),
    ///     vertices: vec![1],
    ///     torque: None,
    /// };
    /// let skeleton = Skeleton::new(vec![body, arm], &rest)?;
    /// let mut row = vec![0.0; skeleton.dofs];
    /// row[6] = 2.0; // the arm's angle: a one-DoF joint
    /// assert!(skeleton.misplaced_torque(&row).is_none());
    /// row[4] = 0.5; // a coordinate of the free root
    /// let (k, bone) = skeleton.misplaced_torque(&row).expect("refused");
    /// assert_eq!((k, bone.name.as_str()), (4, "body"));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn misplaced_torque(&self, row: &[f64]) -> Option<(usize, &Bone)> {
        self.bones.iter().filter(|b| b.joint.dofs() != 1).find_map(|b| {
            (b.dof_offset..b.dof_offset + b.joint.dofs())
                .find(|&k| row.get(k).is_some_and(|&t| t != 0.0))
                .map(|k| (k, b))
        })
    }

    /// The coordinate of the one-DoF joint of bone `name`.
    pub fn scalar_dof(&self, name: &str) -> Result<usize, InputError> {
        let b = self
            .bones
            .iter()
            .find(|b| b.name == name)
            .ok_or_else(|| InputError::new(format!("no bone named '{name}'")))?;
        if b.joint.dofs() != 1 {
            return Err(InputError::new(format!(
                "bone '{name}': a {} joint has no single coordinate",
                b.joint.kind()
            )));
        }
        Ok(b.dof_offset)
    }

    /// Length of the raw joint state ([`Skeleton::save_state`]).
    pub fn state_len(&self) -> usize {
        self.bones.iter().map(|b| b.joint.state_len()).sum()
    }

    /// The raw joint state of every bone, exactly (checkpoints of the backward pass).
    pub fn save_state(&self, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.state_len(), 0.0);
        let mut k = 0;
        for b in &self.bones {
            let n = b.joint.state_len();
            b.joint.write_state(&mut out[k..k + n]);
            k += n;
        }
    }

    /// Restore a state written by [`Skeleton::save_state`].
    pub fn load_state(&mut self, s: &[f64]) -> Result<(), InputError> {
        if s.len() != self.state_len() || !s.iter().all(|v| v.is_finite()) {
            return Err(InputError::new(format!(
                "skeleton state: expected {} finite numbers, got {}",
                self.state_len(),
                s.len()
            )));
        }
        let mut k = 0;
        for b in &mut self.bones {
            let n = b.joint.state_len();
            b.joint.read_state(&s[k..k + n]);
            k += n;
        }
        Ok(())
    }

    /// Joints whose coordinate is at one of its limits (within 1e-9 rad or m): there the reduced
    /// step's limit switches between active and inactive, a kink of the loss.
    pub fn joints_at_limit(&self) -> usize {
        self.bones
            .iter()
            .filter_map(|b| b.joint.increment_bounds())
            .filter(|(lo, hi)| lo.abs() <= 1e-9 || hi.abs() <= 1e-9)
            .count()
    }

    /// The one-DoF joints' coordinates per coordinate index (0 for other coordinates).
    pub fn scalars(&self, out: &mut [f64]) {
        out.fill(0.0);
        for b in &self.bones {
            if let Some(x) = b.joint.scalar() {
                out[b.dof_offset] = x;
            }
        }
    }

    /// `out[l] += sum_ij B_bar_ij dB_ij / dz_l`: the adjoint of the state through `B`
    /// (Eqs. 12-16), by forward-mode dual numbers along each chart direction `l` (the increment
    /// of [`Joint::transform_dual`]). `b_bar` has the layout of [`Skeleton::jacobian`].
    pub fn contract_jacobian_derivative(&self, b_bar: &DMatrix<f64>, out: &mut [f64]) {
        self.for_each_jacobian_derivative(&mut DualScratch::default(), |l, col, vertex, d| {
            let row = 3 * vertex;
            out[l] += b_bar[(row, col)] * d.x + b_bar[(row + 1, col)] * d.y + b_bar[(row + 2, col)] * d.z;
        });
    }

    /// `out[(l, k)] = sum_i g_i . dB_ik / dz_l` (`dofs x dofs`): the second derivatives of the
    /// bone vertices' positions in the charts of [`Joint::transform_dual`] (as in
    /// [`Skeleton::contract_jacobian_derivative`]) contracted with one vector `g` per bone
    /// vertex (in [`Skeleton::rigid`] order). Newton's method with a skeleton adds its
    /// symmetric part to the reduced Hessian (`g` the energy's gradient at the bone vertices).
    pub fn jacobian_derivative_matrix(&self, g: &[Vector3<f64>], out: &mut DMatrix<f64>) {
        self.jacobian_derivative_matrix_with(g, out, &mut DualScratch::default());
    }

    /// [`Skeleton::jacobian_derivative_matrix`] in the buffers of `scratch` (no allocation once
    /// they have the capacity).
    pub fn jacobian_derivative_matrix_with(
        &self,
        g: &[Vector3<f64>],
        out: &mut DMatrix<f64>,
        scratch: &mut DualScratch,
    ) {
        out.fill(0.0);
        self.for_each_jacobian_derivative(scratch, |l, col, vertex, d| {
            out[(l, col)] += g[vertex].dot(&d);
        });
    }

    /// Visit every entry of `dB / dz_l` by forward-mode dual numbers along each chart direction
    /// `l`: `visit(l, column, bone vertex, d)` with `d` the derivative of that vertex's rows of
    /// column `column` of [`Skeleton::jacobian`] (bone vertices in [`Skeleton::rigid`] order).
    fn for_each_jacobian_derivative(
        &self,
        scratch: &mut DualScratch,
        mut visit: impl FnMut(usize, usize, usize, Vector3<f64>),
    ) {
        let zero = Dual64::from(0.0);
        let DualScratch { world, local, z } = scratch;
        for l in 0..self.dofs {
            world.clear();
            local.clear();
            for b in &self.bones {
                z.clear();
                z.resize(b.joint.dofs(), zero);
                if l >= b.dof_offset && l < b.dof_offset + b.joint.dofs() {
                    z[l - b.dof_offset] = zero.derivative();
                }
                let a = b.joint.transform_dual(z);
                let parent = b.parent.map_or(Matrix4::identity(), |p| world[p]);
                world.push(parent * a);
                local.push(a);
            }
            let mut vertex0 = 0;
            for (bi, b) in self.bones.iter().enumerate() {
                let mut suffix: Matrix4<Dual64> = Matrix4::identity();
                let mut v = bi;
                loop {
                    let joint = &self.bones[v];
                    let prefix = joint.parent.map_or(Matrix4::identity(), |p| world[p]);
                    z.clear();
                    z.resize(joint.joint.dofs(), zero);
                    if l >= joint.dof_offset && l < joint.dof_offset + joint.joint.dofs() {
                        z[l - joint.dof_offset] = zero.derivative();
                    }
                    for k in 0..joint.joint.dofs() {
                        let gm = prefix * joint.joint.derivative_dual(z, k) * suffix;
                        for (j, x) in b.rest.iter().enumerate() {
                            let d = gm * x.map(Dual64::from);
                            visit(
                                l,
                                joint.dof_offset + k,
                                vertex0 + j,
                                Vector3::new(d[0].eps, d[1].eps, d[2].eps),
                            );
                        }
                    }
                    suffix = local[v] * suffix;
                    match joint.parent {
                        Some(p) => v = p,
                        None => break,
                    }
                }
                vertex0 += b.rest.len();
            }
        }
    }

    /// The adjoint of [`Skeleton::update`]: given the adjoint `after` of the state after the
    /// increment `dz` (in the charts of [`Joint::transform_dual`]), write the adjoint of the
    /// state before it into `before` and that of `dz` into `dz_bar` (both overwritten).
    pub fn update_adjoint(&self, dz: &[f64], after: &[f64], before: &mut [f64], dz_bar: &mut [f64]) {
        let mut jz = [0.0; 36];
        let mut jdz = [0.0; 36];
        for b in &self.bones {
            let (o, n) = (b.dof_offset, b.joint.dofs());
            if n == 0 {
                continue;
            }
            b.joint
                .update_jacobians(&dz[o..o + n], &mut jz[..n * n], &mut jdz[..n * n]);
            for c in 0..n {
                let (mut s1, mut s2) = (0.0, 0.0);
                for r in 0..n {
                    s1 += jz[r * n + c] * after[o + r];
                    s2 += jdz[r * n + c] * after[o + r];
                }
                before[o + c] = s1;
                dz_bar[o + c] = s2;
            }
        }
    }

    /// Largest change of a distance between two vertices of the same bone (or a vertex and the
    /// bone's first vertex) relative to the rest state, over all bones.
    pub fn bone_length_error(&self, q: &[Vector3<f64>]) -> f64 {
        let mut worst = 0.0f64;
        for b in &self.bones {
            for i in 0..b.vertices.len() {
                for j in i + 1..b.vertices.len() {
                    let now = (q[b.vertices[i]] - q[b.vertices[j]]).norm();
                    let rest = (b.rest[i] - b.rest[j]).xyz().norm();
                    worst = worst.max((now - rest).abs());
                }
            }
        }
        worst
    }

    /// Every joint's coordinates, bone by bone (for reports).
    pub fn coordinates(&self) -> Vec<(String, Vec<f64>)> {
        self.bones
            .iter()
            .map(|b| (b.name.clone(), b.joint.coordinates()))
            .collect()
    }
}
