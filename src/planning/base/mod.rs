//! The OMPL-like core every planner stands on: state space ([`JointSpace`]), validity and motion
//! checking ([`SpaceValidator`]), termination ([`Termination`]), RRT trees ([`Tree`]), samplers
//! ([`PlannerRng`], [`halton`]), the derived range ([`range`]), path shortcutting ([`shortcut`])
//! and results ([`PlanResult`]). It uses `collision`, `kinematics` and `model`, never a planner.

mod goal;
pub mod halton;
pub mod range;
pub(crate) mod result;
pub(crate) mod rng;
pub mod shortcut;
pub(crate) mod space;
pub(crate) mod termination;
pub(crate) mod tree;
pub(crate) mod validity;

pub use goal::GoalSampler;
pub use result::{PlanError, PlanResult, PlanStats};
pub(crate) use rng::DomainPretest;
pub use rng::PlannerRng;
pub use shortcut::{ShortcutSettings, ShortcutStats};
pub use space::JointSpace;
pub use termination::{StopReason, Termination};
pub use tree::{DomainBall, Tree, NO_PARENT};
pub use validity::{space_checker, SegmentChecker, SpaceValidator};
