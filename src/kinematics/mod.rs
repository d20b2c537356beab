//! Kinematics in f64: forward kinematics of all links in one pass, geometric Jacobians of chains,
//! and inverse kinematics (analytic S-R-S arm IK, numeric damped least squares).
//!
//! Depends on `model` and `geometry` only; knows nothing of collision or planning.

mod chain;
pub mod dual_arm;
mod fk;
pub mod numeric;
pub mod randomized;
pub mod srs;

pub use chain::Chain;
pub use fk::{
    forward, link_pose, FkModel, FkPath, FkPathPair, ForwardKinematics, Frame, SpeedAxis,
};
pub use numeric::{pose_error, IkFailure, IkSettings, IkStats, NumericIk};
pub use srs::{SolutionOrder, SrsArm, SrsError};
