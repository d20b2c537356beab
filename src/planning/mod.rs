//! Motion planning, in OMPL's vocabulary (Şucan, Moll & Kavraki, "The Open Motion Planning
//! Library", IEEE RAM 2012), in three layers, each folder one of them:
//!
//! - [`base`]: what every planner stands on — the [`JointSpace`] (state space of some world
//!   variables), validity and motion checking ([`SpaceValidator`], [`space_checker`]), the
//!   [`Termination`] condition, RRT [`Tree`]s, samplers ([`PlannerRng`], [`base::halton`]), the
//!   range derived from the robot ([`base::range`]), sampled goals ([`GoalSampler`]), path
//!   [`base::shortcut`]ting and the [`PlanResult`] with its [`PlanStats`]. It uses `collision`,
//!   `kinematics` and `model` only.
//! - [`problems`]: the problems the grasp planners solve and their goal samplers —
//!   [`problems::grasping`] (grasp, place, dual-arm re-grasp, two-robot hand-off, paper 000). It
//!   uses [`base`].
//! - [`planners`]: the papers' planners, one file or folder each — [`RrtConnect`], [`IkRrt`]
//!   (000 Alg. 3), [`JPlusRrt`] and [`DualArmJPlusRrt`] (000 Alg. 1–2, 4–5),
//!   [`planners::bimanual_ik_rrt`] (002 Alg. 2), [`planners::multi_robot_rrt`] (002 Alg. 3) and
//!   its [`planners::phase_space`] schedule (002 Alg. 4), [`planners::multi_arm`] (independent
//!   arms in one cell), [`planners::visibility_prm`] and [`planners::super_graph`] (003 §V-A),
//!   kept on disk by [`planners::roadmap_cache`] and queried with lazy revalidation by
//!   [`planners::roadmap_query`] (003 §V-B), [`planners::decoupled`] (prioritised planning). They
//!   use [`problems`] and [`base`].
//! - [`tasks`]: problems chained from planners — [`tasks::task`] (000 §VI-C kitchen task, its
//!   re-grasps and hand-offs) and [`tasks::pick_place`] (003's two-hand pick-and-place). They use
//!   [`planners`], [`problems`] and [`base`].
//!
//! This module must not depend on the server (no tokio, no axum, no HTTP types): a planner is a
//! function of (problem, settings, termination, seed) → result with statistics. Time
//! parameterisation lives in [`crate::trajectory`], benchmark tooling (MotionBenchMaker data,
//! problem generation, benchmark cells) in [`crate::benchmark`]; neither is used from here
//! except the trajectory timing the multi-robot schedules need.

pub mod base;
pub mod planners;
pub mod problems;
pub mod tasks;

pub(crate) use base::DomainPretest;
pub use base::{
    space_checker, DomainBall, GoalSampler, JointSpace, PlanError, PlanResult, PlanStats,
    PlannerRng, SegmentChecker, ShortcutSettings, ShortcutStats, SpaceValidator, StopReason,
    Termination, Tree, NO_PARENT,
};
pub use planners::{
    DualArmJPlusRrt, IkRrt, IkRrtSettings, JPlusRrt, JPlusRrtSettings, RrtConnect,
    RrtConnectSettings, Sampler,
};
