//! The JSON answers of Multi-Robot-RRT (CLI `plan multi-robot --json`, job kind `multi_robot`):
//! statistics of 002 Tables I–II and the plan with its schedule and every robot's trajectory.

use std::time::Duration;

use super::{MultiRobotPlan, MultiRobotProblem, MultiRobotStats};

impl MultiRobotStats {
    /// JSON with times in milliseconds (002 Tables I and II's columns and the per-worker rows).
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        json!({
            "planning_time_ms": ms(self.planning_time),
            "phase_space_time_ms": ms(self.phase_space_time),
            "total_time_ms": ms(self.total_time),
            "ik_results": self.ik_results(),
            "solution_trajectories": self.solutions(),
            "collision_checks": self.collision_checks(),
            "combinations_checked": self.combinations,
            "rejected": {
                "collision": self.rejected_collision,
                "score": self.rejected_score,
                "deadlock": self.rejected_deadlock,
            },
            "best_score": self.best_score,
            "scores": self.scores,
            "exact_scores": self.exact_scores,
            "score_time_ms_mean": if self.scores > 0 { ms(self.score_time) / self.scores as f64 } else { 0.0 },
            "workers": self.workers.iter().map(|w| json!({
                "robot": w.name,
                "searches": w.searches,
                "solved": w.solved,
                "solutions": w.solutions,
                "ik_results": w.ik_results,
                "collision_checks": w.collision_checks,
                "time_ms": ms(w.time),
            })).collect::<Vec<_>>(),
        })
    }
}

impl MultiRobotPlan {
    /// The answer of a Multi-Robot-RRT plan (CLI `plan multi-robot --json` and the HTTP job
    /// kind `multi_robot`): every robot's trajectory and grasps, the score, the schedule on one
    /// clock (`sample_period`: also samples every that many seconds), grasp events and the
    /// statistics.
    ///
    /// `trajectories` maps each robot to its [`manyhands_api::JointTrajectory`] on the common
    /// clock ([`Schedule::trajectories`], every `trajectory_period` s), with its grasp events
    /// at the end of the schedule (all hands close together on the one object).
    pub fn to_json(
        &self,
        p: &MultiRobotProblem,
        sample_period: Option<f64>,
        trajectory_period: f64,
    ) -> Result<serde_json::Value, crate::trajectory::timing::TimingError> {
        use serde_json::json;
        let names: Vec<String> = self
            .solutions
            .iter()
            .map(|s| p.members[s.member].name.clone())
            .collect();
        let robots: Vec<_> = self
            .solutions
            .iter()
            .map(|s| {
                let m = &p.members[s.member];
                let placed = &p.world.robots[m.robot];
                let vars: Vec<&str> = (0..placed.robot.dof())
                    .map(|v| placed.robot.var_name(v))
                    .collect();
                json!({
                    "name": m.name,
                    "variables": vars,
                    "waypoints": s.path,
                    "grasps": {
                        "left": m.problem.left_names[s.grasps.0],
                        "right": m.problem.right_names[s.grasps.1],
                    },
                    "left_end_effector": m.problem.left.end_effector,
                    "right_end_effector": m.problem.right.end_effector,
                    "stats": s.stats.to_json(),
                })
            })
            .collect();
        let mut events = Vec::new();
        let mut robot_events = Vec::new();
        let mut variables = Vec::new();
        for s in &self.solutions {
            let m = &p.members[s.member];
            let placed = &p.world.robots[m.robot];
            variables.push(
                (0..placed.robot.dof())
                    .map(|v| placed.robot.var_name(v).to_string())
                    .collect::<Vec<_>>(),
            );
            let mut mine = Vec::new();
            for (ee, g) in [
                (
                    &m.problem.left.end_effector,
                    &m.problem.left_names[s.grasps.0],
                ),
                (
                    &m.problem.right.end_effector,
                    &m.problem.right_names[s.grasps.1],
                ),
            ] {
                events.push(json!({
                    "time": self.schedule.duration,
                    "kind": "grasp",
                    "robot": m.name,
                    "end_effector": ee,
                    "object": p.object,
                    "grasp": g,
                }));
                mine.push(manyhands_api::TrajectoryEvent {
                    kind: "grasp".into(),
                    time_from_start: self.schedule.duration,
                    waypoint: None,
                    robot: m.name.clone(),
                    end_effector: ee.clone(),
                    object: p.object.clone(),
                    grasp: g.clone(),
                });
            }
            robot_events.push(mine);
        }
        let trajectories: serde_json::Map<String, serde_json::Value> = names
            .iter()
            .cloned()
            .zip(
                self.schedule
                    .trajectories(&variables, trajectory_period, robot_events)?
                    .into_iter()
                    .map(|t| json!(t)),
            )
            .collect();
        Ok(json!({
            "object": p.object,
            "robots": robots,
            "score": {
                "epsilon": self.score.epsilon,
                "force_closure": self.score.force_closure,
                "rank": self.score.rank,
                "wrenches": self.score.wrenches,
                "lambda": self.score.lambda,
                "cone_edges": self.score_edges,
                "lower_bound": self.score_edges < self.requested_edges,
            },
            "schedule": self.schedule.to_json(&names, sample_period),
            "events": events,
            "trajectories": trajectories,
            "stats": self.stats.to_json(),
        }))
    }
}
