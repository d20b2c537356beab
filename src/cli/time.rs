//! `manyhands time PLAN.json`: the time-optimal trajectory ([`manyhands::trajectory::timing`]) of
//! a planned path, printed as JSON (the `trajectory` of the plan answers and of
//! `POST /v1/trajectories`).
//!
//! Reads a plan as `--json plan …` prints it (`variables` + `waypoints`, with `events`), a
//! `joint_space` answer (`joints` + `path`), a job as `GET /v1/plans/{id}` answers it (its
//! `result`, its request's `scene`), or a bare `{robot, joint_names, waypoints}` (the
//! `POST /v1/trajectories` body, limits and scaling included). Names `robot/joint` are resolved
//! in the scene (`--scene`, or the job's) when given, else `robot` is taken as a model name.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde_json::Value;

use super::commands::Ctx;
use manyhands::model::Scene;
use manyhands::trajectory::timing::TimingOptions;
use manyhands::trajectory::{path_limits, time_named_path, time_request, PathJoint};
use manyhands::Robot;
use manyhands_api::{JointTrajectory, TrajectoryEvent, TrajectoryRequest};

#[derive(Args, Debug)]
pub struct TimeArgs {
    /// The plan (or path) JSON file, `-` for standard input.
    pub plan: PathBuf,
    /// Scene whose robot instances the `robot/joint` names refer to (default: the job's
    /// request's scene, else the names' robot part as a model name).
    #[arg(long)]
    pub scene: Option<String>,
    /// Seconds between points (0.001..=10).
    #[arg(long, default_value_t = manyhands::trajectory::timing::DEFAULT_SAMPLE_PERIOD)]
    pub sample_period: f64,
    /// Factor (0, 1] on the joints' velocity limits.
    #[arg(long, default_value_t = 1.0)]
    pub velocity_scaling: f64,
    /// Factor (0, 1] on the joints' acceleration limits.
    #[arg(long, default_value_t = 1.0)]
    pub acceleration_scaling: f64,
}

fn field_err(e: manyhands::trajectory::timing::TimingError) -> anyhow::Error {
    anyhow!("{}: {}", e.field, e.reason)
}

pub fn run(ctx: &Ctx, a: &TimeArgs) -> Result<()> {
    let text = if a.plan.as_os_str() == "-" {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut std::io::stdin(), &mut s)?;
        s
    } else {
        std::fs::read_to_string(&a.plan).with_context(|| format!("reading {}", a.plan.display()))?
    };
    let mut v: Value = serde_json::from_str(&text).context("not JSON")?;
    let mut scene_name = a.scene.clone();
    if v.get("result").is_some_and(Value::is_object) {
        if scene_name.is_none() {
            scene_name = v["request"]["scene"].as_str().map(str::to_string);
        }
        v = v["result"].take();
    }
    if v.get("robots").is_some_and(Value::is_array) && v.get("trajectories").is_some() {
        bail!("a multi-robot plan is timed by its schedule: see its `trajectories`");
    }
    let opts = TimingOptions::from_request(
        Some(a.sample_period),
        Some(a.velocity_scaling),
        Some(a.acceleration_scaling),
    )
    .map_err(field_err)?;
    let traj = if v.get("robot").is_some_and(Value::is_string) {
        // A POST /v1/trajectories body; the command line's timing options where it has none.
        let mut req: TrajectoryRequest = super::query::parse(&serde_json::to_string(&v)?)?;
        req.sample_period.get_or_insert(opts.sample_period);
        req.velocity_scaling.get_or_insert(opts.velocity_scaling);
        req.acceleration_scaling
            .get_or_insert(opts.acceleration_scaling);
        let robot = ctx.robot(&req.robot)?;
        time_request(&robot, &req).map_err(field_err)?
    } else {
        time_plan(ctx, &v, scene_name.as_deref(), &opts)?
    };
    println!("{}", serde_json::to_string_pretty(&traj)?);
    Ok(())
}

/// A plan answer's path (`variables`/`joints` + `waypoints`/`path`) timed, with its events.
fn time_plan(
    ctx: &Ctx,
    v: &Value,
    scene: Option<&str>,
    opts: &TimingOptions,
) -> Result<JointTrajectory> {
    let names: Vec<String> = ["joint_names", "variables", "joints"]
        .iter()
        .find_map(|k| v.get(*k))
        .ok_or_else(|| anyhow!("no joint_names, variables or joints"))
        .and_then(|n| Ok(serde_json::from_value(n.clone())?))?;
    let waypoints: Vec<Vec<f64>> = ["waypoints", "path"]
        .iter()
        .find_map(|k| v.get(*k))
        .ok_or_else(|| anyhow!("no waypoints or path"))
        .and_then(|w| Ok(serde_json::from_value(w.clone())?))?;
    let scene: Option<Scene> = scene.map(|s| ctx.scene(s)).transpose()?;
    let mut models: HashMap<String, Arc<Robot>> = HashMap::new();
    let mut joints = Vec::with_capacity(names.len());
    for (i, n) in names.iter().enumerate() {
        let Some((inst, joint)) = n.split_once('/') else {
            bail!("variables[{i}]: '{n}' is not robot/joint (give a bare path a `robot`)");
        };
        let robot = match models.get(inst) {
            Some(r) => r.clone(),
            None => {
                let r = match &scene {
                    Some(s) => s
                        .robots
                        .iter()
                        .find(|p| p.name == inst)
                        .map(|p| p.robot.clone())
                        .ok_or_else(|| {
                            anyhow!("variables[{i}]: the scene has no robot '{inst}'")
                        })?,
                    None => ctx.robot(inst)?,
                };
                models.insert(inst.to_string(), r.clone());
                r
            }
        };
        let var = robot
            .var(joint)
            .ok_or_else(|| anyhow!("variables[{i}]: robot '{inst}' has no joint '{joint}'"))?;
        joints.push(PathJoint { robot, var });
    }
    // Grasps and releases: at rest there, and carried with their time.
    let events: Vec<Value> = v
        .get("events")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    let rest: Vec<usize> = events
        .iter()
        .filter_map(|e| e["waypoint"].as_u64().map(|w| w as usize))
        .collect();
    let limits = path_limits(&names, &joints, (None, None), opts).map_err(field_err)?;
    let mut traj = time_named_path(&names, &waypoints, &limits, opts, &rest).map_err(field_err)?;
    for e in &events {
        let Some(w) = e["waypoint"].as_u64().map(|w| w as usize) else {
            continue;
        };
        let Some(t) = traj.waypoints.get(w).map(|p| p.time_from_start) else {
            bail!("events: waypoint {w} is not on the path");
        };
        let s = |k: &str| e[k].as_str().unwrap_or_default().to_string();
        traj.events.push(TrajectoryEvent {
            kind: s("kind"),
            time_from_start: t,
            waypoint: Some(w),
            robot: s("robot"),
            end_effector: s("end_effector"),
            object: s("object"),
            grasp: s("grasp"),
        });
    }
    Ok(traj)
}
