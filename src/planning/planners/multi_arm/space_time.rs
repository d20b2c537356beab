//! Planning one mover (one arm, or several arms as one composite) in space-time around the
//! timed motions of the movers planned before it: the step of prioritized planning (Erdmann &
//! Lozano-Pérez, "On multiple moving objects", Algorithmica 1987; the space-time RRT in the
//! manner of Sintov & Shapiro's time-based RRT, and of the prioritized baselines of VAMP-MR and
//! mr-shortcut).
//!
//! A state is (q, t): the mover's variables and the time on the common clock. The tree grows
//! forward in time only: EXTEND from the nearest node that is earlier than the sample (distance
//! = the time the mover needs to reach the sample at its velocity limits, plus a quarter of
//! the time gap, so late nodes are preferred when the sample lies late — the way a mover
//! learns to wait), moving at most `step` seconds of full-speed motion toward it, slower when
//! the sample's time asks for it (never faster than the velocity limits); some samples are the
//! node's own configuration at a later time (a wait), some the goal. After every new node the
//! goal is tried straight at full speed, then *held*: the mover must stay free at its goal
//! until every earlier mover has ended.
//!
//! **Certificate.** An edge (q_a, t_a) → (q_b, t_b) is cut at every knot time of the earlier
//! motions in between; on each piece every mover (this one and the earlier ones) moves on a
//! straight line of its joint space linearly in time, so the piece is a straight composite
//! segment, proven free as a continuous motion by [`FastChecker::motion_certified`] in the
//! whole world (the movers not yet planned stand at their start, frozen in the checker).

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::timed::{travel_time, Timed};
use crate::collision::{CollisionWorld, FastChecker};
use crate::planning::Termination;

/// Settings of the space-time search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceTimeSettings {
    /// Most EXTEND iterations of one mover's search.
    pub iterations: u64,
    /// Longest EXTEND, in seconds of full-speed motion.
    pub step: f64,
    /// Probability that a sample is the goal.
    pub goal_bias: f64,
    /// Probability that a sample is a wait (the nearest node's configuration, later).
    pub wait_bias: f64,
}

impl Default for SpaceTimeSettings {
    fn default() -> Self {
        SpaceTimeSettings {
            iterations: 1500,
            step: 0.3,
            goal_bias: 0.1,
            wait_bias: 0.15,
        }
    }
}

struct Node {
    q: Vec<f64>,
    t: f64,
    parent: usize,
}

/// The search of one mover (module documentation).
pub(crate) struct SpaceTime<'a> {
    mover: Vec<usize>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    vel: Vec<f64>,
    earlier: &'a [Timed],
    checker: FastChecker,
    qa: Vec<f64>,
    qb: Vec<f64>,
    buf: Vec<f64>,
    cuts: Vec<f64>,
    /// Certified segment checks so far.
    pub segments: u64,
}

impl<'a> SpaceTime<'a> {
    /// A search for the world variables `mover` (velocity limits `vel`) in `world` around
    /// `earlier`; every other variable stays at `world_q`.
    pub fn new(
        world: &CollisionWorld,
        world_q: &[f64],
        mover: &[usize],
        vel: &[f64],
        earlier: &'a [Timed],
    ) -> SpaceTime<'a> {
        let mut active: Vec<usize> = mover.to_vec();
        for e in earlier {
            active.extend(e.vars.iter().copied());
        }
        let checker = FastChecker::for_active(world, Default::default(), &active, world_q);
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        for &w in mover {
            let (lo, hi) = world
                .robots
                .iter()
                .find(|p| w >= p.offset && w < p.offset + p.robot.dof())
                .map(|p| {
                    let l = p.robot.var_limits(w - p.offset);
                    (l.lower, l.upper)
                })
                .unwrap_or((0.0, 0.0));
            lower.push(lo);
            upper.push(hi);
        }
        SpaceTime {
            mover: mover.to_vec(),
            lower,
            upper,
            vel: vel.to_vec(),
            earlier,
            checker,
            qa: world_q.to_vec(),
            qb: world_q.to_vec(),
            buf: Vec::new(),
            cuts: Vec::new(),
            segments: 0,
        }
    }

    fn horizon_end(&self) -> f64 {
        self.earlier.iter().map(Timed::end).fold(0.0, f64::max)
    }

    fn write(&mut self, q: &[f64], t: f64, second: bool) {
        let out = if second { &mut self.qb } else { &mut self.qa };
        for (&v, &x) in self.mover.iter().zip(q) {
            out[v] = x;
        }
        for e in self.earlier {
            e.write_world(t, &mut self.buf, out);
        }
    }

    /// Whether the mover going straight from `a` at `ta` to `b` at `tb` is proven free
    /// against the earlier motions (module documentation).
    fn edge_free(&mut self, a: &[f64], ta: f64, b: &[f64], tb: f64) -> bool {
        let mut cuts = std::mem::take(&mut self.cuts);
        cuts.clear();
        cuts.push(ta);
        for e in self.earlier {
            e.knots_within(ta, tb, &mut cuts);
        }
        cuts.push(tb);
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        let mut qm = vec![0.0; a.len()];
        let mut ok = true;
        let span = tb - ta;
        for w in cuts.windows(2) {
            for (k, second) in [(0, false), (1, true)] {
                let s = if span > 0.0 { (w[k] - ta) / span } else { 1.0 };
                for ((m, &x), &y) in qm.iter_mut().zip(a).zip(b) {
                    *m = x + (y - x) * s;
                }
                self.write(&qm, w[k], second);
            }
            self.segments += 1;
            if !self.checker.motion_certified(&self.qa, &self.qb) {
                ok = false;
                break;
            }
        }
        if cuts.len() == 1 {
            // A zero-length edge: the state itself.
            self.write(b, tb, false);
            self.write(b, tb, true);
            self.segments += 1;
            ok = self.checker.motion_certified(&self.qa, &self.qb);
        }
        self.cuts = cuts;
        ok
    }

    /// From (q, t): straight to the goal at full speed, then held until every earlier motion
    /// has ended. The arrival time when free.
    fn reach_goal(&mut self, q: &[f64], t: f64, goal: &[f64]) -> Option<f64> {
        let tg = t + travel_time(q, goal, &self.vel);
        if !self.edge_free(q, t, goal, tg) {
            return None;
        }
        let end = self.horizon_end();
        if end > tg && !self.edge_free(goal, tg, goal, end) {
            return None;
        }
        Some(tg)
    }

    /// Plans from `start` (at time 0) to `goal`; the timed motion of the mover, or `None` when
    /// the iterations or `term` run out.
    pub fn plan(
        &mut self,
        start: &[f64],
        goal: &[f64],
        settings: &SpaceTimeSettings,
        term: &mut Termination,
        rng: &mut ChaCha8Rng,
    ) -> Option<Timed> {
        // The mover must be free at its start while the earlier movers pass, if it waited
        // there: the root is checked like any edge, by the first EXTEND from it; the straight
        // attempt comes first.
        let mut nodes = vec![Node {
            q: start.to_vec(),
            t: 0.0,
            parent: usize::MAX,
        }];
        let finish = |nodes: &Vec<Node>, last: usize, tg: f64, goal: &[f64], vars: &[usize]| {
            let mut chain = Vec::new();
            let mut k = last;
            while k != usize::MAX {
                chain.push(k);
                k = nodes[k].parent;
            }
            chain.reverse();
            let mut times: Vec<f64> = chain.iter().map(|&k| nodes[k].t).collect();
            let mut points: Vec<Vec<f64>> = chain.iter().map(|&k| nodes[k].q.clone()).collect();
            times.push(tg);
            points.push(goal.to_vec());
            Timed {
                vars: vars.to_vec(),
                times,
                points,
            }
        };
        if let Some(tg) = self.reach_goal(start, 0.0, goal) {
            return Some(finish(&nodes, 0, tg, goal, &self.mover));
        }
        let horizon =
            self.horizon_end() + 3.0 * travel_time(start, goal, &self.vel) + 4.0 * settings.step;
        let d = start.len();
        let mut sample = vec![0.0; d];
        let mut new_q = vec![0.0; d];
        for _ in 0..settings.iterations {
            if term.should_stop() {
                return None;
            }
            let t_rand = rng.random::<f64>() * horizon;
            let r = rng.random::<f64>();
            let wait = r < settings.wait_bias;
            if r >= settings.wait_bias && r < settings.wait_bias + settings.goal_bias {
                sample.copy_from_slice(goal);
            } else if !wait {
                for ((s, &lo), &hi) in sample.iter_mut().zip(&self.lower).zip(&self.upper) {
                    *s = lo + (hi - lo) * rng.random::<f64>();
                }
            }
            // Nearest earlier node.
            let mut best = (usize::MAX, f64::INFINITY);
            for (i, n) in nodes.iter().enumerate() {
                if n.t >= t_rand {
                    continue;
                }
                let tau = if wait {
                    0.0
                } else {
                    travel_time(&n.q, &sample, &self.vel)
                };
                let dist = tau + 0.25 * (t_rand - n.t);
                if dist < best.1 {
                    best = (i, dist);
                }
            }
            let near = best.0;
            if near == usize::MAX {
                continue;
            }
            let (q0, t0) = (nodes[near].q.clone(), nodes[near].t);
            if wait {
                sample.copy_from_slice(&q0);
            }
            let tau = travel_time(&q0, &sample, &self.vel);
            let alpha = if tau > settings.step {
                settings.step / tau
            } else {
                1.0
            };
            let dur = tau.max(t_rand - t0) * alpha;
            let dur = if wait {
                dur.min(4.0 * settings.step)
            } else {
                dur
            };
            for ((n, &a), &b) in new_q.iter_mut().zip(&q0).zip(&sample) {
                *n = a + (b - a) * alpha;
            }
            let t1 = t0 + dur.max(travel_time(&q0, &new_q, &self.vel));
            if t1 <= t0 || !self.edge_free(&q0, t0, &new_q, t1) {
                continue;
            }
            nodes.push(Node {
                q: new_q.clone(),
                t: t1,
                parent: near,
            });
            let last = nodes.len() - 1;
            if let Some(tg) = self.reach_goal(&new_q, t1, goal) {
                return Some(finish(&nodes, last, tg, goal, &self.mover));
            }
        }
        None
    }
}
