//! Forward kinematics of every link in one pass over the (topologically ordered) tree.

use nalgebra::{Translation3, UnitQuaternion};

use crate::geometry::Pose;
use crate::model::{JointKind, Robot};

/// Motion of joint `j` at value `v` (in the joint frame).
#[inline]
pub(crate) fn joint_motion(
    kind: JointKind,
    axis: &nalgebra::Unit<nalgebra::Vector3<f64>>,
    v: f64,
) -> Pose {
    match kind {
        JointKind::Revolute | JointKind::Continuous => Pose::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(axis, v),
        ),
        JointKind::Prismatic => Pose::from_parts(
            Translation3::from(axis.into_inner() * v),
            UnitQuaternion::identity(),
        ),
        JointKind::Fixed => Pose::identity(),
    }
}

/// Poses of all links in the frame `base` is given in: `out[l] = base * T_root→l(q)`.
/// `out` must have `robot.links.len()` entries. Allocates nothing.
#[inline]
pub fn forward(robot: &Robot, base: &Pose, q: &[f64], out: &mut [Pose]) {
    debug_assert_eq!(out.len(), robot.links.len());
    debug_assert_eq!(q.len(), robot.dof());
    out[0] = *base;
    for (ji, j) in robot.joints.iter().enumerate() {
        let parent = out[j.parent];
        let local = if j.kind == JointKind::Fixed {
            j.origin
        } else {
            j.origin * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q))
        };
        out[j.child] = parent * local;
    }
}

/// Pose of one link relative to the robot root (walks only the path to it).
pub fn link_pose(robot: &Robot, q: &[f64], link: usize) -> Pose {
    let mut pose = Pose::identity();
    let mut l = link;
    while let Some(ji) = robot.links[l].parent_joint {
        let j = &robot.joints[ji];
        pose = j.origin * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q)) * pose;
        l = j.parent;
    }
    pose
}

/// Reusable FK buffer (one per thread), so hot loops allocate nothing.
#[derive(Debug, Clone)]
pub struct ForwardKinematics {
    pub poses: Vec<Pose>,
}

impl ForwardKinematics {
    pub fn new(robot: &Robot) -> Self {
        ForwardKinematics {
            poses: vec![Pose::identity(); robot.links.len()],
        }
    }

    /// Computes all link poses relative to `base` and returns them.
    pub fn compute(&mut self, robot: &Robot, base: &Pose, q: &[f64]) -> &[Pose] {
        forward(robot, base, q, &mut self.poses);
        &self.poses
    }
}
