//! Exact collision checking with parry3d-f64 shapes (being written).
use super::{CollisionChecker, CollisionWorld, Contact};
/// Reference checker on the real geometry.
pub struct ExactChecker {
    checks: u64,
}
impl ExactChecker {
    pub fn new(_w: &CollisionWorld) -> Self {
        ExactChecker { checks: 0 }
    }
}
impl CollisionChecker for ExactChecker {
    fn is_free(&mut self, _q: &[f64]) -> bool {
        self.checks += 1;
        true
    }
    fn first_contact(&mut self, _q: &[f64]) -> Option<Contact> {
        None
    }
    fn checks(&self) -> u64 {
        self.checks
    }
}
