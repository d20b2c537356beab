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
