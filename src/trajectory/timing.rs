//! Time-optimal parameterisation of a joint-space polyline under per-joint velocity and
//! acceleration limits: TOPP-RA (H. Pham & Q.-C. Pham, "A New Approach to Time-Optimal Path
//! Parameterization Based on Reachability Analysis", IEEE T-RO 2018), on the polyline itself.
//!
//! **What is timed.** The path is the polyline through the waypoints, parameterised by its
//! joint-space arc length s (`q(s) = q_k + (s − S_k) u_k` on segment k, `u_k` the unit
//! direction). The planners proved exactly these straight segments collision-free (certified
//! checks or resolution checks, whatever the planner used), so the timed trajectory stays *on*
//! the checked polyline: no blends, no deviation, nothing left to re-check. The price: at a
//! corner where the direction changes the velocity direction jumps, which no finite
//! acceleration can do, so the trajectory comes to rest there (TOPP-RA's controllable set at
//! that grid point is {0}). Consecutive collinear segments (same direction) are one straight
//! run and are passed at speed; a waypoint named in `rest_at` (a grasp or release) is a stop
//! even when collinear. Kunz & Stilman's circular blends (RSS 2012) would pass corners at
//! speed but leave the polyline by up to their blend radius; they are not used here, because
//! the certified checks prove the polyline with no margin to spare for that deviation.
//!
//! **The algorithm (Pham & Pham 2018, §III–IV).** With x = ṡ² and u = s̈ on a grid
//! 0 = s_0 < … < s_N, x_{i+1} = x_i + 2 Δ_i u_i (§III-A, eq. 6). The joint constraints are
//! `|q'_j(s) ṡ| ≤ v_j` (velocity: x ≤ x̄ = min_j v_j² / u_j²) and `|q'_j u + q''_j x| ≤ a_j`
//! (acceleration); on a straight segment q'' = 0, so the per-stage LP of §IV is one-dimensional
//! with the closed form `|u| ≤ ū = min_j a_j / |u_j|`. The backward pass (Alg. 1, lines 1–5)
//! computes the controllable sets K_i = [0, k_i] (k_N = 0, k_i = min(x̄_i, k_{i+1} + 2 Δ_i ū_i),
//! k_i = 0 at a rest point); the forward pass (lines 6–10) takes the greedy u_i = the largest
//! control keeping x_{i+1} ∈ K_{i+1}: `u_i = min(ū_i, (k_{i+1} − x_i) / (2 Δ_i))`.
//!
//! **The grid.** On a straight run between two rest points x̄ and ū are constant, so the
//! exact time-optimal profile is `x(s) = min(x̄, 2 ū s, 2 ū (L − s))` (accelerate, cruise,
//! decelerate). Each run is gridded at its switch points {0, x̄/(2ū), L − x̄/(2ū), L} (or
//! {0, L/2, L} when full speed is not reached, plus the collinear waypoints); on that grid the
//! passes above give this exact profile — no discretisation error, unlike the uniform grids
//! of the paper's §VI, which converge to it from below.
//!
//! **Guarantees.** Starts and ends at rest; every state on the polyline (positions are
//! interpolated on the original segments); |q̇_j| ≤ v_j and |q̈_j| ≤ a_j at every instant (not
//! only at the grid points: between grid points u is constant and x is linear in s); time-
//! optimal among the trajectories that follow the polyline exactly. Deterministic (no
//! randomness).

use manyhands_api::{JointTrajectory, TimedWaypoint, TrajectoryEvent, TrajectoryPoint};
use thiserror::Error;

use crate::collision::CollisionWorld;

/// The model's defaults for a joint without a velocity or acceleration limit.
pub use crate::model::{DEFAULT_ACCELERATION, DEFAULT_VELOCITY};

/// Default sampling period of a trajectory, seconds (10 ms, issue 25).
pub const DEFAULT_SAMPLE_PERIOD: f64 = 0.01;

/// Bounds of a requested sampling period, seconds.
pub const MIN_SAMPLE_PERIOD: f64 = 0.001;
pub const MAX_SAMPLE_PERIOD: f64 = 10.0;

/// Smallest velocity or acceleration scaling factor: a factor of 1e-300 would scale the limits
/// below what the squared velocity bound can hold (x̄ = v² underflows to 0) and time a motion
/// in 0 s; at 10⁻³ every limit keeps twelve orders of magnitude of headroom.
pub const MIN_SCALING: f64 = 0.001;

/// Most sampled points of one trajectory.
pub const MAX_POINTS: usize = 100_000;

/// Most sampled values (points × joints) of one trajectory, so that the answer (three numbers
/// a value) stays bounded whatever the path's length and number of joints.
pub const MAX_VALUES: usize = 500_000;

/// Why a path could not be timed: the offending input (`field`, e.g. `waypoints[3][2]`) and the
/// reason.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("{field}: {reason}")]
pub struct TimingError {
    pub field: String,
    pub reason: String,
}

fn err(field: impl Into<String>, reason: impl Into<String>) -> TimingError {
    TimingError {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Per-joint limits of a timing problem (one entry per path coordinate).
#[derive(Debug, Clone, PartialEq)]
pub struct TimingLimits {
    /// Maximum |q̇_j| (> 0).
    pub velocity: Vec<f64>,
    /// Maximum |q̈_j| (> 0).
    pub acceleration: Vec<f64>,
}

impl TimingLimits {
    /// Limits scaled as MoveIt's `velocity_scaling_factor` / `acceleration_scaling_factor`
    /// (each in [`MIN_SCALING`], 1]).
    pub fn scaled(&self, velocity: f64, acceleration: f64) -> Result<TimingLimits, TimingError> {
        check_scaling("velocity_scaling", velocity)?;
        check_scaling("acceleration_scaling", acceleration)?;
        Ok(TimingLimits {
            velocity: self.velocity.iter().map(|v| v * velocity).collect(),
            acceleration: self.acceleration.iter().map(|a| a * acceleration).collect(),
        })
    }

    fn check(&self, dof: usize) -> Result<(), TimingError> {
        for (name, l) in [
            ("velocity_limits", &self.velocity),
            ("acceleration_limits", &self.acceleration),
        ] {
            if l.len() != dof {
                return Err(err(name, format!("{} values for {dof} joints", l.len())));
            }
            if let Some(i) = l.iter().position(|x| !(x.is_finite() && *x > 0.0)) {
                return Err(err(format!("{name}[{i}]"), format!("{} is not > 0", l[i])));
            }
        }
        Ok(())
    }
}

/// Checks a scaling factor: finite, within [[`MIN_SCALING`], 1].
pub fn check_scaling(field: &str, s: f64) -> Result<(), TimingError> {
    if s.is_finite() && (MIN_SCALING..=1.0).contains(&s) {
        Ok(())
    } else {
        Err(err(field, format!("{s} is not within [{MIN_SCALING}, 1]")))
    }
}

/// Checks a sampling period: finite, within [`MIN_SAMPLE_PERIOD`, `MAX_SAMPLE_PERIOD`].
pub fn check_sample_period(field: &str, p: f64) -> Result<(), TimingError> {
    if p.is_finite() && (MIN_SAMPLE_PERIOD..=MAX_SAMPLE_PERIOD).contains(&p) {
        Ok(())
    } else {
        Err(err(
            field,
            format!("{p} is not within [{MIN_SAMPLE_PERIOD}, {MAX_SAMPLE_PERIOD}] s"),
        ))
    }
}

/// One stage of the TOPP-RA grid: [s, s + Δ] with constant acceleration `u` (= s̈), entered
/// with `x` = ṡ² at time `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stage {
    s: f64,
    delta: f64,
    x: f64,
    u: f64,
    t: f64,
    dt: f64,
}

/// One state of a timed trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct TimedPoint {
    pub time: f64,
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
}

/// A time-optimal trajectory along a polyline (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct TimedPath {
    waypoints: Vec<Vec<f64>>,
    /// Arc length of each waypoint.
    arc: Vec<f64>,
    /// Unit direction of each segment (zero for a repeated waypoint).
    dirs: Vec<Vec<f64>>,
    stages: Vec<Stage>,
    /// Time each waypoint is reached.
    pub waypoint_times: Vec<f64>,
    pub duration: f64,
}

/// Times `waypoints` (at least one, all of one length, finite) within `limits`, stopping at
/// every corner and at the waypoints of `rest_at` (module documentation).
pub fn time_polyline(
    waypoints: &[Vec<f64>],
    limits: &TimingLimits,
    rest_at: &[usize],
) -> Result<TimedPath, TimingError> {
    let Some(first) = waypoints.first() else {
        return Err(err("waypoints", "no waypoint"));
    };
    let dof = first.len();
    if dof == 0 {
        return Err(err("waypoints[0]", "no joint values"));
    }
    for (w, q) in waypoints.iter().enumerate() {
        if q.len() != dof {
            return Err(err(
                format!("waypoints[{w}]"),
                format!("{} values, waypoint 0 has {dof}", q.len()),
            ));
        }
        if let Some(j) = q.iter().position(|x| !x.is_finite()) {
            return Err(err(format!("waypoints[{w}][{j}]"), "not finite"));
        }
    }
    limits.check(dof)?;
    let n = waypoints.len();
    // Segments: arc lengths and unit directions.
    let mut arc = Vec::with_capacity(n);
    let mut dirs = Vec::with_capacity(n.saturating_sub(1));
    arc.push(0.0);
    for w in waypoints.windows(2) {
        let len = w[0]
            .iter()
            .zip(&w[1])
            .map(|(a, b)| (b - a) * (b - a))
            .sum::<f64>()
            .sqrt();
        let dir: Vec<f64> = if len > 0.0 {
            w[0].iter().zip(&w[1]).map(|(a, b)| (b - a) / len).collect()
        } else {
            vec![0.0; dof]
        };
        arc.push(arc[arc.len() - 1] + len);
        dirs.push(dir);
    }
    // Straight runs between rest points: segments of one direction.
    let mut stop = vec![false; n];
    stop[0] = true;
    stop[n - 1] = true;
    for &r in rest_at {
        if r < n {
            stop[r] = true;
        }
    }
    // Direction of the last non-empty segment, to find corners across repeated waypoints.
    let mut last_dir: Option<usize> = None;
    for k in 0..dirs.len() {
        if arc[k + 1] <= arc[k] {
            continue;
        }
        if let Some(p) = last_dir {
            let cos: f64 = dirs[p].iter().zip(&dirs[k]).map(|(a, b)| a * b).sum();
            if cos < 1.0 - 1e-12 {
                stop[k] = true;
            }
        }
        last_dir = Some(k);
    }
    // Grid and per-stage limits (x̄, ū): each run's switch points and collinear waypoints.
    let mut grid: Vec<(f64, f64, f64)> = Vec::new(); // (s, x̄, ū) of the stage starting at s
    let mut rest = Vec::new(); // s of the rest points
    let mut k = 0;
    while k + 1 < n {
        // The run from waypoint k to the next stop.
        let mut e = k + 1;
        while !stop[e] {
            e += 1;
        }
        rest.push(arc[k]);
        let (s0, s1) = (arc[k], arc[e]);
        if s1 > s0 {
            let seg = (k..e)
                .find(|&j| arc[j + 1] > arc[j])
                .unwrap_or(k)
                .min(dirs.len() - 1);
            let (mut xbar, mut ubar) = (f64::INFINITY, f64::INFINITY);
            for (j, &d) in dirs[seg].iter().enumerate() {
                let d = d.abs();
                if d > 0.0 {
                    xbar = xbar.min((limits.velocity[j] / d).powi(2));
                    ubar = ubar.min(limits.acceleration[j] / d);
                }
            }
            let len = s1 - s0;
            let sw = xbar / (2.0 * ubar);
            let mut pts = vec![s0];
            if 2.0 * sw < len {
                pts.extend([s0 + sw, s1 - sw]);
            } else {
                pts.push(s0 + 0.5 * len);
            }
            pts.extend(arc[k + 1..e].iter().copied());
            pts.sort_by(f64::total_cmp);
            pts.dedup_by(|a, b| *a - *b <= 0.0);
            grid.extend(pts.into_iter().map(|s| (s, xbar, ubar)));
        }
        k = e;
    }
    let total = arc[n - 1];
    rest.push(total);
    let m = grid.len();
    // Backward pass (Pham & Pham 2018, Alg. 1 lines 1–5): k_i, the top of K_i.
    let mut kmax = vec![0.0; m + 1];
    let mut r = rest.len() - 1;
    for i in (0..m).rev() {
        let (s, xbar, ubar) = grid[i];
        let next = if i + 1 < m { grid[i + 1].0 } else { total };
        while r > 0 && rest[r] > s {
            r -= 1;
        }
        kmax[i] = if rest[r] == s {
            0.0
        } else {
            xbar.min(kmax[i + 1] + 2.0 * (next - s) * ubar)
        };
    }
    // Forward pass (Alg. 1 lines 6–10): the greedy control, and the time of each stage.
    let mut stages = Vec::with_capacity(m);
    let (mut x, mut t) = (0.0f64, 0.0);
    for i in 0..m {
        let (s, _, ubar) = grid[i];
        let next = if i + 1 < m { grid[i + 1].0 } else { total };
        let delta = next - s;
        let u = ubar.min((kmax[i + 1] - x) / (2.0 * delta));
        let x1 = (x + 2.0 * delta * u).clamp(0.0, kmax[i + 1]);
        let v = x.sqrt() + x1.sqrt();
        let dt = if v > 0.0 { 2.0 * delta / v } else { 0.0 };
        stages.push(Stage {
            s,
            delta,
            x,
            u,
            t,
            dt,
        });
        t += dt;
        x = x1;
    }
    // A motion of non-zero length takes a finite, positive time; limits so small that the
    // squared velocity bound underflows (or so large that it overflows) would answer an
    // instant jump or an endless one.
    if total > 0.0 && !(t.is_finite() && t > 0.0) {
        return Err(err(
            "velocity_limits",
            format!(
                "the limits are outside what can time this path (a motion of length {total} \
                 would take {t} s)"
            ),
        ));
    }
    let mut tp = TimedPath {
        waypoints: waypoints.to_vec(),
        arc,
        dirs,
        stages,
        waypoint_times: Vec::new(),
        duration: t,
    };
    tp.waypoint_times = tp.arc.iter().map(|&s| tp.time_at_arc(s)).collect();
    Ok(tp)
}

impl TimedPath {
    /// Number of path coordinates.
    pub fn dof(&self) -> usize {
        self.waypoints[0].len()
    }

    /// The waypoints timed.
    pub fn waypoints(&self) -> &[Vec<f64>] {
        &self.waypoints
    }

    /// The time the trajectory reaches arc length `s` (its first arrival).
    fn time_at_arc(&self, s: f64) -> f64 {
        let i = self.stages.partition_point(|g| g.s + g.delta < s);
        let Some(g) = self.stages.get(i) else {
            return self.duration;
        };
        let d = (s - g.s).clamp(0.0, g.delta);
        let v0 = g.x.sqrt();
        let v1 = (g.x + 2.0 * g.u * d).max(0.0).sqrt();
        if v0 + v1 > 0.0 {
            g.t + 2.0 * d / (v0 + v1)
        } else {
            g.t
        }
    }

    /// Arc length, ṡ and s̈ at time `t` (clamped into [0, duration]).
    fn arc_at(&self, t: f64) -> (f64, f64, f64) {
        let Some(last) = self.stages.last() else {
            return (0.0, 0.0, 0.0);
        };
        let t = t.clamp(0.0, self.duration);
        let i = self
            .stages
            .partition_point(|g| g.t + g.dt <= t)
            .min(self.stages.len() - 1);
        let g = &self.stages[i];
        if t >= self.duration {
            return (last.s + last.delta, 0.0, 0.0);
        }
        let tau = (t - g.t).clamp(0.0, g.dt);
        let v0 = g.x.sqrt();
        let sd = (v0 + g.u * tau).max(0.0);
        let s = (g.s + v0 * tau + 0.5 * g.u * tau * tau).clamp(g.s, g.s + g.delta);
        (s, sd, g.u)
    }

    /// The state at time `t` (clamped into [0, duration]): positions on the polyline,
    /// velocities and accelerations.
    pub fn state_at(&self, t: f64) -> TimedPoint {
        let dof = self.dof();
        let (s, sd, sdd) = self.arc_at(t);
        let n = self.waypoints.len();
        let mut positions = self.waypoints[n - 1].clone();
        let mut velocities = vec![0.0; dof];
        let mut accelerations = vec![0.0; dof];
        if n > 1 && s < self.arc[n - 1] {
            // The segment holding s (the last one starting at or before it).
            let k = (self.arc.partition_point(|&a| a <= s).max(1) - 1).min(n - 2);
            let d = s - self.arc[k];
            let (from, to) = (&self.waypoints[k], &self.waypoints[k + 1]);
            for (j, &u) in self.dirs[k].iter().enumerate() {
                // On the segment, between its two ends (rounding can step past its far end).
                let (a, b) = (from[j], to[j]);
                positions[j] = (a + d * u).clamp(a.min(b), a.max(b));
                velocities[j] = u * sd;
                accelerations[j] = u * sdd;
            }
        }
        TimedPoint {
            time: t.clamp(0.0, self.duration),
            positions,
            velocities,
            accelerations,
        }
    }

    /// Most points of a sampling of this path: [`MAX_POINTS`], and [`MAX_VALUES`] / joints.
    pub fn max_points(&self) -> usize {
        MAX_POINTS.min(MAX_VALUES / self.dof().max(1))
    }

    /// Number of points [`Self::sample`] gives at `period`.
    pub fn sample_count(&self, period: f64) -> usize {
        let steps = (self.duration / period).floor();
        if !steps.is_finite() || steps > MAX_POINTS as f64 {
            return usize::MAX;
        }
        let steps = steps as usize;
        steps + 1 + usize::from((steps as f64) * period < self.duration)
    }

    /// States every `period` seconds from 0, and the final state at the duration. Fails
    /// (naming `field`) when the period is outside [`MIN_SAMPLE_PERIOD`, `MAX_SAMPLE_PERIOD`]
    /// or gives more than [`Self::max_points`] points.
    pub fn sample(&self, period: f64, field: &str) -> Result<Vec<TimedPoint>, TimingError> {
        check_sample_period(field, period)?;
        let count = self.sample_count(period);
        if count > self.max_points() {
            return Err(err(
                field,
                format!(
                    "a {:.3} s trajectory of {} joints sampled every {period} s has more than {} \
                     points ({MAX_POINTS} points, {MAX_VALUES} values at most)",
                    self.duration,
                    self.dof(),
                    self.max_points()
                ),
            ));
        }
        let mut out = Vec::with_capacity(count);
        let steps = (self.duration / period).floor() as usize;
        for i in 0..=steps {
            out.push(self.state_at(i as f64 * period));
        }
        if (steps as f64) * period < self.duration {
            out.push(self.state_at(self.duration));
        }
        Ok(out)
    }

    /// The smallest period ≥ `period` whose sampling has at most [`Self::max_points`] points.
    pub fn feasible_period(&self, period: f64) -> f64 {
        let max = self.max_points();
        if self.sample_count(period) <= max {
            period
        } else {
            (self.duration / max.saturating_sub(2).max(1) as f64).max(period)
        }
    }
}

/// The timing settings of a request: sampling period and MoveIt's scaling factors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimingOptions {
    pub sample_period: f64,
    pub velocity_scaling: f64,
    pub acceleration_scaling: f64,
}

impl Default for TimingOptions {
    fn default() -> Self {
        TimingOptions {
            sample_period: DEFAULT_SAMPLE_PERIOD,
            velocity_scaling: 1.0,
            acceleration_scaling: 1.0,
        }
    }
}

impl TimingOptions {
    /// The options of a request's fields (`sample_period`, `velocity_scaling`,
    /// `acceleration_scaling`), checked, with the defaults for those not given.
    pub fn from_request(
        sample_period: Option<f64>,
        velocity_scaling: Option<f64>,
        acceleration_scaling: Option<f64>,
    ) -> Result<TimingOptions, TimingError> {
        let o = TimingOptions {
            sample_period: sample_period.unwrap_or(DEFAULT_SAMPLE_PERIOD),
            velocity_scaling: velocity_scaling.unwrap_or(1.0),
            acceleration_scaling: acceleration_scaling.unwrap_or(1.0),
        };
        check_sample_period("sample_period", o.sample_period)?;
        check_scaling("velocity_scaling", o.velocity_scaling)?;
        check_scaling("acceleration_scaling", o.acceleration_scaling)?;
        Ok(o)
    }
}

/// The limits of every variable of `world` (in world order): each robot's
/// [`crate::Robot::velocity_limit`] and [`crate::Robot::acceleration_limit`].
pub fn world_limits(world: &CollisionWorld) -> TimingLimits {
    let mut l = TimingLimits {
        velocity: Vec::new(),
        acceleration: Vec::new(),
    };
    for p in &world.robots {
        for v in 0..p.robot.dof() {
            l.velocity.push(p.robot.velocity_limit(v));
            l.acceleration.push(p.robot.acceleration_limit(v));
        }
    }
    l
}

impl TimingLimits {
    /// The limits of the variables `vars` (indices into these limits).
    pub fn select(&self, vars: &[usize]) -> TimingLimits {
        TimingLimits {
            velocity: vars.iter().map(|&v| self.velocity[v]).collect(),
            acceleration: vars.iter().map(|&v| self.acceleration[v]).collect(),
        }
    }
}

impl TimedPath {
    /// The trajectory as answered (`trajectory_msgs/JointTrajectory`'s shape): `joint_names`,
    /// points every `period` s — or, when that would exceed [`Self::max_points`], every
    /// [`Self::feasible_period`] s, as `sample_period` then says — the waypoints with their
    /// times, and `events`.
    pub fn to_trajectory(
        &self,
        joint_names: &[String],
        period: f64,
        events: Vec<TrajectoryEvent>,
    ) -> Result<JointTrajectory, TimingError> {
        let period = self.feasible_period(period);
        let points = self
            .sample(period, "sample_period")?
            .into_iter()
            .map(|p| TrajectoryPoint {
                positions: p.positions,
                velocities: p.velocities,
                accelerations: p.accelerations,
                time_from_start: p.time,
            })
            .collect();
        Ok(JointTrajectory {
            joint_names: joint_names.to_vec(),
            points,
            sample_period: period,
            duration: self.duration,
            waypoints: self
                .waypoints
                .iter()
                .zip(&self.waypoint_times)
                .map(|(q, &t)| TimedWaypoint {
                    positions: q.clone(),
                    time_from_start: t,
                })
                .collect(),
            events,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(v: f64, a: f64, dof: usize) -> TimingLimits {
        TimingLimits {
            velocity: vec![v; dof],
            acceleration: vec![a; dof],
        }
    }

    #[test]
    fn straight_line_is_a_trapezoid() {
        // 1-D, length 4, v = 1, a = 1: 1 s up, 3 s cruise, 1 s down.
        let p = time_polyline(&[vec![0.0], vec![4.0]], &limits(1.0, 1.0, 1), &[]).expect("t");
        assert!((p.duration - 5.0).abs() < 1e-12, "{}", p.duration);
        let mid = p.state_at(2.5);
        assert!((mid.positions[0] - 2.0).abs() < 1e-12);
        assert!((mid.velocities[0] - 1.0).abs() < 1e-12);
        // Triangle: length 1 → 2 s.
        let q = time_polyline(&[vec![0.0], vec![1.0]], &limits(1.0, 1.0, 1), &[]).expect("t");
        assert!((q.duration - 2.0).abs() < 1e-12);
    }

    #[test]
    fn corners_stop_and_collinear_points_do_not() {
        let l = limits(1.0, 1.0, 2);
        let straight = [vec![0.0, 0.0], vec![2.0, 0.0], vec![4.0, 0.0]];
        let p = time_polyline(&straight, &l, &[]).expect("t");
        assert!((p.duration - 5.0).abs() < 1e-12);
        assert!(p.state_at(p.waypoint_times[1]).velocities[0] > 0.99);
        let stopped = time_polyline(&straight, &l, &[1]).expect("t");
        assert!((stopped.duration - 6.0).abs() < 1e-12);
        let corner = [vec![0.0, 0.0], vec![2.0, 0.0], vec![2.0, 2.0]];
        let c = time_polyline(&corner, &l, &[]).expect("t");
        assert!((c.duration - 6.0).abs() < 1e-12);
        assert!(c.state_at(3.0).velocities.iter().all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn bad_input_names_the_field() {
        let l = limits(1.0, 1.0, 2);
        let e = time_polyline(&[vec![0.0, 0.0], vec![1.0]], &l, &[]).expect_err("len");
        assert_eq!(e.field, "waypoints[1]");
        let e = time_polyline(&[vec![0.0, f64::NAN]], &l, &[]).expect_err("nan");
        assert_eq!(e.field, "waypoints[0][1]");
        let e = time_polyline(&[vec![0.0, 0.0]], &limits(0.0, 1.0, 2), &[]).expect_err("v");
        assert_eq!(e.field, "velocity_limits[0]");
        assert!(l.scaled(0.0, 1.0).is_err() && l.scaled(1.0, 1.5).is_err());
        let e = l.scaled(1e-300, 1.0).expect_err("tiny");
        assert_eq!(e.field, "velocity_scaling");
        assert!(l.scaled(MIN_SCALING, MIN_SCALING).is_ok());
        assert!(l.scaled(MIN_SCALING * 0.99, 1.0).is_err());
        // Limits that underflow the squared velocity bound: a typed error, never a 0 s motion.
        let e = time_polyline(
            &[vec![0.0, 0.0], vec![1.0, 0.0]],
            &limits(1e-300, 1.0, 2),
            &[],
        )
        .expect_err("underflow");
        assert_eq!(e.field, "velocity_limits");
        let p = time_polyline(&[vec![0.0, 0.0]], &l, &[]).expect("one point");
        assert_eq!(p.duration, 0.0);
        assert_eq!(p.sample(0.01, "sample_period").expect("s").len(), 1);
        assert!(p.sample(0.0, "sample_period").is_err());
        // A long 20-joint path: at most MAX_VALUES / 20 points; coarser when asked for more.
        let long = time_polyline(
            &[vec![0.0; 20], vec![1000.0; 20]],
            &limits(1.0, 1.0, 20),
            &[],
        )
        .expect("t");
        assert_eq!(long.max_points(), MAX_VALUES / 20);
        let e = long.sample(0.01, "sample_period").expect_err("too many");
        assert_eq!(e.field, "sample_period");
        let period = long.feasible_period(0.01);
        assert!(period > 0.01);
        let n = long.sample(period, "sample_period").expect("sampled").len();
        assert!(n <= long.max_points() && n > long.max_points() / 2, "{n}");
    }
}
