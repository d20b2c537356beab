//! Problems chained from planners: grasping and placing, dual-arm re-grasping and hand-offs
//! ([`grasping`], 000), the kitchen task ([`task`], 000 §VI-C) and the two-hand pick-and-place
//! ([`pick_place`], 003). They use [`super::planners`] and [`super::base`].

pub mod grasping;
pub mod pick_place;
pub mod task;
