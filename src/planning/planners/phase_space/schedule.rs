//! A [`Schedule`] on its clock (002 §V's timing, module documentation of [`super`]): the state
//! of every robot at any time, samples, every robot's JointTrajectory and the JSON answer.

use super::{Profile, Schedule};

/// Every robot's positions, velocities and accelerations at one time.
pub type FullState = (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<Vec<f64>>);

/// A sample of a schedule: time, every robot's positions and velocities.
pub type Sample = (f64, Vec<Vec<f64>>, Vec<Vec<f64>>);

impl Schedule {
    /// The path parameter s ∈ [0, 1] of a piece of duration `dt` at time `tau` into it, ṡ and
    /// s̈ (0 for a constant-velocity piece, whose velocity jumps at its ends).
    fn piece(profile: Profile, dt: f64, tau: f64) -> (f64, f64, f64) {
        match profile {
            Profile::Constant => {
                if dt <= 0.0 {
                    (1.0, 0.0, 0.0)
                } else {
                    ((tau / dt).clamp(0.0, 1.0), 1.0 / dt, 0.0)
                }
            }
            Profile::Trapezoid { v, a } => {
                let ta = v / a;
                let tau = tau.clamp(0.0, dt);
                if tau < ta {
                    (0.5 * a * tau * tau, a * tau, a)
                } else if tau > dt - ta {
                    let r = dt - tau;
                    (1.0 - 0.5 * a * r * r, a * r, -a)
                } else {
                    (0.5 * a * ta * ta + v * (tau - ta), v, 0.0)
                }
            }
        }
    }

    /// Every robot's configuration and velocity at time `t` of the common clock.
    pub fn state_at(&self, t: f64) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let (p, v, _) = self.full_state_at(t);
        (p, v)
    }

    /// Every robot's configuration, velocity and acceleration at time `t` of the common clock.
    pub fn full_state_at(&self, t: f64) -> FullState {
        let k = self
            .knots
            .partition_point(|k| k.time <= t)
            .clamp(1, self.knots.len().max(1))
            - 1;
        let a = &self.knots[k];
        if k + 1 >= self.knots.len() {
            let zeros: Vec<Vec<f64>> = a.configs.iter().map(|c| vec![0.0; c.len()]).collect();
            return (a.configs.clone(), zeros.clone(), zeros);
        }
        let b = &self.knots[k + 1];
        let (s, sd, sdd) = Self::piece(self.profiles[k], b.time - a.time, t - a.time);
        let mut pos = Vec::with_capacity(a.configs.len());
        let mut vel = Vec::with_capacity(a.configs.len());
        let mut acc = Vec::with_capacity(a.configs.len());
        for (ca, cb) in a.configs.iter().zip(&b.configs) {
            pos.push(ca.iter().zip(cb).map(|(x, y)| x + (y - x) * s).collect());
            vel.push(ca.iter().zip(cb).map(|(x, y)| (y - x) * sd).collect());
            acc.push(ca.iter().zip(cb).map(|(x, y)| (y - x) * sdd).collect());
        }
        (pos, vel, acc)
    }

    /// Each robot's trajectory on the common clock (`variables[r]`: the joint names of robot
    /// r's configuration): points every `period` s from 0 to the schedule's duration (coarser
    /// when that would exceed [`crate::trajectory::timing::MAX_POINTS`] points or
    /// [`crate::trajectory::timing::MAX_VALUES`] values over all robots), the
    /// knots as its waypoints (a robot that waits keeps its configuration between two of
    /// them), and `events[r]`. Within the joint limits when the schedule was timed with
    /// acceleration limits (trapezoidal pieces); with velocity limits only, the velocity
    /// jumps at the knots.
    pub fn trajectories(
        &self,
        variables: &[Vec<String>],
        period: f64,
        mut events: Vec<Vec<manyhands_api::TrajectoryEvent>>,
    ) -> Result<Vec<manyhands_api::JointTrajectory>, crate::trajectory::timing::TimingError> {
        use crate::trajectory::timing::{check_sample_period, MAX_POINTS, MAX_VALUES};
        check_sample_period("sample_period", period)?;
        let joints: usize = variables.iter().map(Vec::len).sum();
        let max = MAX_POINTS.min(MAX_VALUES / joints.max(1)).max(3);
        let period = if self.duration / period + 2.0 > max as f64 {
            self.duration / (max - 2) as f64
        } else {
            period
        };
        let samples: Vec<_> = {
            let steps = (self.duration / period).floor() as usize;
            let mut times: Vec<f64> = (0..=steps).map(|i| i as f64 * period).collect();
            if (steps as f64) * period < self.duration {
                times.push(self.duration);
            }
            times
                .into_iter()
                .map(|t| (t, self.full_state_at(t)))
                .collect()
        };
        events.resize(variables.len(), Vec::new());
        Ok(variables
            .iter()
            .zip(events)
            .enumerate()
            .map(|(r, (names, events))| manyhands_api::JointTrajectory {
                joint_names: names.clone(),
                points: samples
                    .iter()
                    .map(|(t, (p, v, a))| manyhands_api::TrajectoryPoint {
                        positions: p[r].clone(),
                        velocities: v[r].clone(),
                        accelerations: a[r].clone(),
                        time_from_start: *t,
                    })
                    .collect(),
                sample_period: period,
                duration: self.duration,
                waypoints: self
                    .knots
                    .iter()
                    .map(|k| manyhands_api::TimedWaypoint {
                        positions: k.configs[r].clone(),
                        time_from_start: k.time,
                    })
                    .collect(),
                events,
            })
            .collect())
    }

    /// Samples at `period` seconds (and the end): `(time, positions per robot, velocities)`.
    pub fn sample(&self, period: f64) -> Vec<Sample> {
        let mut out = Vec::new();
        if period.is_nan() || period <= 0.0 {
            return out;
        }
        let steps = (self.duration / period).floor() as usize;
        for i in 0..=steps {
            let t = i as f64 * period;
            let (p, v) = self.state_at(t);
            out.push((t, p, v));
        }
        if steps as f64 * period < self.duration {
            let (p, v) = self.state_at(self.duration);
            out.push((self.duration, p, v));
        }
        out
    }
}

impl Schedule {
    /// JSON of the schedule (times in seconds; `robots` names the robots of `phase` order):
    /// method, duration, phase path, knots as points `{time_from_start, phase, positions}` with
    /// one configuration per robot, and samples every `sample_period` s when given.
    pub fn to_json(&self, robots: &[String], sample_period: Option<f64>) -> serde_json::Value {
        use serde_json::json;
        let points: Vec<_> = self
            .knots
            .iter()
            .map(|k| json!({"time_from_start": k.time, "phase": k.phase, "positions": k.configs}))
            .collect();
        let mut v = json!({
            "method": self.method,
            "duration": self.duration,
            "robots": robots,
            "robot_durations": self.robot_durations,
            "phase_path": self.phase_path,
            "points": points,
            "profile": if self.profiles.iter().any(|p| matches!(p, Profile::Trapezoid { .. })) {
                "trapezoid"
            } else {
                "constant_velocity"
            },
            "stats": {
                "time_ms": self.stats.time.as_secs_f64() * 1e3,
                "iterations": self.stats.iterations,
                "tree_nodes": self.stats.tree_nodes,
                "collision_checks": self.stats.collision_checks,
                "segments_certified": self.stats.segments_checked,
                "path_vertices_raw": self.stats.path_vertices_raw,
                "path_vertices": self.stats.path_vertices,
            },
        });
        if let Some(p) = sample_period.filter(|p| *p > 0.0) {
            let samples: Vec<_> = self
                .sample(p)
                .into_iter()
                .map(|(t, pos, vel)| json!({"time_from_start": t, "positions": pos, "velocities": vel}))
                .collect();
            v["samples"] = json!(samples);
            v["sample_period"] = json!(p);
        }
        v
    }
}
