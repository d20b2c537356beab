//! What a planner returns: the path and its statistics, or a [`PlanError`].

use std::time::Duration;

use serde::Serialize;
use thiserror::Error;

use crate::planning::base::termination::StopReason;

/// Statistics of one planning query (OMPL's benchmark properties, in spirit).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PlanStats {
    /// Wall time of the search, from the call to the validated raw path (start and goal checks
    /// and the final re-validation included).
    pub time: Duration,
    /// Wall time of path simplification (shortcutting and its re-validation).
    pub simplify_time: Duration,
    /// Planner iterations (random samples drawn).
    pub iterations: u64,
    /// Number of states in the start tree.
    pub start_tree_size: usize,
    /// Number of states in the goal tree (all goal roots included).
    pub goal_tree_size: usize,
    /// Configuration collision checks (start, goals, segments, final re-validation).
    pub collision_checks: u64,
    /// Segments given to the motion validator.
    pub segments_checked: u64,
    /// Length (space distance) of the raw path.
    pub length_raw: f64,
    /// Length of the simplified path (equal to `length_raw` without simplification).
    pub length_simplified: f64,
    /// Vertices of the raw path.
    pub vertices_raw: usize,
    /// Vertices of the returned path.
    pub vertices_simplified: usize,
    /// Goal-sampler (IK) queries made by planners that search their goals (IK-RRT family).
    pub ik_queries: u64,
    /// Wall time spent in those queries (part of `time`; 000 Table 5's "IK solving").
    pub ik_time: Duration,
    /// Valid goal configurations found and added to the goal tree (IK solutions, 000 Alg. 3).
    pub ik_solutions: u64,
    /// Analytic arm-IK calls made by those queries.
    pub ik_calls: u64,
    /// Jacobian pseudoinverse steps (J+-RRT family, 000 Alg. 2 and 5).
    pub jacobian_steps: u64,
    /// Times the search started over with a new tree (J+-RRT family, `restart_nodes`).
    pub restarts: u64,
    /// The certified motion checks of the search, shortcutting and final re-validation (`None`
    /// when the checker does not certify motions this way): every returned segment is then
    /// proven collision-free as a continuous motion in the fast model.
    pub certification: Option<crate::collision::CertifyStats>,
    /// States removed from the trees because an edge accepted by the screening pass of lazy
    /// certification failed its full certification (`RrtConnectSettings::lazy`).
    pub lazy_removed: u64,
}

impl PlanStats {
    /// JSON with times in milliseconds (the form the CLI and the server print).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "time_ms": self.time.as_secs_f64() * 1e3,
            "simplify_time_ms": self.simplify_time.as_secs_f64() * 1e3,
            "iterations": self.iterations,
            "start_tree_size": self.start_tree_size,
            "goal_tree_size": self.goal_tree_size,
            "collision_checks": self.collision_checks,
            "segments_checked": self.segments_checked,
            "length_raw": self.length_raw,
            "length_simplified": self.length_simplified,
            "vertices_raw": self.vertices_raw,
            "vertices_simplified": self.vertices_simplified,
            "ik_queries": self.ik_queries,
            "ik_time_ms": self.ik_time.as_secs_f64() * 1e3,
            "ik_solutions": self.ik_solutions,
            "ik_calls": self.ik_calls,
            "jacobian_steps": self.jacobian_steps,
            "restarts": self.restarts,
            "certification": self.certification.map(|c| serde_json::json!({
                "motions": c.motions,
                "proven_free": c.proven_free,
                "collides": c.collides,
                "unproven": c.unproven,
                "max_inflation_m": c.max_inflation,
                "floor_m": c.floor,
                "finest_inflation_m": c.finest_inflation,
            })),
        })
    }
}

/// A solved query: a collision-free path from the start to one of the goals.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanResult {
    /// States of the path in the space's coordinates; first = start, last = `goals[goal_index]`.
    pub path: Vec<Vec<f64>>,
    /// Index (in the goal list given to the planner) of the goal reached.
    pub goal_index: usize,
    pub stats: PlanStats,
}

/// Why a query was not solved.
#[derive(Debug, Clone, Error)]
pub enum PlanError {
    /// The space or an input does not fit (dimension, bounds, non-finite values).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The start state is outside the bounds or in collision.
    #[error("start configuration invalid: {reason}")]
    InvalidStart { reason: String },
    /// No goal state is within the bounds and collision-free.
    #[error("no valid goal configuration ({count} given): {reason}")]
    InvalidGoal { count: usize, reason: String },
    /// Fixed trajectories admit no coordination that was found (phase-space scheduling, 002
    /// §V): their final configurations collide with each other, or no monotone collision-free
    /// phase path was found and one robot after the other collides too. Not a goal problem:
    /// the trajectories' ends are given, only their timing is searched.
    #[error("no collision-free schedule: {reason}")]
    NoSchedule { reason: String },
    /// The time limit ran out before a path was found.
    #[error("time limit reached ({:.3} ms and {} iterations in this step)", .stats.time.as_secs_f64() * 1e3, .stats.iterations)]
    Timeout { stats: Box<PlanStats> },
    /// The iteration limit was reached before a path was found.
    #[error("iteration limit reached after {} iterations", .stats.iterations)]
    IterationLimit { stats: Box<PlanStats> },
    /// The external stop flag was raised.
    #[error("stopped on request after {} iterations", .stats.iterations)]
    Stopped { stats: Box<PlanStats> },
    /// A phase of a chained task failed (see [`crate::planning::tasks::task`]).
    #[error("{phase}: {error}")]
    InPhase {
        phase: String,
        error: Box<PlanError>,
    },
    /// The path found failed its final re-validation (a bug in a planner, never expected).
    #[error("path failed re-validation at segment {segment}")]
    PathInvalid {
        segment: usize,
        stats: Box<PlanStats>,
    },
}

impl PlanError {
    /// The error for a termination condition that fired.
    pub fn stopped(reason: StopReason, stats: PlanStats) -> PlanError {
        let stats = Box::new(stats);
        match reason {
            StopReason::TimeLimit => PlanError::Timeout { stats },
            StopReason::IterationLimit => PlanError::IterationLimit { stats },
            StopReason::Requested => PlanError::Stopped { stats },
        }
    }

    /// The error itself, or the one inside a failed phase.
    /// This error as the failure of `phase` (a step of a composed planner).
    pub fn in_phase(self, phase: impl Into<String>) -> PlanError {
        PlanError::InPhase {
            phase: phase.into(),
            error: Box::new(self),
        }
    }

    pub fn root(&self) -> &PlanError {
        match self {
            PlanError::InPhase { error, .. } => error.root(),
            e => e,
        }
    }

    /// Statistics gathered before the failure, when the search ran.
    pub fn stats(&self) -> Option<&PlanStats> {
        match self {
            PlanError::Timeout { stats }
            | PlanError::IterationLimit { stats }
            | PlanError::Stopped { stats }
            | PlanError::PathInvalid { stats, .. } => Some(stats),
            PlanError::InPhase { error, .. } => error.stats(),
            _ => None,
        }
    }
}
