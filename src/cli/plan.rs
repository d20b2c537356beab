//! `manyhands plan …`: the grasp planners of papers 000 and 002 on a scene, from its start
//! configuration. Prints a summary (or, with `--json`, the whole plan: variables, waypoints,
//! phases with statistics, grasp/release events).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{anyhow, bail, Result};
use clap::{Args, Subcommand};

use super::commands::Ctx;
use manyhands::collision::CollisionWorld;
use manyhands::kinematics::randomized::RandomizedIkSettings;
use manyhands::model::Scene;
use manyhands::planning::planners::bimanual_ik_rrt::{BimanualProblem, BimanualSettings};
use manyhands::planning::problems::grasping::arm_grid;
use manyhands::planning::tasks::task::{
    bimanual_task, kitchen_task, precheck_reach, reach_task, regrasp_task, GraspAlgorithm,
    KitchenTask, RegraspTask, TaskPlan,
};
use manyhands::planning::{IkRrtSettings, Termination};
use manyhands::reachability::{GridCache, GridRecipe};
use manyhands::trajectory::timing::TimingOptions;

/// Settings every planning command shares.
#[derive(Args, Debug, Clone)]
pub struct Common {
    /// Random seed (same seed → same plan).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Time limit of the whole query (s).
    #[arg(long, default_value_t = 10.0)]
    pub time_limit: f64,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2 p_IK). Default: 0.1,
    /// bimanual 0.03 (002 §VI).
    #[arg(long)]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query.
    #[arg(long, default_value_t = 50)]
    pub ik_tries: u64,
    /// Skip path pruning (shortcutting).
    #[arg(long)]
    pub no_prune: bool,
    /// Seconds between the points of the answer's timed `trajectory` (0.001..=10).
    #[arg(long, default_value_t = manyhands::trajectory::timing::DEFAULT_SAMPLE_PERIOD)]
    pub trajectory_period: f64,
    /// Factor (0, 1] on the joints' velocity limits for the trajectory.
    #[arg(long, default_value_t = 1.0)]
    pub velocity_scaling: f64,
    /// Factor (0, 1] on the joints' acceleration limits for the trajectory.
    #[arg(long, default_value_t = 1.0)]
    pub acceleration_scaling: f64,
}

/// The trajectory timing options of the common settings, checked.
pub(super) fn timing(c: &Common) -> Result<TimingOptions> {
    TimingOptions::from_request(
        Some(c.trajectory_period),
        Some(c.velocity_scaling),
        Some(c.acceleration_scaling),
    )
    .map_err(|e| anyhow!("--{}: {}", e.field.replace('_', "-"), e.reason))
}

/// The arm grids that filter IK-RRT's randomized IK (000 §II-D, §III-B).
#[derive(Args, Debug)]
pub struct ArmGridArgs {
    /// Folder caching the arm reachability grids (built on first use).
    #[arg(long, default_value = "data/reach")]
    pub grid_dir: PathBuf,
    /// Run the randomized IK unfiltered (no arm grid).
    #[arg(long)]
    pub no_reachability: bool,
}

impl ArmGridArgs {
    /// The grid of `robot`'s arm `group`, unless switched off.
    fn grid(
        &self,
        s: &Scene,
        robot: &str,
        group: &str,
    ) -> Result<Option<Arc<manyhands::reachability::ReachabilityGrid>>> {
        if self.no_reachability {
            return Ok(None);
        }
        let cache = GridCache::new(Some(self.grid_dir.clone()));
        Ok(arm_grid(
            &cache,
            &CollisionWorld::from_scene(s),
            robot,
            group,
        )?)
    }
}

#[derive(Subcommand, Debug)]
pub enum PlanCmd {
    /// Grasp an object with one hand (IK-RRT, 000 Alg. 3, or J+-RRT, Alg. 1–2).
    Reach {
        #[arg(long, default_value = "kitchen")]
        scene: String,
        #[arg(long, default_value = "armar")]
        robot: String,
        /// Chain group from the free joints to the hand.
        #[arg(long, default_value = "torso_right_arm")]
        group: String,
        #[arg(long, default_value = "wok")]
        object: String,
        /// ik-rrt or j-plus-rrt.
        #[arg(long, default_value = "ik-rrt", value_parser = parse_algorithm)]
        planner: GraspAlgorithm,
        #[command(flatten)]
        grids: ArmGridArgs,
        #[command(flatten)]
        common: Common,
    },
    /// Dual-arm re-grasp (000 §V) or hand-off between two robots (000 §VI-D): the object goes
    /// from the giver's hand to the receiver's (grasped first when it rests).
    Regrasp {
        #[arg(long, default_value = "kitchen")]
        scene: String,
        /// Giver as ROBOT:GROUP.
        #[arg(long, default_value = "armar:torso_right_arm")]
        giver: String,
        /// Receiver as ROBOT:GROUP.
        #[arg(long, default_value = "armar:torso_left_arm")]
        receiver: String,
        #[arg(long, default_value = "wok")]
        object: String,
        /// Giver grasp that holds the object at the start (it is put into the hand).
        #[arg(long)]
        held: Option<String>,
        /// ik-rrt (dual-arm IK-RRT) or j-plus-rrt (dual-arm J+-RRT).
        #[arg(long, default_value = "ik-rrt", value_parser = parse_algorithm)]
        planner: GraspAlgorithm,
        #[command(flatten)]
        grids: ArmGridArgs,
        #[command(flatten)]
        common: Common,
    },
    /// The kitchen task (000 §VI-C): grasp the wok with the right hand, re-grasp to the left,
    /// move the right arm away, place the wok in the cabinet.
    Kitchen {
        #[arg(long, default_value = "kitchen")]
        scene: String,
        #[command(flatten)]
        grids: ArmGridArgs,
        #[command(flatten)]
        common: Common,
    },
    /// Bimanual IK-RRT (002 Alg. 2): platform + hip + both arms (20 DoF for ARMAR) to a two-hand
    /// grasp, goals from IkDualArm with base placement.
    /// Multi-Robot-RRT (002 Alg. 3): one Bimanual IK-RRT worker per robot, a collector scoring
    /// grasp wrench spaces and rejecting deadlocks, then phase-space scheduling (002 §V).
    MultiRobot(MultiRobotArgs),
    /// The exchange position and the grasp, exchange and place configurations of a two-hand
    /// pick-and-place (003 §V-C) for a scene object and its goal pose.
    Exchange(Box<super::exchange::ExchangeArgs>),
    /// The whole two-hand pick-and-place task (003 Fig. 2, §V-B): key configurations, the four
    /// super-graph queries with lazy revalidation, one certified plan with grasp and release
    /// events.
    PickPlace(Box<super::pick_place::PickPlaceArgs>),
    /// N independent arms of a scene in one timed plan (job kind `multi_arm`): decoupled
    /// scheduling, prioritized planning in space-time or composite RRT-Connect, chosen
    /// automatically, then makespan-aware shortcutting.
    MultiArm(super::multi_arm::MultiArmArgs),
    Bimanual {
        #[arg(long, default_value = "kitchen")]
        scene: String,
        #[arg(long, default_value = "armar")]
        robot: String,
        #[arg(long, default_value = "torso_left_arm")]
        left: String,
        #[arg(long, default_value = "torso_right_arm")]
        right: String,
        #[arg(long, default_value = "table")]
        object: String,
        /// Folder caching the platform-frame reachability grids (built on first use).
        #[arg(long, default_value = "data/reach")]
        grid_dir: PathBuf,
        /// FK samples per grid when one is built.
        #[arg(long, default_value_t = 400_000)]
        grid_samples: u64,
        #[command(flatten)]
        common: Common,
    },
}

/// Multi-Robot-RRT arguments (002 Alg. 3 + §V).
#[derive(Args, Debug)]
pub struct MultiRobotArgs {
    #[arg(long, default_value = "kitchen_two")]
    pub scene: String,
    /// Robot instances, comma-separated (default: every robot of the scene).
    #[arg(long = "robot", value_delimiter = ',')]
    pub robot_names: Vec<String>,
    #[arg(long, default_value = "torso_left_arm")]
    pub left: String,
    #[arg(long, default_value = "torso_right_arm")]
    pub right: String,
    #[arg(long, default_value = "table")]
    pub object: String,
    /// Minimum grasp score s_min (ε of all contacts' wrench space must exceed it).
    #[arg(long, default_value_t = 0.0)]
    pub s_min: f64,
    /// Friction coefficient μ of the score.
    #[arg(long, default_value_t = 0.5)]
    pub mu: f64,
    /// Friction cone edges of the score.
    #[arg(long, default_value_t = 8)]
    pub cone_edges: usize,
    /// Torque scale λ of the score (default 1 / the object's radius).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Workers stepped round-robin on one thread: same seed, same plan.
    #[arg(long)]
    pub deterministic: bool,
    /// Most solutions per worker.
    #[arg(long, default_value_t = 32)]
    pub max_solutions: usize,
    /// Write the phase space (002 Fig. 9) as SVG.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Also sample the schedule every that many seconds.
    #[arg(long)]
    pub sample_period: Option<f64>,
    #[arg(long, default_value = "data/reach")]
    pub grid_dir: PathBuf,
    #[arg(long, default_value_t = 400_000)]
    pub grid_samples: u64,
    #[command(flatten)]
    pub common: Common,
}

fn parse_algorithm(s: &str) -> Result<GraspAlgorithm, String> {
    GraspAlgorithm::parse(s).ok_or_else(|| format!("'{s}': expected ik-rrt or j-plus-rrt"))
}

fn split_hand(s: &str, what: &str) -> Result<(String, String)> {
    let (r, g) = s
        .split_once(':')
        .ok_or_else(|| anyhow!("{what}: expected ROBOT:GROUP, got '{s}'"))?;
    Ok((r.to_string(), g.to_string()))
}

pub(super) fn settings(
    c: &Common,
    default_p_ik: f64,
) -> Result<(IkRrtSettings, RandomizedIkSettings)> {
    let p_ik = c.p_ik.unwrap_or(default_p_ik);
    if !(0.0..=1.0).contains(&p_ik) {
        bail!("p_ik: {p_ik} must be within [0, 1]");
    }
    if !(1..=1_000_000).contains(&c.ik_tries) {
        bail!("ik_tries: {} must be within [1, 1000000]", c.ik_tries);
    }
    let mut planner = IkRrtSettings {
        p_ik,
        ..IkRrtSettings::default()
    };
    if c.no_prune {
        planner.rrt.shortcut = None;
    }
    let ik = RandomizedIkSettings {
        max_tries: c.ik_tries,
        ..RandomizedIkSettings::default()
    };
    Ok((planner, ik))
}

pub(super) fn termination(c: &Common) -> Result<Termination> {
    if !(c.time_limit.is_finite() && c.time_limit > 0.0 && c.time_limit <= 3600.0) {
        bail!("time_limit: {} s must be within (0, 3600]", c.time_limit);
    }
    Ok(Termination::new().with_time_limit(Duration::from_secs_f64(c.time_limit)))
}

pub fn run(ctx: &Ctx, cmd: &PlanCmd) -> Result<()> {
    let opts = match cmd {
        PlanCmd::MultiRobot(_)
        | PlanCmd::Exchange(_)
        | PlanCmd::PickPlace(_)
        | PlanCmd::MultiArm(_) => TimingOptions::default(),
        PlanCmd::Reach { common, .. }
        | PlanCmd::Regrasp { common, .. }
        | PlanCmd::Kitchen { common, .. }
        | PlanCmd::Bimanual { common, .. } => timing(common)?,
    };
    let (scene, plan, extra): (Scene, TaskPlan, String) = match cmd {
        PlanCmd::MultiRobot(a) => return super::multi_robot::plan(ctx, a),
        PlanCmd::Exchange(a) => return super::exchange::plan(ctx, a),
        PlanCmd::PickPlace(a) => return super::pick_place::plan(ctx, a),
        PlanCmd::MultiArm(a) => return super::multi_arm::plan(ctx, a),
        PlanCmd::Reach {
            scene,
            robot,
            group,
            object,
            planner: algorithm,
            grids,
            common,
        } => {
            let s = ctx.scene(scene)?;
            let (planner, ik) = settings(common, 0.1)?;
            // An object out of reach fails here, before a grid is built.
            precheck_reach(&s, robot, group, object)?;
            let grid = match algorithm {
                GraspAlgorithm::IkRrt => grids.grid(&s, robot, group)?,
                GraspAlgorithm::JPlusRrt => None,
            };
            let mut term = termination(common)?;
            let plan = reach_task(
                &s,
                robot,
                group,
                object,
                grid,
                *algorithm,
                planner,
                ik,
                &mut term,
                common.seed,
            )?;
            (s, plan, String::new())
        }
        PlanCmd::Regrasp {
            scene,
            giver,
            receiver,
            object,
            held,
            planner: algorithm,
            grids,
            common,
        } => {
            let s = ctx.scene(scene)?;
            let (planner, ik) = settings(common, 0.1)?;
            let receiver = split_hand(receiver, "receiver")?;
            let grid = match algorithm {
                GraspAlgorithm::IkRrt => grids.grid(&s, &receiver.0, &receiver.1)?,
                GraspAlgorithm::JPlusRrt => None,
            };
            let task = RegraspTask {
                giver: split_hand(giver, "giver")?,
                receiver,
                object: object.clone(),
                held: held.clone(),
                grid,
                algorithm: *algorithm,
                planner,
                ik,
            };
            let mut term = termination(common)?;
            let plan = regrasp_task(&s, &task, &mut term, common.seed)?;
            (s, plan, String::new())
        }
        PlanCmd::Kitchen {
            scene,
            grids,
            common,
        } => {
            let s = ctx.scene(scene)?;
            let (planner, ik) = settings(common, 0.1)?;
            let base = KitchenTask::armar_wok();
            let task = KitchenTask {
                planner,
                ik,
                grids: (
                    grids.grid(&s, &base.robot, &base.first)?,
                    grids.grid(&s, &base.robot, &base.second)?,
                ),
                ..base
            };
            let mut term = termination(common)?;
            let plan = kitchen_task(&s, &task, &mut term, common.seed)?;
            (s, plan, String::new())
        }
        PlanCmd::Bimanual {
            scene,
            robot,
            left,
            right,
            object,
            grid_dir,
            grid_samples,
            common,
        } => {
            let s = ctx.scene(scene)?;
            let (planner, ik) = settings(common, 0.03)?;
            let model = s
                .robots
                .iter()
                .find(|r| &r.name == robot)
                .ok_or_else(|| anyhow!("robot: the scene has no robot '{robot}'"))?
                .robot
                .clone();
            let cache = GridCache::new(Some(grid_dir.clone()));
            let recipe = GridRecipe {
                samples: *grid_samples,
                ..GridRecipe::default()
            };
            let t = std::time::Instant::now();
            let gl: Arc<_> = cache.get(&model, left, recipe)?;
            let gr: Arc<_> = cache.get(&model, right, recipe)?;
            let grids_s = t.elapsed().as_secs_f64();
            let world = CollisionWorld::from_scene(&s);
            let q0 = CollisionWorld::start_config(&s);
            let p = BimanualProblem::new(
                &s,
                &world,
                &q0,
                robot,
                (left, right),
                object,
                (&gl, &gr),
                BimanualSettings::default(),
            )?;
            let mut term = termination(common)?;
            let plan = bimanual_task(&p, planner, ik, &mut term, common.seed)?;
            let extra = format!(
                "grids {:.2} s (cached in {}), inverse maps + R_bi {:.1} ms\n",
                grids_s,
                grid_dir.display(),
                p.map_time.as_secs_f64() * 1e3
            );
            (s, plan, extra)
        }
    };
    let json = plan.to_json(&CollisionWorld::from_scene(&scene), &opts)?;
    ctx.print(&json, || summary(&plan, &extra));
    Ok(())
}

fn summary(plan: &TaskPlan, extra: &str) -> String {
    let mut s = String::from(extra);
    s += &format!(
        "plan: {} waypoints, {:.2} ms in all ({:.2} ms IK)\n",
        plan.waypoints.len(),
        plan.time.as_secs_f64() * 1e3,
        plan.ik_time().as_secs_f64() * 1e3
    );
    for p in &plan.phases {
        s += &format!(
            "  {:<8} {:<16} {:>8.2} ms + {:>6.2} ms pruning, {:>6} iterations, {:>3} IK solutions, {:>7} collision checks, length {:.3} → {:.3}, waypoints {}..{}\n",
            p.name,
            p.planner,
            p.stats.time.as_secs_f64() * 1e3,
            p.stats.simplify_time.as_secs_f64() * 1e3,
            p.stats.iterations,
            p.stats.ik_solutions,
            p.stats.collision_checks,
            p.stats.length_raw,
            p.stats.length_simplified,
            p.first,
            p.last
        );
    }
    for e in &plan.events {
        s += &format!(
            "  at {:>3}: {:?} {} {} {} ({})\n",
            e.waypoint, e.kind, e.robot, e.end_effector, e.object, e.grasp
        );
    }
    s.trim_end().to_string()
}
