//! Problems chained from planners: the kitchen task with its grasps, places, dual-arm re-grasps
//! and hand-offs ([`task`], 000 §VI-C) and the two-hand pick-and-place ([`pick_place`], 003).
//! They use [`super::planners`], [`super::problems`] and [`super::base`].

pub mod pick_place;
pub mod task;
