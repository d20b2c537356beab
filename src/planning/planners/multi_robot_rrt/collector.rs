//! The collector of Multi-Robot-RRT (paper 002 Alg. 3 lines 7–10, §IV-B/C): stores every
//! worker's solutions and checks each new combination once, cheapest test first — the final
//! poses against each other, the grasp score, the deadlock check (002 eq. 2) — with pairwise
//! verdict caches (see the parent module's documentation).

use std::collections::HashMap;
use std::time::Instant;

use super::{
    MultiRobotEvent, MultiRobotProblem, MultiRobotSettings, MultiRobotStats, Rejection, Solution,
    WorkerStats,
};
use crate::collision::{CollisionChecker, FastChecker};
use crate::grasp::{
    quality_of_wrenches_nearest, score_exceeds_nearest, GraspQuality, Point6, WrenchSpaceSettings,
};
use crate::planning::PlanError;

/// Pairwise verdict caches and checkers of the collector.
pub(super) struct Collector<'p> {
    p: &'p MultiRobotProblem,
    s_min: f64,
    wrench: WrenchSpaceSettings,
    pub(super) solutions: Vec<Vec<Solution>>,
    /// Per pair (a < b) of members: a checker of the two robots alone.
    pair: HashMap<(usize, usize), (FastChecker, Vec<f64>)>,
    /// (a, i, b, j) → final configurations collide.
    goal_hit: HashMap<(usize, usize, usize, usize), bool>,
    /// (a, i, b, j) → deadlock (either way).
    dead: HashMap<(usize, usize, usize, usize), bool>,
    /// Cone edges of the score level that passed the last accepted combination.
    pub(super) score_edges: usize,
    pub(super) stats: MultiRobotStats,
}

impl<'p> Collector<'p> {
    pub(super) fn new(p: &'p MultiRobotProblem, settings: &MultiRobotSettings) -> Collector<'p> {
        let n = p.members.len();
        let mut pair = HashMap::new();
        for a in 0..n {
            for b in a + 1..n {
                let keep = [p.members[a].robot, p.members[b].robot];
                if let Some(w) = p.world.subset(&keep) {
                    let between = w.between_robots();
                    let q = p.world.subset_config(&keep, &p.world_q);
                    pair.insert((a, b), (FastChecker::new(&between), q));
                }
            }
        }
        Collector {
            p,
            s_min: settings.s_min,
            wrench: settings.wrench,
            solutions: vec![Vec::new(); n],
            pair,
            goal_hit: HashMap::new(),
            dead: HashMap::new(),
            score_edges: settings.wrench.cone_edges,
            stats: MultiRobotStats {
                workers: p
                    .members
                    .iter()
                    .map(|m| WorkerStats {
                        name: m.name.clone(),
                        ..WorkerStats::default()
                    })
                    .collect(),
                best_score: 0.0,
                ..MultiRobotStats::default()
            },
        }
    }

    /// Whether `qa` of member a and `qb` of member b collide (`a < b`).
    fn pair_state_hits(&mut self, a: usize, b: usize, qa: &[f64], qb: &[f64]) -> bool {
        let Some((c, q)) = self.pair.get_mut(&(a, b)) else {
            return false;
        };
        let na = qa.len();
        q[..na].copy_from_slice(qa);
        q[na..].copy_from_slice(qb);
        self.stats.collector_checks += 1;
        !c.is_free(q)
    }

    /// Whether member `fixed` at `c` collides with member `moving` anywhere along `path`
    /// (continuous motion).
    fn config_hits_path(
        &mut self,
        fixed: usize,
        c: &[f64],
        moving: usize,
        path: &[Vec<f64>],
    ) -> bool {
        let (a, b) = (fixed.min(moving), fixed.max(moving));
        let Some((checker, q)) = self.pair.get_mut(&(a, b)) else {
            return false;
        };
        let split = if fixed < moving {
            c.len()
        } else {
            path[0].len()
        };
        let mut qa = q.clone();
        let mut qb = q.clone();
        let load = |dst: &mut Vec<f64>, m: &[f64]| {
            if fixed < moving {
                dst[..split].copy_from_slice(c);
                dst[split..].copy_from_slice(m);
            } else {
                dst[..split].copy_from_slice(m);
                dst[split..].copy_from_slice(c);
            }
        };
        if path.len() == 1 {
            load(&mut qa, &path[0]);
            self.stats.collector_checks += 1;
            return !checker.is_free(&qa);
        }
        for w in path.windows(2) {
            load(&mut qa, &w[0]);
            load(&mut qb, &w[1]);
            self.stats.collector_checks += 1;
            if !checker.motion_certified(&qa, &qb) {
                return true;
            }
        }
        false
    }

    /// Stores a new solution (reported as a [`MultiRobotEvent::Solution`]) and checks the
    /// combinations it enables; the first that passes.
    pub(super) fn add(
        &mut self,
        s: Solution,
        progress: &mut dyn FnMut(MultiRobotEvent<'_>),
    ) -> Option<(Vec<usize>, GraspQuality)> {
        let k = s.member;
        self.solutions[k].push(s);
        let sk = self.solutions[k].len() - 1;
        progress(MultiRobotEvent::Solution {
            robot: &self.p.members[k].name,
            count: self.solutions[k].len() as u64,
        });
        let n = self.solutions.len();
        if (0..n).any(|j| j != k && self.solutions[j].is_empty()) {
            return None;
        }
        // Every combination with sk at k: a mixed-radix counter over the others.
        let others: Vec<usize> = (0..n).filter(|&j| j != k).collect();
        let mut idx = vec![0usize; n];
        idx[k] = sk;
        loop {
            let verdict = self.check(&idx);
            self.stats.combinations += 1;
            let (rejected, score) = match &verdict {
                Ok(q) => (None, Some(q.epsilon)),
                Err((r, sc)) => (Some(*r), *sc),
            };
            if let Some(e) = score {
                self.stats.best_score = self.stats.best_score.max(e);
            }
            match rejected {
                Some(Rejection::Collision) => self.stats.rejected_collision += 1,
                Some(Rejection::Score) => self.stats.rejected_score += 1,
                Some(Rejection::Deadlock) => self.stats.rejected_deadlock += 1,
                None => {}
            }
            progress(MultiRobotEvent::Combination {
                checked: self.stats.combinations,
                rejected,
                score,
                best: self.stats.best_score,
            });
            if let Ok(q) = verdict {
                return Some((idx, q));
            }
            // Next combination.
            let mut carry = true;
            for &j in &others {
                if !carry {
                    break;
                }
                idx[j] += 1;
                if idx[j] < self.solutions[j].len() {
                    carry = false;
                } else {
                    idx[j] = 0;
                }
            }
            if carry {
                return None;
            }
        }
    }

    /// One combination: final poses, score, deadlock (cheapest first).
    fn check(&mut self, idx: &[usize]) -> Result<GraspQuality, (Rejection, Option<f64>)> {
        let n = idx.len();
        for a in 0..n {
            for b in a + 1..n {
                let key = (a, idx[a], b, idx[b]);
                let hit = match self.goal_hit.get(&key) {
                    Some(&h) => h,
                    None => {
                        let qa = self.solutions[a][idx[a]]
                            .path
                            .last()
                            .cloned()
                            .unwrap_or_default();
                        let qb = self.solutions[b][idx[b]]
                            .path
                            .last()
                            .cloned()
                            .unwrap_or_default();
                        let h = self.pair_state_hits(a, b, &qa, &qb);
                        self.goal_hit.insert(key, h);
                        h
                    }
                };
                if hit {
                    return Err((Rejection::Collision, None));
                }
            }
        }
        let grasps: Vec<(usize, usize)> =
            (0..n).map(|k| self.solutions[k][idx[k]].grasps).collect();
        // The score: a cheap proof that ε > s_min first; the exact ε only where it is reported
        // (a rejection's score, the accepted combination).
        let t = Instant::now();
        let wrenches = self.p.combination_wrenches(&grasps, &self.wrench);
        let passes = match &wrenches {
            Ok((w, _)) => score_exceeds_nearest(w, self.s_min),
            Err(_) => false,
        };
        self.stats.scores += 1;
        let mut exact = None;
        if !passes {
            let q = self.exact_score(&wrenches);
            self.stats.score_time += t.elapsed();
            match q {
                Some(q) if q.force_closure && q.epsilon > self.s_min => exact = Some(q),
                Some(q) => return Err((Rejection::Score, Some(q.epsilon))),
                None => return Err((Rejection::Score, None)),
            }
        } else {
            self.stats.score_time += t.elapsed();
        }
        let mut exact = |c: &mut Collector<'_>| -> Option<GraspQuality> {
            if exact.is_none() {
                let t = Instant::now();
                exact = c.exact_score(&wrenches);
                c.stats.score_time += t.elapsed();
            }
            exact
        };
        for a in 0..n {
            for b in a + 1..n {
                let key = (a, idx[a], b, idx[b]);
                let dead = match self.dead.get(&key) {
                    Some(&d) => d,
                    None => {
                        let d = self.deadlock(a, idx[a], b, idx[b]);
                        self.dead.insert(key, d);
                        d
                    }
                };
                if dead {
                    let e = exact(self).map(|q| q.epsilon);
                    return Err((Rejection::Deadlock, e));
                }
            }
        }
        // Proven above s_min, so the exact computation agrees; a failure there (numerically
        // degenerate hull) rejects the combination as the exact path alone would.
        match exact(self) {
            Some(q) if q.force_closure && q.epsilon > self.s_min => Ok(q),
            Some(q) => Err((Rejection::Score, Some(q.epsilon))),
            None => Err((Rejection::Score, None)),
        }
    }

    /// The exact score of a combination's wrenches ([`quality_of_wrenches_nearest`]); `None`
    /// when they cannot be scored.
    fn exact_score(&mut self, w: &Result<(Vec<Point6>, f64), PlanError>) -> Option<GraspQuality> {
        let (w, lambda) = w.as_ref().ok()?;
        self.stats.exact_scores += 1;
        quality_of_wrenches_nearest(w, *lambda).ok()
    }

    /// 002 eq. 2 for the pair (a, b): a's start and goal against b's trajectory, and b's
    /// against a's.
    fn deadlock(&mut self, a: usize, i: usize, b: usize, j: usize) -> bool {
        let pa = self.solutions[a][i].path.clone();
        let pb = self.solutions[b][j].path.clone();
        for (fixed, c, moving, path) in [
            (a, &pa[0], b, &pb),
            (a, &pa[pa.len() - 1], b, &pb),
            (b, &pb[0], a, &pa),
            (b, &pb[pb.len() - 1], a, &pa),
        ] {
            if self.config_hits_path(fixed, c, moving, path) {
                return true;
            }
        }
        false
    }
}
