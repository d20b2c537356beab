//! manyhands: multi-robot grasp-and-motion planning.
//!
//! Layers (a module may use only the ones below it):
//! `collision`, `kinematics` → `model` → `geometry`.
//! The planning core never depends on tokio or axum.

pub mod client;
pub mod collision;
pub mod geometry;
pub mod grasp;
pub mod kinematics;
pub mod model;
pub mod planning;
pub mod reachability;
pub mod server;

pub use model::{Robot, Scene};
