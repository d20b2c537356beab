//! Geometry shared by every layer: poses (nalgebra `Isometry3<f64>`), their JSON form, and the
//! primitive and mesh shapes that robots and scenes are made of.
//!
//! Owns no knowledge of robots, scenes or collision algorithms; depends on nothing in the crate.

mod pose;
mod shape;
mod solid;
mod trig;

pub use pose::{iso_from_rpy, quat_from_rpy, quat_to_rpy, Pose, PoseJson};
pub use shape::{Geometry, Mesh, Shape};
pub use solid::{CoverBox, Solid, COVER_CELLS, MAX_COVER_BOXES, MAX_MOVING_COVER_BOXES};
pub use trig::{atan2, sin_cos, sin_cos_lanes};

/// Distance of point `p` from the line through the origin along `axis` (any length; a zero
/// axis gives the distance from the origin). The lever arm of `p` about a revolute joint
/// whose axis passes through the frame's origin: the speed bounds of the certified motion
/// checks (`FkModel::speed_bounds`, `SphereChecker`) use it.
pub fn distance_from_axis(p: &nalgebra::Vector3<f64>, axis: &nalgebra::Vector3<f64>) -> f64 {
    let n = axis.norm();
    if n > 0.0 {
        p.cross(axis).norm() / n
    } else {
        p.norm()
    }
}
