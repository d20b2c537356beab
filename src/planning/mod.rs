//! Motion planning, in OMPL's vocabulary (Şucan, Moll & Kavraki, "The Open Motion Planning
//! Library", IEEE RAM 2012): a [`JointSpace`] (state space of some world variables), a
//! [`Termination`] condition, RRT [`Tree`]s, the [`RrtConnect`] planner, path [`shortcut`]ting and a
//! [`PlanResult`] carrying the path and its [`PlanStats`]. The grasp planners of the papers build
//! on them: [`IkRrt`] (000 Alg. 3), [`JPlusRrt`] and [`DualArmJPlusRrt`] (000 Alg. 1–2, 4–5),
//! the problems they solve in [`grasping`] (grasp, place, dual-arm re-grasp, two-robot hand-off),
//! [`bimanual_ik_rrt`] (002 Alg. 2) and the chained tasks in [`task`] (000 §VI-C kitchen task).
//! [`visibility_prm`] builds compact roadmaps, [`super_graph`] composes those of torso + each arm
//! into one roadmap of a humanoid (003 §V-A), kept on disk by [`roadmap_cache`] and queried with
//! lazy revalidation by [`roadmap_query`] (003 §V-B).
//!
//! This module owns planning. It uses `collision`, `kinematics` and `model`, and must not depend on
//! the server (no tokio, no axum, no HTTP types): a planner is a function of (problem, settings,
//! termination, seed) → result with statistics. [`mbm`] loads the MotionBenchMaker problem sets
//! used as the outside benchmark. [`timing`] gives a path its time-optimal parameterisation
//! (TOPP-RA, Pham & Pham 2018) under joint velocity and acceleration limits.

pub mod bimanual_ik_rrt;
pub mod decoupled;
pub mod grasping;
pub mod halton;
mod ik_rrt;
pub mod j_plus_rrt;
pub mod mbm;
pub mod mbm_data;
pub mod mbm_gen;
pub mod multi_arm;
pub mod multi_arm_cells;
pub mod multi_robot_rrt;
pub mod phase_space;
pub mod pick_place;
pub mod range;
mod result;
mod rng;
pub mod roadmap_cache;
pub mod roadmap_query;
mod rrt_connect;
pub mod shortcut;
mod space;
pub mod super_graph;
pub mod task;
mod termination;
pub mod timing;
pub mod trajectory;
mod tree;
mod validity;
pub mod visibility_prm;

pub use ik_rrt::{GoalSampler, IkRrt, IkRrtSettings};
pub use j_plus_rrt::{DualArmJPlusRrt, JPlusRrt, JPlusRrtSettings};
pub use result::{PlanError, PlanResult, PlanStats};
pub(crate) use rng::DomainPretest;
pub use rng::PlannerRng;
pub use rrt_connect::{RrtConnect, RrtConnectSettings, Sampler};
pub use shortcut::{ShortcutSettings, ShortcutStats};
pub use space::JointSpace;
pub use termination::{StopReason, Termination};
pub use tree::{DomainBall, Tree, NO_PARENT};
pub use validity::{space_checker, SegmentChecker, SpaceValidator};
