//! A given joint path as a timed [`JointTrajectory`] ([`crate::trajectory::timing`]): what
//! `POST /v1/trajectories` and `manyhands time` do. Resolves joint names against the robot
//! models, takes the limits from them (URDF velocity, `joint_limits.yaml`, defaults) with the
//! request's overrides and scaling, and bounds every size (waypoints, points) so that no input
//! makes the answer unbounded.

pub mod timing;

use std::collections::HashMap;
use std::sync::Arc;

use manyhands_api::{JointTrajectory, TrajectoryRequest};

use crate::trajectory::timing::{time_polyline, TimingError, TimingLimits, TimingOptions};
use crate::Robot;

/// Most waypoints of a path to time.
pub const MAX_WAYPOINTS: usize = 10_000;

fn err(field: impl Into<String>, reason: impl Into<String>) -> TimingError {
    TimingError {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Per-joint-name overrides of velocity (`.0`) and acceleration (`.1`) limits.
pub type LimitOverrides<'a> = (
    Option<&'a HashMap<String, f64>>,
    Option<&'a HashMap<String, f64>>,
);

/// One path coordinate: the robot model it belongs to and its variable there.
#[derive(Clone)]
pub struct PathJoint {
    pub robot: Arc<Robot>,
    pub var: usize,
}

/// The limits of `joints` from their robots, with per-name overrides (`overrides.0` velocity,
/// `overrides.1` acceleration, keyed by the names of `names`), scaled by `opts`.
pub fn path_limits(
    names: &[String],
    joints: &[PathJoint],
    overrides: LimitOverrides<'_>,
    opts: &TimingOptions,
) -> Result<TimingLimits, TimingError> {
    let mut l = TimingLimits {
        velocity: joints
            .iter()
            .map(|j| j.robot.velocity_limit(j.var))
            .collect(),
        acceleration: joints
            .iter()
            .map(|j| j.robot.acceleration_limit(j.var))
            .collect(),
    };
    for (field, map, target) in [
        ("max_velocity", overrides.0, &mut l.velocity),
        ("max_acceleration", overrides.1, &mut l.acceleration),
    ] {
        let Some(map) = map else { continue };
        // Sorted, so that the first bad entry named is the same every time.
        let mut entries: Vec<(&String, &f64)> = map.iter().collect();
        entries.sort_by(|a, b| a.0.cmp(b.0));
        for (name, &x) in entries {
            let f = format!("{field}.{name}");
            let Some(k) = names.iter().position(|n| {
                n == name || n.rsplit_once('/').is_some_and(|(_, bare)| bare == name)
            }) else {
                return Err(err(f, "not one of the path's joints"));
            };
            if !(x.is_finite() && x > 0.0) {
                return Err(err(f, format!("{x} is not > 0")));
            }
            target[k] = x;
        }
    }
    l.scaled(opts.velocity_scaling, opts.acceleration_scaling)
}

/// Times `waypoints` of `joints` (named `names`; at rest at the waypoints `rest_at`) into a
/// trajectory, refusing paths of more than [`MAX_WAYPOINTS`] waypoints and samplings of more
/// than [`crate::trajectory::timing::MAX_POINTS`] points or [`crate::trajectory::timing::MAX_VALUES`] values (naming the
/// field).
pub fn time_named_path(
    names: &[String],
    waypoints: &[Vec<f64>],
    limits: &TimingLimits,
    opts: &TimingOptions,
    rest_at: &[usize],
) -> Result<JointTrajectory, TimingError> {
    if waypoints.is_empty() || waypoints.len() > MAX_WAYPOINTS {
        return Err(err(
            "waypoints",
            format!(
                "{} waypoints, 1 to {MAX_WAYPOINTS} allowed",
                waypoints.len()
            ),
        ));
    }
    for (w, q) in waypoints.iter().enumerate() {
        if q.len() != names.len() {
            return Err(err(
                format!("waypoints[{w}]"),
                format!("{} values for {} joints", q.len(), names.len()),
            ));
        }
    }
    let timed = time_polyline(waypoints, limits, rest_at)?;
    // Refused rather than sampled more coarsely than asked (sample() names the field).
    timed.sample(opts.sample_period, "sample_period")?;
    timed.to_trajectory(names, opts.sample_period, Vec::new())
}

/// `POST /v1/trajectories` on `robot` (the model `req.robot` names): the joints of
/// `req.joint_names` (`joint` or `robot/joint`), else of `req.group`, else all variables.
pub fn time_request(
    robot: &Arc<Robot>,
    req: &TrajectoryRequest,
) -> Result<JointTrajectory, TimingError> {
    let opts = TimingOptions::from_request(
        req.sample_period,
        req.velocity_scaling,
        req.acceleration_scaling,
    )?;
    let vars: Vec<usize> = match (&req.joint_names, &req.group) {
        (Some(_), Some(_)) => {
            return Err(err("group", "give joint_names or group, not both"));
        }
        (Some(names), None) => {
            if names.is_empty() {
                return Err(err("joint_names", "no joint"));
            }
            let mut vars = Vec::with_capacity(names.len());
            for (i, n) in names.iter().enumerate() {
                let bare = n
                    .strip_prefix(&format!("{}/", req.robot))
                    .unwrap_or(n.as_str());
                let v = robot.var(bare).ok_or_else(|| {
                    err(
                        format!("joint_names[{i}]"),
                        format!("robot '{}' has no movable joint '{n}'", req.robot),
                    )
                })?;
                if vars.contains(&v) {
                    return Err(err(
                        format!("joint_names[{i}]"),
                        format!("'{n}' given twice"),
                    ));
                }
                vars.push(v);
            }
            vars
        }
        (None, Some(g)) => robot
            .group(g)
            .map(|g| g.vars.clone())
            .filter(|v| !v.is_empty())
            .ok_or_else(|| {
                err(
                    "group",
                    format!("robot '{}' has no group '{g}' with joints", req.robot),
                )
            })?,
        (None, None) => (0..robot.dof()).collect(),
    };
    let names: Vec<String> = match &req.joint_names {
        Some(n) => n.clone(),
        None => vars
            .iter()
            .map(|&v| robot.var_name(v).to_string())
            .collect(),
    };
    let joints: Vec<PathJoint> = vars
        .iter()
        .map(|&var| PathJoint {
            robot: robot.clone(),
            var,
        })
        .collect();
    let limits = path_limits(
        &names,
        &joints,
        (req.max_velocity.as_ref(), req.max_acceleration.as_ref()),
        &opts,
    )?;
    time_named_path(&names, &req.waypoints, &limits, &opts, &[])
}
