//! Collision checking, the hot path of every planner.
//!
//! `CollisionWorld` says what is checked against what (robot links, fixed obstacles, free and
//! attached objects, SRDF-disabled pairs, touch links). Two `CollisionChecker`s answer the same
//! question: `ExactChecker` (parry3d shapes, the reference used by tests) and `FastChecker`
//! (conservative primitive model, no allocation per check; its segment check skips runs of
//! states it proves free with swept-volume bounds) and `SphereChecker` (robots made of spheres,
//! 8 states per call). `MotionValidator` checks straight segments between configurations.
//!
//! Depends on `model`, `kinematics`, `geometry`; must not depend on planning or the server.

pub mod always;
mod exact;
mod fast;
mod generate;
mod gjk;
mod motion;
mod spheres;
mod world;

pub use exact::ExactChecker;
pub(crate) use exact::{is_solid_mesh, parry_shape, to_parry};
pub use fast::{Certification, CertifyStats, FastChecker, FastModelSettings};
pub use generate::{random_boxes, random_config_near, RandomBoxes};
pub use motion::MotionValidator;
pub use spheres::{AutoChecker, CertifyCounts, SegmentScreen, SphereChecker, LANES};
pub use world::{AttachedBody, BodyId, CollisionWorld, PlacedRobot, StaticBody, StaticKind};

/// Two bodies found in collision.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Contact {
    /// Name of the first body (`robot/link`, `obstacle:name`, `object:name`).
    pub a: String,
    /// Name of the second body.
    pub b: String,
}

/// "Is configuration q of the world's robots free?" — q is the concatenation of every robot's
/// configuration in scene order (see [`CollisionWorld::dof`]).
pub trait CollisionChecker: Send {
    /// True when no checked pair of bodies intersects.
    fn is_free(&mut self, q: &[f64]) -> bool;
    /// The first colliding pair found, if any (for reports; may allocate).
    fn first_contact(&mut self, q: &[f64]) -> Option<Contact>;
    /// Number of configuration checks performed so far.
    fn checks(&self) -> u64;
}
