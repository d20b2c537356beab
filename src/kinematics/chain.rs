//! A serial chain of a robot (base link → tip link, optionally a fixed tip offset), its
//! geometric Jacobian and its forward kinematics relative to the chain base.

use nalgebra::{DMatrix, Matrix6xX, Vector3};

use super::fk::joint_motion;
use crate::geometry::Pose;
use crate::model::{JointKind, Robot};

/// A serial chain between two links of a robot.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub base_link: usize,
    pub tip_link: usize,
    /// Joints from base to tip (every joint on the path, fixed ones included).
    pub joints: Vec<usize>,
    /// Independent variables moved by the chain, in order (mimic joints map onto them).
    pub vars: Vec<usize>,
}

impl Chain {
    /// The chain from `base_link` down to `tip_link`; `None` if tip is not below base.
    pub fn new(robot: &Robot, base_link: usize, tip_link: usize) -> Option<Chain> {
        let links = robot.link_path(base_link, tip_link)?;
        let joints: Vec<usize> = links[1..]
            .iter()
            .filter_map(|&l| robot.links[l].parent_joint)
            .collect();
        let mut vars = Vec::new();
        for &j in &joints {
            let jt = &robot.joints[j];
            let v = jt.var.or(jt.mimic.map(|m| m.var));
            if let Some(v) = v {
                if !vars.contains(&v) {
                    vars.push(v);
                }
            }
        }
        Some(Chain {
            base_link,
            tip_link,
            joints,
            vars,
        })
    }

    /// The chain of an SRDF group that is a chain (`<chain>` or a single chain subgroup).
    pub fn from_group(robot: &Robot, group: &str) -> Option<Chain> {
        let (b, t) = robot.group(group)?.chain?;
        Chain::new(robot, b, t)
    }

    /// Pose of the tip link in the base-link frame.
    pub fn tip_pose(&self, robot: &Robot, q: &[f64]) -> Pose {
        let mut pose = Pose::identity();
        for &ji in &self.joints {
            let j = &robot.joints[ji];
            pose = if j.kind == JointKind::Fixed {
                pose * j.origin
            } else {
                pose * j.origin * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q))
            };
        }
        pose
    }

    /// Geometric Jacobian (6 × `vars.len()`, rows: linear then angular velocity) of the tip in
    /// the base-link frame. Mimic joints add to their master variable's column.
    pub fn jacobian(&self, robot: &Robot, q: &[f64]) -> Matrix6xX<f64> {
        let mut jac = Matrix6xX::zeros(self.vars.len());
        self.jacobian_into(robot, q, &mut jac);
        jac
    }

    /// Jacobian into a preallocated 6 × n matrix, in one pass along the chain with no buffer: a
    /// revolute joint's column is `(z × (tip − p), z)`, which is `(z × tip − z × p, z)`; the
    /// pass adds `−z × p` and `z` (times the mimic multiplier) as it meets each joint and, once
    /// the tip is known, adds `(Σ z) × tip` to the linear rows. Prismatic joints add `z` to the
    /// linear rows only.
    pub fn jacobian_into(&self, robot: &Robot, q: &[f64], jac: &mut Matrix6xX<f64>) {
        jac.fill(0.0);
        let mut pose = Pose::identity();
        for &ji in &self.joints {
            let j = &robot.joints[ji];
            let frame = pose * j.origin;
            if j.kind != JointKind::Fixed {
                let (var, mul) = match (j.var, j.mimic) {
                    (Some(v), _) => (v, 1.0),
                    (None, Some(m)) => (m.var, m.multiplier),
                    _ => (usize::MAX, 0.0),
                };
                if let Some(col) = self.vars.iter().position(|&v| v == var) {
                    let z = frame.rotation * j.axis.into_inner() * mul;
                    let lin = match j.kind {
                        JointKind::Prismatic => z,
                        _ => -z.cross(&frame.translation.vector),
                    };
                    for r in 0..3 {
                        jac[(r, col)] += lin[r];
                    }
                    if j.kind != JointKind::Prismatic {
                        for r in 0..3 {
                            jac[(r + 3, col)] += z[r];
                        }
                    }
                }
                pose = frame * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q));
            } else {
                pose = frame;
            }
        }
        let tip = pose.translation.vector;
        for col in 0..jac.ncols() {
            let w = Vector3::new(jac[(3, col)], jac[(4, col)], jac[(5, col)]);
            let t = w.cross(&tip);
            for r in 0..3 {
                jac[(r, col)] += t[r];
            }
        }
    }

    /// Jacobian as a dynamically sized matrix (for callers that need `DMatrix`).
    pub fn jacobian_dyn(&self, robot: &Robot, q: &[f64]) -> DMatrix<f64> {
        let j = self.jacobian(robot, q);
        DMatrix::from_column_slice(6, self.vars.len(), j.as_slice())
    }
}
