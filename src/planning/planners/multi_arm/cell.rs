//! The certificate of a multi-arm motion: a composite configuration (every arm's planned
//! variables, arm by arm) put into the whole world — fixed bodies, every robot, what each holds —
//! and a straight composite segment proven free as a continuous motion of all arms moving
//! together by [`FastChecker::motion_certified`] (the check of today's multi-robot schedules
//! and single-arm plans; its module documentation gives the bound). Every returned plan passes
//! it segment by segment, whichever method found it.

use super::problem::MultiArmProblem;
use crate::collision::{CollisionChecker, FastChecker};

/// The whole world with every arm's variables active (the others frozen at their start).
pub(crate) struct Cell {
    vars: Vec<usize>,
    checker: FastChecker,
    qa: Vec<f64>,
    qb: Vec<f64>,
    /// Certified segment checks so far.
    pub segments: u64,
}

impl Cell {
    pub fn new(p: &MultiArmProblem) -> Cell {
        let vars = p.vars();
        let checker = FastChecker::for_active(&p.world, Default::default(), &vars, &p.world_q);
        Cell {
            vars,
            checker,
            qa: p.world_q.clone(),
            qb: p.world_q.clone(),
            segments: 0,
        }
    }

    fn write(vars: &[usize], c: &[f64], q: &mut [f64]) {
        for (&v, &x) in vars.iter().zip(c) {
            q[v] = x;
        }
    }

    /// Whether composite configuration `c` is free.
    pub fn state_free(&mut self, c: &[f64]) -> bool {
        Self::write(&self.vars, c, &mut self.qa);
        self.checker.is_free(&self.qa)
    }

    /// The first colliding pair at `c`, for messages.
    pub fn contact(&mut self, c: &[f64]) -> Option<String> {
        Self::write(&self.vars, c, &mut self.qa);
        self.checker
            .first_contact(&self.qa)
            .map(|k| format!("{} with {}", k.a, k.b))
    }

    /// Whether the straight composite motion a → b is proven free (ends included).
    pub fn segment_free(&mut self, a: &[f64], b: &[f64]) -> bool {
        Self::write(&self.vars, a, &mut self.qa);
        Self::write(&self.vars, b, &mut self.qb);
        self.segments += 1;
        self.checker.motion_certified(&self.qa, &self.qb)
    }

    /// The first segment of `path` that is not proven free.
    pub fn first_unproven(&mut self, path: &[Vec<f64>]) -> Option<usize> {
        if path.len() == 1 {
            return (!self.state_free(&path[0])).then_some(0);
        }
        path.windows(2)
            .position(|w| !self.segment_free(&w[0], &w[1]))
    }
}
