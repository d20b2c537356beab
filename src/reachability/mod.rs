//! Reachability spaces (paper 000 = Vahrenkamp et al. 2009, §II-B; paper 002 = Vahrenkamp et al.
//! 2010, §III) and the collision glue of the randomized IK solvers.
//!
//! Owns:
//! * [`ReachabilityGrid`]: the 6-D voxel grid over the TCP pose (x, y, z, roll, pitch, yaw) in the
//!   frame of a chain's base, filled by sampling self-collision-free joint configurations through
//!   FK (000 §II-B), with its versioned binary file format and an SVG slice plot;
//! * [`GraspCheckers`] / [`ObjectPlacement`]: collision checking of IK answers with the grasped
//!   object attached to the hand, and of free object poses against the obstacles;
//! * [`inverse`]: inverse reachability maps, their union over grasp sets, the bimanual map
//!   R_bi = min(R_left, R_right) and the base-placement dual-arm IK (002 §III-A/B/C, Alg. 1);
//! * [`queries`]: ready-made single-arm and dual-arm IK queries on scene objects (scene grasps →
//!   the solvers of `kinematics::randomized` / `kinematics::dual_arm`).
//!
//! Depends on `model`, `kinematics`, `collision` and `geometry`; it must not depend on planning or
//! the server.

pub mod cache;
mod grid;
pub mod inverse;
pub mod queries;
mod svg;
mod validity;

pub use cache::{GridCache, GridRecipe};
pub use grid::{chain_hash, BuildStats, GridParams, ReachError, ReachabilityGrid, FORMAT_VERSION};
pub use svg::{slice_svg, SliceAxes};
pub use validity::{hand_links, GraspCheckers, ObjectPlacement};
