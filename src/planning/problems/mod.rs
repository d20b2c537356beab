//! The problems the grasp planners solve (OMPL's problem definitions with their goals): the
//! grasp, place, dual-arm re-grasp and hand-off problems of paper 000 on a scene and their goal
//! samplers ([`grasping`]). They use [`super::base`]; the planners ([`super::planners`]) and
//! the tasks ([`super::tasks`]) use them.

pub mod grasping;
