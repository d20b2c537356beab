//! Motion validation: a straight joint-space segment is checked at a fixed resolution.

use super::{CollisionChecker, CollisionWorld};
use crate::model::JointKind;

/// Checks straight segments between two world configurations with a `CollisionChecker`.
///
/// The segment is cut into `n` equal steps so that no revolute variable moves more than
/// `angular` radians and no prismatic variable more than `linear` metres per step; the
/// intermediate states and the end state are checked in bisection order (midpoint first, then
/// quarter points, …) so a blocked segment is usually rejected after a few checks.
/// The start state is assumed valid. Allocates only at construction.
pub struct MotionValidator<C: CollisionChecker> {
    pub checker: C,
    /// Per world variable: the largest step allowed.
    step_limit: Vec<f64>,
    scratch: Vec<f64>,
    order: Vec<u32>,
    segments: u64,
}

impl<C: CollisionChecker> MotionValidator<C> {
    /// `angular` in radians, `linear` in metres (e.g. 0.5° and 5 mm).
    pub fn new(world: &CollisionWorld, checker: C, angular: f64, linear: f64) -> Self {
        let mut step_limit = Vec::with_capacity(world.dof());
        for p in &world.robots {
            for v in 0..p.robot.dof() {
                let j = &p.robot.joints[p.robot.vars[v]];
                step_limit.push(if j.kind == JointKind::Prismatic {
                    linear
                } else {
                    angular
                });
            }
        }
        let n = step_limit.len();
        MotionValidator {
            checker,
            step_limit,
            scratch: vec![0.0; n],
            order: Vec::new(),
            segments: 0,
        }
    }

    /// Number of steps the segment `a → b` is cut into.
    pub fn steps(&self, a: &[f64], b: &[f64]) -> usize {
        let mut n = 1.0f64;
        for i in 0..a.len() {
            n = n.max(((b[i] - a[i]).abs() / self.step_limit[i]).ceil());
        }
        n as usize
    }

    /// True when every state of the segment `a → b` (end included, start excluded) is free.
    pub fn is_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        self.segments += 1;
        let n = self.steps(a, b);
        if self.order.len() != n {
            bisection_order(n, &mut self.order);
        }
        for k in 0..self.order.len() {
            let t = self.order[k] as f64 / n as f64;
            for i in 0..a.len() {
                self.scratch[i] = a[i] + (b[i] - a[i]) * t;
            }
            if !self.checker.is_free(&self.scratch) {
                return false;
            }
        }
        true
    }

    /// Checks a whole path (its first state included).
    pub fn is_path_valid(&mut self, path: &[Vec<f64>]) -> bool {
        match path.first() {
            None => true,
            Some(first) => {
                self.checker.is_free(first) && path.windows(2).all(|w| self.is_valid(&w[0], &w[1]))
            }
        }
    }

    /// Segments checked so far.
    pub fn segments(&self) -> u64 {
        self.segments
    }
}

/// Indices 1..=n in bisection order: n first (the end), then n/2, n/4, 3n/4, …
pub(crate) fn bisection_order(n: usize, out: &mut Vec<u32>) {
    out.clear();
    out.push(n as u32);
    let mut seen = vec![false; n + 1];
    seen[n] = true;
    seen[0] = true;
    let mut denom = 2usize;
    while out.len() < n {
        for k in (1..denom).step_by(2) {
            let i = (k * n) / denom;
            if !seen[i] {
                seen[i] = true;
                out.push(i as u32);
            }
        }
        if denom > 2 * n {
            for (i, s) in seen.iter_mut().enumerate() {
                if !*s {
                    *s = true;
                    out.push(i as u32);
                }
            }
        }
        denom *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::bisection_order;

    #[test]
    fn bisection_order_visits_every_step_once() {
        for n in 1..200 {
            let mut o = Vec::new();
            bisection_order(n, &mut o);
            let mut s = o.clone();
            s.sort();
            assert_eq!(s, (1..=n as u32).collect::<Vec<_>>(), "n = {n}");
        }
    }
}
