//! What the multi-arm planner returns: one composite polyline of every arm's planned variables,
//! proven free with all arms moving together, timed on one clock (the time-optimal timing that
//! stays on the polyline, [`crate::trajectory::timing`]), the schedule (every arm's values at
//! every vertex time), the makespan before and after shortcutting, the method that succeeded
//! and the statistics of every method tried.

use std::ops::Range;
use std::time::Duration;

use serde_json::{json, Value};

use crate::planning::planners::phase_space::ScheduleMethod;
use crate::trajectory::timing::{TimedPath, TimingError};

/// The method that found the plan (module documentation of [`super`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MultiArmMethod {
    /// Every arm alone, then the phase-space schedule (002 §V).
    Decoupled,
    /// Prioritized planning in space-time.
    Prioritized,
    /// RRT-Connect in the composite space of the arms in conflict (or of all arms).
    Composite,
}

impl MultiArmMethod {
    pub fn name(self) -> &'static str {
        match self {
            MultiArmMethod::Decoupled => "decoupled",
            MultiArmMethod::Prioritized => "prioritized",
            MultiArmMethod::Composite => "composite",
        }
    }
}

/// One method tried.
#[derive(Debug, Clone, PartialEq)]
pub struct Attempt {
    pub method: MultiArmMethod,
    pub solved: bool,
    pub time: Duration,
    /// Why it failed, or what it found.
    pub note: String,
}

/// Statistics of a multi-arm query.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MultiArmStats {
    /// Everything: planning, shortcutting, certification, timing.
    pub time: Duration,
    /// Until the raw plan was found and certified.
    pub planning_time: Duration,
    pub shortcut_time: Duration,
    pub attempts: Vec<Attempt>,
    /// Certified composite segment checks (methods, shortcutting and final certification).
    pub segments_certified: u64,
    pub vertices_raw: usize,
    pub vertices: usize,
    pub shortcuts_tried: u64,
    pub shortcuts_composite: u64,
    pub shortcuts_per_arm: u64,
}

/// A solved multi-arm query.
#[derive(Debug, Clone)]
pub struct MultiArmPlan {
    pub method: MultiArmMethod,
    /// How the phase-space scheduler coordinated the paths (decoupled only).
    pub schedule_method: Option<ScheduleMethod>,
    /// Priority order of the arms (prioritized and composite: the movers in planning order).
    pub order: Vec<usize>,
    /// Arms planned together in the composite space (composite only).
    pub composite_arms: Vec<usize>,
    /// Pairs of arms whose paths alone had no schedule (when computed).
    pub conflicts: Vec<(usize, usize)>,
    /// World variables of a composite configuration, arm by arm.
    pub vars: Vec<usize>,
    /// Where each arm's values sit in a composite configuration.
    pub arm_ranges: Vec<Range<usize>>,
    /// The plan: straight composite segments, each proven free with all arms moving.
    pub path: Vec<Vec<f64>>,
    /// Its time-optimal timing (velocity and acceleration limits, scaled as asked).
    pub timed: TimedPath,
    /// Makespan of the raw plan and of the returned (shortcut) plan, seconds, both timed the
    /// same way.
    pub makespan_before: f64,
    pub makespan: f64,
    pub stats: MultiArmStats,
}

impl MultiArmPlan {
    /// JSON of the plan. `arm_names[k]` names arm k (its robot), `joint_names` the composite
    /// variables (`robot/joint`); `period` samples the trajectory.
    pub fn to_json(
        &self,
        arm_names: &[String],
        joint_names: &[String],
        period: f64,
    ) -> Result<Value, TimingError> {
        let trajectory = self.timed.to_trajectory(joint_names, period, Vec::new())?;
        let schedule: Vec<Value> = self
            .path
            .iter()
            .zip(&self.timed.waypoint_times)
            .map(|(c, t)| {
                let per_arm: Vec<&[f64]> = self.arm_ranges.iter().map(|r| &c[r.clone()]).collect();
                json!({"time_from_start": t, "positions": per_arm})
            })
            .collect();
        let s = &self.stats;
        Ok(json!({
            "planner": "multi_arm",
            "method": self.method,
            "schedule_method": self.schedule_method,
            "certified": true,
            "arms": arm_names,
            "order": self.order.iter().map(|&k| &arm_names[k]).collect::<Vec<_>>(),
            "composite_arms": self.composite_arms.iter().map(|&k| &arm_names[k]).collect::<Vec<_>>(),
            "conflicts": self.conflicts.iter().map(|&(a, b)| [&arm_names[a], &arm_names[b]]).collect::<Vec<_>>(),
            "joints": joint_names,
            "path": self.path,
            "makespan": self.makespan,
            "makespan_before_shortcut": self.makespan_before,
            "schedule": {"arms": arm_names, "points": schedule, "duration": self.timed.duration},
            "trajectory": trajectory,
            "stats": {
                "time_ms": s.time.as_secs_f64() * 1e3,
                "planning_time_ms": s.planning_time.as_secs_f64() * 1e3,
                "shortcut_time_ms": s.shortcut_time.as_secs_f64() * 1e3,
                "segments_certified": s.segments_certified,
                "vertices_raw": s.vertices_raw,
                "vertices": s.vertices,
                "makespan_before": self.makespan_before,
                "makespan_after": self.makespan,
                "shortcuts": {"tried": s.shortcuts_tried, "composite": s.shortcuts_composite,
                              "per_arm": s.shortcuts_per_arm},
                "attempts": s.attempts.iter().map(|a| json!({
                    "method": a.method, "solved": a.solved,
                    "time_ms": a.time.as_secs_f64() * 1e3, "note": a.note,
                })).collect::<Vec<_>>(),
            },
        }))
    }
}
