//! manyhands: multi-robot grasp-and-motion planning.
//!
//! Layers (a module may use only the ones below it):
//! `collision`, `kinematics` → `model` → `geometry`.
//! The planning core never depends on tokio or axum. The HTTP API's request/response types are
//! the `manyhands-api` crate (re-exported in [`server::api`]); the Rust client is the separate
//! `manyhands-client` crate, which depends on none of this one.

pub mod benchmark;
pub mod cache_tier;
pub mod collision;
pub mod geometry;
pub mod grasp;
pub mod kinematics;
pub mod model;
pub mod planning;
pub mod reachability;
pub mod server;
pub mod skips;
pub mod trajectory;

pub use model::{Robot, Scene};
