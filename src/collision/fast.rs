//! Fast conservative collision checking (being written).
use super::{CollisionChecker, CollisionWorld, Contact};
/// Settings of the fast model.
#[derive(Debug, Clone, Copy)]
pub struct FastModelSettings;
/// Planner checker.
pub struct FastChecker {
    checks: u64,
}
impl FastChecker {
    pub fn new(_w: &CollisionWorld) -> Self {
        FastChecker { checks: 0 }
    }
}
impl CollisionChecker for FastChecker {
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
