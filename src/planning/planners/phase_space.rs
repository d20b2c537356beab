//! Phase-space scheduling of several robot trajectories for simultaneous execution (paper 002
//! = Vahrenkamp et al. 2010, §V, Alg. 4).
//!
//! Each robot `i` has a joint trajectory `t_i` (waypoints of its own configuration, each free on
//! its own in the scene) and a phase φ_i ∈ [0, 1]; the interpolation I_ti(φ_i) runs the
//! waypoints at the robot's velocity limits: the phase of a waypoint is the time it is reached
//! when every segment is run as fast as the slowest of its joints allows
//! (`max_v |Δq_v| / vmax_v`), divided by the trajectory's duration T_i. A phase vector
//! φ ∈ P = [0, 1]^n is one execution state of all robots; valid(φ) ⇔ no two robots (links and
//! what they hold) intersect at (I_t1(φ_1), …, I_tn(φ_n)). The schedule is a path in P from
//! (0, …, 0) to (1, …, 1), searched with RRT-Connect and the paper's Extend (Alg. 4).
//!
//! **What is proven.** The paper validates a phase segment by sampling it every ε_sampl and
//! argues that ε_sampl is safe when a phase step of that length moves no robot point farther
//! than the smallest clearance d_min (the worst-case workspace displacement d_ws of its
//! ref. [24]). Here the same argument is made exact per segment instead of with one global
//! ε_sampl: a phase segment is cut where any robot passes a waypoint, so that on each piece every
//! robot moves on a straight line of its joint space, and each piece is given to
//! [`FastChecker::motion_certified`] on the world of the robots alone
//! ([`CollisionWorld::between_robots`]), which proves the continuous motion free with per-body
//! bounds on how far any point can move (the d_ws of the joint changes) against primitives grown
//! by that distance, refined where the clearance is tight. So every edge of the phase tree and
//! every segment of the returned schedule is free as a continuous motion, not only at samples;
//! ε_sampl becomes the certificate's own refinement. ε_extend (`PhaseSpaceSettings::extend`)
//! stays the RRT's step.
//!
//! **Monotone phases.** A robot never runs its trajectory backwards: the forward tree only grows
//! toward samples that dominate the node it grows from (the root (0, …, 0) dominates nothing and
//! is dominated by every sample, so one always exists), the backward tree only toward samples
//! its node dominates, and the two trees connect only from a forward node to a backward node that
//! dominates it. Every edge is therefore non-decreasing in every coordinate, and so is the path
//! (the shortcut keeps that: it joins two vertices of a monotone path). Robots *wait* where the
//! path keeps their phase constant.
//!
//! **Search order.** The straight line in P (everyone at once, at constant rates) is tried
//! first. Then, when sequential execution in index order is valid, a *prioritized advance*
//! (not in the paper; in the spirit of prioritized velocity tuning): from φ = 0 each step moves
//! the largest set of unfinished robots by ε_extend in phase (sets tried by size, then robot 0's
//! membership first), keeping only steps after which the robots could still finish one after
//! the other — so it never deadlocks, and robots overlap in time wherever they can. Only when
//! that does not apply (a robot's goal lies on a lower-indexed robot's path, say) does
//! RRT-Connect in P (Alg. 4) search; its samples are half uniform and half "some robots move
//! on from a tree node while the others wait", the moves schedules are made of. Whatever stage
//! found it, the returned path is certified again as a whole before it is timed.
//!
//! **Fallback.** Sequential execution — robot 1 runs all of its trajectory while the others wait
//! at their start, then robot 2, … — is valid whenever the trajectories pass 002's deadlock
//! check (eq. 2); it is tried (and certified like every other path) when the search fails.
//!
//! **Timing.** A phase path becomes a schedule on one clock: each piece (straight for every
//! robot) lasts as long as its slowest joint needs at its velocity limit (the robot's
//! [`crate::Robot::velocity_limit`], scaled by `PhaseSpaceSettings::velocity_scaling`); with
//! acceleration limits (the server and Multi-Robot-RRT always give them: the robot's joint-limits
//! file or the default)
//! each piece is run rest to rest with a trapezoidal profile (stopping at every piece: simple and
//! always within both limits; a time-optimal parameterisation is the job of the trajectory
//! timing module).

use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::planning::{PlanError, PlanStats, StopReason, Termination};

/// Velocity used for a joint whose URDF gives none (0, missing or not finite), rad/s or m/s: the
/// model's default.
pub use crate::model::DEFAULT_VELOCITY;

/// One robot's trajectory for the scheduler: waypoints of its own configuration (all of its
/// variables, in the robot's variable order).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotTrajectory {
    /// Index of the robot in the world.
    pub robot: usize,
    pub waypoints: Vec<Vec<f64>>,
    /// Per-variable acceleration limits (`None`: velocity limits only).
    pub accelerations: Option<Vec<f64>>,
}

/// Settings of the phase-space search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseSpaceSettings {
    /// ε_extend of Alg. 4: the longest tree edge, in phase units (Euclidean in P).
    pub extend: f64,
    /// Shortcut the phase path (monotone vertex skipping).
    pub shortcut: bool,
    /// Fall back to sequential execution when the search fails.
    pub sequential_fallback: bool,
    /// Most RRT iterations (besides the caller's termination).
    pub max_iterations: u64,
    /// Factors (0, 1] on every joint's velocity and acceleration limits when the phase path
    /// is timed (MoveIt's scaling factors); the phases themselves do not depend on them.
    pub velocity_scaling: f64,
    pub acceleration_scaling: f64,
}

impl Default for PhaseSpaceSettings {
    fn default() -> Self {
        PhaseSpaceSettings {
            extend: 0.1,
            shortcut: true,
            sequential_fallback: true,
            max_iterations: 20_000,
            velocity_scaling: 1.0,
            acceleration_scaling: 1.0,
        }
    }
}

/// How the schedule was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ScheduleMethod {
    /// All robots start together and run at constant phase rates (the straight line in P).
    Simultaneous,
    /// Prioritized advance: robots move on together where they can, lower-priority robots
    /// wait where they must (module documentation).
    Prioritized,
    /// RRT-Connect in phase space (Alg. 4).
    PhaseSpaceRrt,
    /// One robot after the other (the fallback guaranteed by the deadlock check).
    Sequential,
}

/// A timed knot of a schedule: every robot's configuration at one instant of the common clock.
#[derive(Debug, Clone, PartialEq)]
pub struct Knot {
    pub time: f64,
    pub phase: Vec<f64>,
    /// Per robot, its configuration.
    pub configs: Vec<Vec<f64>>,
}

/// How the motion between two knots is timed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Profile {
    /// Constant velocity (velocity limits only).
    Constant,
    /// Rest to rest, path parameter acceleration `a` up to speed `v` (trapezoid or triangle).
    Trapezoid { v: f64, a: f64 },
}

/// Statistics of one scheduling run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhaseSpaceStats {
    pub time: Duration,
    pub iterations: u64,
    pub tree_nodes: usize,
    /// Phase states checked (tree nodes, pieces, fallback).
    pub collision_checks: u64,
    /// Certified motion checks (pieces of phase segments).
    pub segments_checked: u64,
    pub path_vertices_raw: usize,
    pub path_vertices: usize,
}

/// The result: the phase path and the timed schedule.
#[derive(Debug, Clone, PartialEq)]
pub struct Schedule {
    pub method: ScheduleMethod,
    /// The phase path (monotone), from (0, …, 0) to (1, …, 1).
    pub phase_path: Vec<Vec<f64>>,
    /// Knots on one clock; between two knots every robot moves on a straight line of its joint
    /// space with the profile of the later knot (`profiles[k]` times knots k → k+1).
    pub knots: Vec<Knot>,
    pub profiles: Vec<Profile>,
    /// Duration of each robot's trajectory when run alone at its velocity limits (T_i).
    pub robot_durations: Vec<f64>,
    pub duration: f64,
    pub stats: PhaseSpaceStats,
}

/// One robot's trajectory with phases.
#[derive(Debug, Clone)]
struct Track {
    /// Index of the robot in the world, and where its variables start.
    robot: usize,
    offset: usize,
    points: Vec<Vec<f64>>,
    /// Phase of each waypoint (0 … 1, non-decreasing; all 0 when the robot does not move).
    phase: Vec<f64>,
    duration: f64,
    vel: Vec<f64>,
    acc: Option<Vec<f64>>,
}

impl Track {
    /// I_t(φ) into `out`.
    fn config_at(&self, phi: f64, out: &mut [f64]) {
        let n = self.points.len();
        if n == 1 || phi <= 0.0 || self.duration <= 0.0 {
            out.copy_from_slice(&self.points[0]);
            return;
        }
        if phi >= 1.0 {
            out.copy_from_slice(&self.points[n - 1]);
            return;
        }
        // Last waypoint whose phase is ≤ φ.
        let j = self.phase.partition_point(|&p| p <= phi).clamp(1, n - 1) - 1;
        let (p0, p1) = (self.phase[j], self.phase[j + 1]);
        let t = if p1 > p0 { (phi - p0) / (p1 - p0) } else { 1.0 };
        for ((o, &a), &b) in out.iter_mut().zip(&self.points[j]).zip(&self.points[j + 1]) {
            *o = a + (b - a) * t;
        }
    }
}

/// The scheduler of a set of trajectories in one world.
pub struct PhaseSpace {
    world: CollisionWorld,
    checker: FastChecker,
    tracks: Vec<Track>,
    q: Vec<f64>,
    qb: Vec<f64>,
    checks: u64,
    segments: u64,
}

fn invalid(msg: impl Into<String>) -> PlanError {
    PlanError::InvalidInput(msg.into())
}

impl PhaseSpace {
    /// A scheduler for `trajectories` (one per robot of `world`, every robot once; robots
    /// without a trajectory keep the configuration of `world_q`). Fixed bodies of `world` are not
    /// checked here: each trajectory must be free in the scene on its own (check it with the
    /// planners' validator, as the `schedule` job does).
    pub fn new(
        world: &CollisionWorld,
        world_q: &[f64],
        trajectories: &[RobotTrajectory],
    ) -> Result<PhaseSpace, PlanError> {
        if world_q.len() != world.dof() {
            return Err(invalid(format!(
                "world configuration must have {} values",
                world.dof()
            )));
        }
        if trajectories.is_empty() {
            return Err(invalid("no trajectory to schedule"));
        }
        let mut seen = vec![false; world.robots.len()];
        let mut tracks = Vec::with_capacity(trajectories.len());
        for (k, t) in trajectories.iter().enumerate() {
            let p = world
                .robots
                .get(t.robot)
                .ok_or_else(|| invalid(format!("trajectories[{k}]: no robot {}", t.robot)))?;
            if std::mem::replace(&mut seen[t.robot], true) {
                return Err(invalid(format!(
                    "trajectories[{k}]: robot '{}' has two trajectories",
                    p.name
                )));
            }
            let dof = p.robot.dof();
            if t.waypoints.is_empty() {
                return Err(invalid(format!(
                    "trajectories[{k}] ({}): no waypoints",
                    p.name
                )));
            }
            for (w, q) in t.waypoints.iter().enumerate() {
                if q.len() != dof || q.iter().any(|v| !v.is_finite()) {
                    return Err(invalid(format!(
                        "trajectories[{k}].waypoints[{w}] ({}): must be {dof} finite values",
                        p.name
                    )));
                }
            }
            let vel: Vec<f64> = (0..dof).map(|v| p.robot.velocity_limit(v)).collect();
            if let Some(a) = &t.accelerations {
                if a.len() != dof || a.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                    return Err(invalid(format!(
                        "trajectories[{k}].accelerations ({}): must be {dof} positive values",
                        p.name
                    )));
                }
            }
            let mut times = vec![0.0];
            for w in t.waypoints.windows(2) {
                let d = w[0]
                    .iter()
                    .zip(&w[1])
                    .zip(&vel)
                    .map(|((a, b), v)| (b - a).abs() / v)
                    .fold(0.0f64, f64::max);
                times.push(times[times.len() - 1] + d);
            }
            let duration = times[times.len() - 1];
            let phase = if duration > 0.0 {
                times.iter().map(|t| (t / duration).min(1.0)).collect()
            } else {
                vec![0.0; times.len()]
            };
            tracks.push(Track {
                robot: t.robot,
                offset: p.offset,
                points: t.waypoints.clone(),
                phase,
                duration,
                vel,
                acc: t.accelerations.clone(),
            });
        }
        // Robots without a trajectory keep their `world_q` values (the buffers start from it).
        let between = world.between_robots();
        let checker = FastChecker::new(&between);
        let s = PhaseSpace {
            world: between,
            checker,
            tracks,
            q: world_q.to_vec(),
            qb: world_q.to_vec(),
            checks: 0,
            segments: 0,
        };
        Ok(s)
    }

    /// Number of scheduled robots (the dimension of P).
    pub fn dim(&self) -> usize {
        self.tracks.len()
    }

    /// The world the robots are checked in (robots and what they hold, against each other).
    pub fn world(&self) -> &CollisionWorld {
        &self.world
    }

    /// T_i of every scheduled robot (s).
    pub fn durations(&self) -> Vec<f64> {
        self.tracks.iter().map(|t| t.duration).collect()
    }

    /// The world configuration at phase φ into `out`.
    pub fn world_config(&self, phi: &[f64], out: &mut [f64]) {
        for (t, &p) in self.tracks.iter().zip(phi) {
            let dof = t.points[0].len();
            t.config_at(p, &mut out[t.offset..t.offset + dof]);
        }
    }

    /// Each scheduled robot's configuration at phase φ.
    pub fn robot_configs(&self, phi: &[f64]) -> Vec<Vec<f64>> {
        self.tracks
            .iter()
            .zip(phi)
            .map(|(t, &p)| {
                let mut c = vec![0.0; t.points[0].len()];
                t.config_at(p, &mut c);
                c
            })
            .collect()
    }

    /// valid(φ) of 002 §V: no two robots intersect at phase φ.
    pub fn is_valid(&mut self, phi: &[f64]) -> bool {
        let mut q = std::mem::take(&mut self.q);
        self.world_config(phi, &mut q);
        self.checks += 1;
        let free = self.checker.is_free(&q);
        self.q = q;
        free
    }

    /// The parameters in (0, 1) of the straight phase segment a → b where some robot passes a
    /// waypoint, sorted, with 0 and 1 at the ends.
    fn breakpoints(&self, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut s = vec![0.0, 1.0];
        for (t, (&pa, &pb)) in self.tracks.iter().zip(a.iter().zip(b)) {
            let (lo, hi) = (pa.min(pb), pa.max(pb));
            if hi - lo <= 0.0 {
                continue;
            }
            for &k in &t.phase {
                if k > lo && k < hi {
                    s.push((k - pa) / (pb - pa));
                }
            }
        }
        s.sort_by(f64::total_cmp);
        s.dedup();
        s
    }

    /// Whether the straight phase segment a → b is proven free as a continuous motion of all
    /// robots (module documentation), both ends included.
    pub fn segment_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        let cuts = self.breakpoints(a, b);
        let n = a.len();
        let mut pa = vec![0.0; n];
        let mut pb = vec![0.0; n];
        let (mut qa, mut qb) = (std::mem::take(&mut self.q), std::mem::take(&mut self.qb));
        let mut ok = true;
        for w in cuts.windows(2) {
            for k in 0..n {
                pa[k] = a[k] + (b[k] - a[k]) * w[0];
                pb[k] = a[k] + (b[k] - a[k]) * w[1];
            }
            self.world_config(&pa, &mut qa);
            self.world_config(&pb, &mut qb);
            self.segments += 1;
            if !self.checker.motion_certified(&qa, &qb) {
                ok = false;
                break;
            }
        }
        self.q = qa;
        self.qb = qb;
        ok
    }

    /// Whether every segment of a phase path is proven free.
    pub fn path_valid(&mut self, path: &[Vec<f64>]) -> bool {
        path.windows(2).all(|w| self.segment_valid(&w[0], &w[1]))
    }

    /// Schedules the trajectories: the straight line first, then RRT-Connect in P (Alg. 4),
    /// then (when allowed) sequential execution; the path is shortcut and timed.
    pub fn plan(
        &mut self,
        settings: &PhaseSpaceSettings,
        term: &mut Termination,
        seed: u64,
    ) -> Result<Schedule, PlanError> {
        let t0 = Instant::now();
        let (c0, s0) = (self.checks, self.segments);
        if !(settings.extend > 0.0 && settings.extend.is_finite()) {
            return Err(invalid("phase space: extend must be > 0"));
        }
        let n = self.dim();
        let zero = vec![0.0; n];
        let one = vec![1.0; n];
        let mut stats = PhaseSpaceStats::default();
        if !self.is_valid(&zero) {
            return Err(PlanError::InvalidStart {
                reason: format!(
                    "the robots' start configurations collide with each other ({})",
                    self.contact_at(&zero)
                ),
            });
        }
        if !self.is_valid(&one) {
            return Err(PlanError::NoSchedule {
                reason: format!(
                    "the trajectories' final configurations collide with each other ({})",
                    self.contact_at(&one)
                ),
            });
        }
        let (method, raw) = if self.segment_valid(&zero, &one) {
            (
                ScheduleMethod::Simultaneous,
                vec![zero.clone(), one.clone()],
            )
        } else {
            let found = match self.prioritized(settings.extend, term) {
                Some(p) => Some((ScheduleMethod::Prioritized, p)),
                None => self
                    .rrt(settings, term, seed, &mut stats)
                    .map(|p| (ScheduleMethod::PhaseSpaceRrt, p)),
            };
            match found {
                Some(f) => f,
                None => {
                    let seq = self.sequential_path();
                    if settings.sequential_fallback && self.path_valid(&seq) {
                        (ScheduleMethod::Sequential, seq)
                    } else {
                        stats.time = t0.elapsed();
                        let ps = PlanStats {
                            time: stats.time,
                            iterations: stats.iterations,
                            collision_checks: self.checks - c0,
                            segments_checked: self.segments - s0,
                            ..PlanStats::default()
                        };
                        return Err(match term.reason() {
                            Some(r) if r != StopReason::IterationLimit => PlanError::stopped(r, ps),
                            _ => PlanError::NoSchedule {
                                reason: "none found in phase space, and executing the \
                                         trajectories one after the other collides (they fail \
                                         the deadlock check, 002 eq. 2)"
                                    .into(),
                            },
                        });
                    }
                }
            }
        };
        stats.path_vertices_raw = raw.len();
        let path = if settings.shortcut && raw.len() > 2 {
            self.shortcut(raw)
        } else {
            raw
        };
        stats.path_vertices = path.len();
        // The returned path is certified once more as a whole: whatever stage found it, no
        // schedule leaves the planner unproven.
        if let Some(segment) = path
            .windows(2)
            .position(|w| !self.segment_valid(&w[0], &w[1]))
        {
            return Err(PlanError::PathInvalid {
                segment,
                stats: Box::new(PlanStats {
                    time: t0.elapsed(),
                    collision_checks: self.checks - c0,
                    segments_checked: self.segments - s0,
                    ..PlanStats::default()
                }),
            });
        }
        let (knots, profiles) = self.time(&path, settings);
        stats.time = t0.elapsed();
        stats.collision_checks = self.checks - c0;
        stats.segments_checked = self.segments - s0;
        let duration = knots.last().map_or(0.0, |k| k.time);
        Ok(Schedule {
            method,
            phase_path: path,
            knots,
            profiles,
            robot_durations: self.durations(),
            duration,
            stats,
        })
    }

    /// The colliding pair at φ, for messages.
    fn contact_at(&mut self, phi: &[f64]) -> String {
        let mut q = std::mem::take(&mut self.q);
        self.world_config(phi, &mut q);
        let c = self.checker.first_contact(&q);
        self.q = q;
        c.map_or_else(|| "no contact".into(), |c| format!("{} with {}", c.a, c.b))
    }

    /// Robot 1 runs, then robot 2, … (each vertex moves one phase from 0 to 1).
    pub fn sequential_path(&self) -> Vec<Vec<f64>> {
        let n = self.dim();
        let mut p = vec![vec![0.0; n]];
        for k in 0..n {
            let mut v = p[p.len() - 1].clone();
            v[k] = 1.0;
            p.push(v);
        }
        p
    }

    /// Prioritized advance (module documentation): from φ = 0, each step moves the largest set
    /// of unfinished robots it can by `step` in phase (capped at 1), trying sets by size, then
    /// by priority (robot 0 first), and keeps only steps after which the robots can still
    /// finish one after the other in priority order ([`Self::completion`]). That invariant
    /// holds at φ = 0 when sequential execution is valid, and the lowest unfinished robot
    /// moving on alone keeps it, so the advance never deadlocks; where no tried set passes, the
    /// remaining sequential completion ends the path. Runs of the same set merge into one
    /// straight segment (a union of certified collinear pieces is certified). `None` when
    /// sequential execution from φ = 0 is itself invalid, or `term` fires.
    fn prioritized(&mut self, step: f64, term: &mut Termination) -> Option<Vec<Vec<f64>>> {
        let n = self.dim();
        if n > 16 {
            return None;
        }
        let mut phi = vec![0.0; n];
        if !self.completion_valid(&phi) {
            return None;
        }
        // Robot sets as bit masks: all but at most two robots together, or one alone (so a
        // step tries O(n²) sets), largest first, then robot 0's membership first, robot 1's …
        let mut masks: Vec<u64> = (1..(1u64 << n))
            .filter(|m| {
                let c = m.count_ones() as usize;
                c + 2 >= n || c == 1
            })
            .collect();
        let priority_key =
            |m: u64| -> u64 { (0..n).fold(0u64, |acc, k| (acc << 1) | ((m >> k) & 1)) };
        masks.sort_by(|a, b| {
            b.count_ones()
                .cmp(&a.count_ones())
                .then(priority_key(*b).cmp(&priority_key(*a)))
        });
        let mut path = vec![phi.clone()];
        let mut last_delta = vec![0.0; n];
        let mut next = vec![0.0; n];
        let mut tried = Vec::new();
        loop {
            if phi.iter().all(|&x| x >= 1.0) {
                return Some(path);
            }
            if term.should_stop() {
                return None;
            }
            let mut moved = false;
            tried.clear();
            for &m in &masks {
                // The robots of `m` that still have phase left; a set whose effective move was
                // already tried is skipped.
                let eff = (0..n)
                    .filter(|&k| (m >> k) & 1 == 1 && phi[k] < 1.0)
                    .fold(0u64, |acc, k| acc | (1 << k));
                if eff == 0 || tried.contains(&eff) {
                    continue;
                }
                tried.push(eff);
                for k in 0..n {
                    next[k] = if (eff >> k) & 1 == 1 {
                        (phi[k] + step).min(1.0)
                    } else {
                        phi[k]
                    };
                }
                if self.is_valid(&next)
                    && self.segment_valid(&phi, &next)
                    && self.completion_valid(&next)
                {
                    moved = true;
                    break;
                }
            }
            if !moved {
                // The sequential completion from φ is valid (the invariant): take it.
                path.extend(self.completion(&phi).into_iter().skip(1));
                return Some(path);
            }
            // The same phase step as the last one (same robots, none cut short at its end):
            // extend the last straight segment instead of adding a vertex.
            let same = path.len() > 1
                && (0..n).all(|k| ((next[k] - phi[k]) - last_delta[k]).abs() <= 1e-12);
            for k in 0..n {
                last_delta[k] = next[k] - phi[k];
            }
            if same {
                path.pop();
            }
            phi.copy_from_slice(&next);
            path.push(phi.clone());
        }
    }

    /// From φ, the robots finish one after the other in index order: φ, then robot 0's phase
    /// set to 1, then robot 1's, … (unfinished robots only).
    fn completion(&self, phi: &[f64]) -> Vec<Vec<f64>> {
        let mut out = vec![phi.to_vec()];
        for k in 0..phi.len() {
            if phi[k] < 1.0 {
                let mut v = out[out.len() - 1].clone();
                v[k] = 1.0;
                out.push(v);
            }
        }
        out
    }

    /// Whether [`Self::completion`] from φ is certified.
    fn completion_valid(&mut self, phi: &[f64]) -> bool {
        let c = self.completion(phi);
        self.path_valid(&c)
    }

    /// RRT-Connect in P with monotone trees (module documentation).
    fn rrt(
        &mut self,
        settings: &PhaseSpaceSettings,
        term: &mut Termination,
        seed: u64,
        stats: &mut PhaseSpaceStats,
    ) -> Option<Vec<Vec<f64>>> {
        let n = self.dim();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Trees: (state, parent). Tree 0 grows forward from 0, tree 1 backward from 1.
        let mut trees: [Vec<(Vec<f64>, usize)>; 2] = [
            vec![(vec![0.0; n], usize::MAX)],
            vec![(vec![1.0; n], usize::MAX)],
        ];
        let eps = settings.extend;
        let mut sample = vec![0.0; n];
        let mut side = 0usize;
        let mut it = 0u64;
        while it < settings.max_iterations {
            if term.should_stop() {
                break;
            }
            it += 1;
            if rng.random::<bool>() {
                // Waiting bias: from a random node of the growing tree, a random subset of the
                // robots moves on (uniformly up to its end, forward; back to its start,
                // backward) while the others wait. Schedules are made of such moves, and
                // uniform samples in the interior of P rarely lead along the thin free
                // regions near its faces where some robots wait.
                let tree = &trees[side];
                let node = &tree[rng.random_range(0..tree.len())].0;
                for (s, &x) in sample.iter_mut().zip(node) {
                    *s = if rng.random::<bool>() {
                        x
                    } else if side == 0 {
                        x + (1.0 - x) * rng.random::<f64>()
                    } else {
                        x * rng.random::<f64>()
                    };
                }
            } else {
                for s in sample.iter_mut() {
                    *s = rng.random::<f64>();
                }
            }
            // Extend tree `side` one step toward the sample.
            if let Some(i) = self.extend(&mut trees[side], side == 0, &sample, eps) {
                let x = trees[side][i].0.clone();
                // Connect the other tree toward the new node.
                let other = 1 - side;
                if let Some(j) = self.connect(&mut trees[other], other == 0, &x, eps) {
                    stats.iterations = it;
                    stats.tree_nodes = trees[0].len() + trees[1].len();
                    let (fi, bi) = if side == 0 { (i, j) } else { (j, i) };
                    let mut path = Vec::new();
                    let mut k = fi;
                    while k != usize::MAX {
                        path.push(trees[0][k].0.clone());
                        k = trees[0][k].1;
                    }
                    path.reverse();
                    let mut k = trees[1][bi].1;
                    while k != usize::MAX {
                        path.push(trees[1][k].0.clone());
                        k = trees[1][k].1;
                    }
                    return Some(path);
                }
            }
            side = 1 - side;
        }
        stats.iterations = it;
        stats.tree_nodes = trees[0].len() + trees[1].len();
        None
    }

    /// Nearest node of `tree` that the target dominates (forward) or that dominates it
    /// (backward); the root always qualifies.
    fn nearest(tree: &[(Vec<f64>, usize)], forward: bool, target: &[f64]) -> usize {
        let mut best = (0usize, f64::INFINITY);
        for (i, (s, _)) in tree.iter().enumerate() {
            let ok = s
                .iter()
                .zip(target)
                .all(|(&a, &b)| if forward { a <= b } else { a >= b });
            if !ok {
                continue;
            }
            let d: f64 = s.iter().zip(target).map(|(a, b)| (a - b) * (a - b)).sum();
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    /// Alg. 4: one step of at most `eps` from the nearest admissible node toward `target`;
    /// the new node's index, or `None` when trapped.
    fn extend(
        &mut self,
        tree: &mut Vec<(Vec<f64>, usize)>,
        forward: bool,
        target: &[f64],
        eps: f64,
    ) -> Option<usize> {
        let near = Self::nearest(tree, forward, target);
        self.step(tree, near, target, eps).map(|(i, _)| i)
    }

    /// From node `near` one step toward `target`: `(new index, reached target)`.
    fn step(
        &mut self,
        tree: &mut Vec<(Vec<f64>, usize)>,
        near: usize,
        target: &[f64],
        eps: f64,
    ) -> Option<(usize, bool)> {
        let from = tree[near].0.clone();
        let d = from
            .iter()
            .zip(target)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        if d <= 0.0 {
            return Some((near, true));
        }
        let reached = d <= eps;
        let new: Vec<f64> = if reached {
            target.to_vec()
        } else {
            from.iter()
                .zip(target)
                .map(|(a, b)| (a + (b - a) * eps / d).clamp(0.0, 1.0))
                .collect()
        };
        if !self.is_valid(&new) || !self.segment_valid(&from, &new) {
            return None;
        }
        tree.push((new, near));
        Some((tree.len() - 1, reached))
    }

    /// RRT-Connect's CONNECT: steps toward `target` until reached (its index) or trapped.
    fn connect(
        &mut self,
        tree: &mut Vec<(Vec<f64>, usize)>,
        forward: bool,
        target: &[f64],
        eps: f64,
    ) -> Option<usize> {
        let mut at = Self::nearest(tree, forward, target);
        loop {
            match self.step(tree, at, target, eps) {
                Some((i, true)) => return Some(i),
                Some((i, false)) => at = i,
                None => return None,
            }
        }
    }

    /// Monotone shortcut: from each kept vertex, the farthest later vertex it reaches directly.
    fn shortcut(&mut self, path: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let mut out = vec![path[0].clone()];
        let mut i = 0;
        while i + 1 < path.len() {
            let mut j = path.len() - 1;
            while j > i + 1 && !self.segment_valid(&path[i], &path[j]) {
                j -= 1;
            }
            out.push(path[j].clone());
            i = j;
        }
        out
    }

    /// Knots and profiles of a phase path (module documentation: Timing).
    fn time(&self, path: &[Vec<f64>], settings: &PhaseSpaceSettings) -> (Vec<Knot>, Vec<Profile>) {
        let (vs, acs) = (settings.velocity_scaling, settings.acceleration_scaling);
        let n = self.dim();
        let mut knots = Vec::new();
        let mut profiles = Vec::new();
        let mut t = 0.0;
        let push = |t: f64, phi: Vec<f64>, knots: &mut Vec<Knot>| {
            let configs = self.robot_configs(&phi);
            knots.push(Knot {
                time: t,
                phase: phi,
                configs,
            });
        };
        push(0.0, path[0].clone(), &mut knots);
        for w in path.windows(2) {
            let cuts = self.breakpoints(&w[0], &w[1]);
            for c in cuts.windows(2) {
                let pb: Vec<f64> = (0..n)
                    .map(|k| w[0][k] + (w[1][k] - w[0][k]) * c[1])
                    .collect();
                let prev = &knots[knots.len() - 1];
                let qb = self.robot_configs(&pb);
                // Path parameter limits: ṡ ≤ V, s̈ ≤ A over all joints of all robots.
                let (mut v, mut a) = (f64::INFINITY, f64::INFINITY);
                let mut any_acc = false;
                for (r, tr) in self.tracks.iter().enumerate() {
                    for (j, (&x0, &x1)) in prev.configs[r].iter().zip(&qb[r]).enumerate() {
                        let dq = (x1 - x0).abs();
                        if dq > 0.0 {
                            v = v.min(tr.vel[j] * vs / dq);
                            if let Some(acc) = &tr.acc {
                                any_acc = true;
                                a = a.min(acc[j] * acs / dq);
                            }
                        }
                    }
                }
                if !v.is_finite() {
                    // Nobody moves on this piece (a phase moved over a waypoint repeat).
                    continue;
                }
                let (dt, prof) = if any_acc && a.is_finite() {
                    if v * v / a >= 1.0 {
                        // Triangle: accelerate half way, decelerate the rest.
                        let vp = a.sqrt();
                        (2.0 / vp, Profile::Trapezoid { v: vp, a })
                    } else {
                        (1.0 / v + v / a, Profile::Trapezoid { v, a })
                    }
                } else {
                    (1.0 / v, Profile::Constant)
                };
                t += dt;
                profiles.push(prof);
                push(t, pb, &mut knots);
            }
        }
        (knots, profiles)
    }
}

mod schedule;
mod svg;

pub use schedule::{FullState, Sample};
pub use svg::phase_space_svg;
