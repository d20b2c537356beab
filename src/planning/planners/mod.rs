//! The papers' planners, one file or folder each, named after the algorithm they implement
//! (their headers cite it). They stand on [`super::base`]; none uses a task.

pub mod bimanual_ik_rrt;
pub mod decoupled;
pub(crate) mod ik_rrt;
pub mod j_plus_rrt;
pub mod multi_arm;
pub mod multi_robot_rrt;
pub mod phase_space;
pub mod roadmap_cache;
pub mod roadmap_query;
pub(crate) mod rrt_connect;
pub mod super_graph;
pub mod visibility_prm;

pub use ik_rrt::{IkRrt, IkRrtSettings};
pub use j_plus_rrt::{DualArmJPlusRrt, JPlusRrt, JPlusRrtSettings};
pub use rrt_connect::{RrtConnect, RrtConnectSettings, Sampler};
