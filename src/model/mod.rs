//! The robot and scene model: `Robot` from URDF + SRDF, `Scene` from scene JSON.
//!
//! Pure data, loaders and validation errors. Depends only on `geometry`; knows nothing of
//! kinematics algorithms, collision checking or planning — except that the robot loaders end
//! with the sampled search for always-colliding link pairs of `collision::always` (MoveIt's
//! "Always" category), which needs forward kinematics and the exact checker.

mod cell;
mod error;
mod joint_limits;
mod library;
mod robot;
mod scene;
pub mod spherize;
mod srdf;
mod urdf;
mod write;

pub use cell::{arm_cell, panda_four, ArmCell};
pub use error::ModelError;
pub use joint_limits::{parse_joint_limits, VarDynamics, DEFAULT_ACCELERATION, DEFAULT_VELOCITY};
pub use library::{data_root, load_robot_dir, load_scene_dir, load_scene_dir_lenient};
pub use robot::{
    AlwaysColliding, EndEffector, Group, GroupMember, GroupState, Joint, JointKind, Limits, Link,
    Mimic, Robot, RobotLibrary, Visual, VisualGeometry,
};
pub use scene::{
    Body, BodyJson, ContactPoint, GeometryJson, Grasp, GraspJson, GraspType, Object,
    RobotPlacement, RobotPlacementJson, Scene, SceneJson,
};
pub use write::{to_srdf, to_urdf};
