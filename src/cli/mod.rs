//! Command-line front end (clap). Thin: parses arguments, calls the library, prints text or JSON.

mod bench;
mod commands;
mod data;
mod exchange;
mod grasp;
mod load_http;
mod loadtest;
mod multi_arm;
mod multi_robot;
mod pick_place;
mod plan;
mod query;
mod reach;
mod roadmap;
mod serve;
mod time;

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "manyhands",
    version,
    about = "Multi-robot grasp-and-motion planning"
)]
pub struct Cli {
    /// Folder of robot models (NAME.urdf + NAME.srdf). Default: ./robots, else the shipped ones.
    #[arg(long, global = true, env = "MANYHANDS_ROBOTS")]
    pub robots: Option<PathBuf>,
    /// Folder of scenes (*.json). Default: ./scenes, else the shipped ones.
    #[arg(long, global = true, env = "MANYHANDS_SCENES")]
    pub scenes: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Inspect robot models.
    Robot {
        #[command(subcommand)]
        cmd: RobotCmd,
    },
    /// Forward kinematics: poses of links for a configuration.
    Fk(commands::FkArgs),
    /// Inverse kinematics of a group's chain for a TCP pose (analytic S-R-S or numeric).
    Ik(commands::IkArgs),
    /// Collision check of a scene at a configuration (which pair collides).
    Check(commands::CheckArgs),
    /// Scene tools.
    Scene {
        #[command(subcommand)]
        cmd: SceneCmd,
    },
    /// Grasp quality: force closure and Ferrari–Canny ε of scene grasps or given contacts.
    Grasp {
        #[command(subcommand)]
        cmd: grasp::GraspCmd,
    },
    /// Reachability grids: build (with progress bar), info, SVG slice plot.
    Reach {
        #[command(subcommand)]
        cmd: reach::ReachCmd,
    },
    /// Roadmaps (003 §V-A): `roadmap build` composes the super graph of a scene's humanoid
    /// (Visibility-PRM of torso + each arm) offline and keeps it in a file.
    Roadmap {
        #[command(subcommand)]
        cmd: RoadmapCmd,
    },
    /// Grasp planning on a scene: reach (IK-RRT), regrasp / hand-off, the kitchen task, bimanual.
    Plan {
        #[command(subcommand)]
        cmd: plan::PlanCmd,
    },
    /// Phase-space scheduling (002 §V) of given trajectories, one per robot of a scene: the
    /// `schedule` job's JSON body in (text, `@FILE` or `-`), its answer out.
    Schedule(multi_robot::ScheduleArgs),
    /// Time-optimal trajectory (TOPP-RA on the polyline, within the joints' velocity and
    /// acceleration limits) of a plan JSON as `--json plan …` prints it, or of a bare
    /// `{robot, joint_names, waypoints}`; prints the trajectory JSON.
    Time(time::TimeArgs),
    /// Grasp IK queries run locally with the HTTP endpoints' JSON bodies: ik-grasp, ik-dual-arm,
    /// ik-base-placement.
    Query(query::QueryArgs),
    /// Benchmarks (medians over many seeded runs).
    Bench {
        #[command(subcommand)]
        cmd: bench::BenchCmd,
    },
    /// Outside data sets: `data mbm` fetches the MotionBenchMaker problem sets into the cache.
    Data {
        #[command(subcommand)]
        cmd: data::DataCmd,
    },
    /// The HTTP/JSON planning server (REST API, async jobs, SSE, Prometheus metrics).
    Serve(serve::ServeArgs),
    /// Drives a running server on 127.0.0.1 with concurrent IK queries and planning jobs.
    Loadtest(loadtest::LoadtestArgs),
}

#[derive(Subcommand, Debug)]
pub enum RobotCmd {
    /// List the robot models found.
    List,
    /// DoF, joints with limits, groups, end effectors, links and collision shapes.
    Show {
        /// Model name (from the robots folder) or a path to a .urdf file.
        robot: String,
    },
    /// What loading tolerated: link pairs colliding in (nearly) every configuration that the
    /// SRDF does not disable (each with the SRDF line that would), continuous joints written as
    /// revolute ±π, other warnings.
    Check {
        /// Model name (from the robots folder) or a path to a .urdf file.
        robot: String,
        /// The SRDF of a .urdf path (default: the .srdf beside it with the same stem).
        #[arg(long)]
        srdf: Option<std::path::PathBuf>,
    },
    /// A conservative sphere model of the robot (`model::spherize`: spheres containing every
    /// collision primitive), written as DIR/NAME_spherized.urdf and .srdf, for the SIMD sphere
    /// checker; prints spheres and protrusion per link.
    Spherize(commands::SpherizeArgs),
}

#[derive(Subcommand, Debug)]
pub enum RoadmapCmd {
    /// Builds (or loads, when a file with the same robot, scene and parameter keys exists) the
    /// super graph of a scene's robot and prints its sizes and build times.
    Build(roadmap::BuildArgs),
}

#[derive(Subcommand, Debug)]
pub enum SceneCmd {
    /// List the scenes found.
    List,
    /// Writes a scene with N random boxes that touch no robot at its start configuration.
    RandomBoxes(commands::RandomBoxesArgs),
    /// The `panda_four` cell (four MotionBenchMaker Pandas around a table, issue 23): prints the
    /// scene, or with `--out DIR` writes DIR/robots/panda.{urdf,srdf} (from the fetched data,
    /// `manyhands data mbm`) and DIR/scenes/panda_four.json, ready for `--robots`/`--scenes`.
    PandaFour(commands::PandaFourArgs),
    /// A public VAMP-MR multi-arm cell (`panda_two_rod`, `panda_four`, `panda_four_bins`) over
    /// the fetched MotionBenchMaker Panda (`manyhands data mbm`): prints the scene, or with
    /// `--out DIR` writes DIR/robots/MODEL.{urdf,srdf} and DIR/scenes/vamp_mr_NAME.json.
    VampMr(commands::VampMrArgs),
}

pub fn run() -> Result<()> {
    let cli = Cli::parse();
    let ctx = commands::Ctx::new(&cli);
    match &cli.command {
        Command::Robot {
            cmd: RobotCmd::List,
        } => commands::robot_list(&ctx),
        Command::Robot {
            cmd: RobotCmd::Show { robot },
        } => commands::robot_show(&ctx, robot),
        Command::Robot {
            cmd: RobotCmd::Check { robot, srdf },
        } => commands::robot_check(&ctx, robot, srdf.as_deref()),
        Command::Robot {
            cmd: RobotCmd::Spherize(a),
        } => commands::robot_spherize(&ctx, a),
        Command::Fk(a) => commands::fk(&ctx, a),
        Command::Ik(a) => commands::ik(&ctx, a),
        Command::Check(a) => commands::check(&ctx, a),
        Command::Scene {
            cmd: SceneCmd::List,
        } => commands::scene_list(&ctx),
        Command::Scene {
            cmd: SceneCmd::RandomBoxes(a),
        } => commands::random_boxes(&ctx, a),
        Command::Scene {
            cmd: SceneCmd::PandaFour(a),
        } => commands::panda_four(a),
        Command::Scene {
            cmd: SceneCmd::VampMr(a),
        } => commands::vamp_mr(a),
        Command::Grasp { cmd } => grasp::run(&ctx, cmd),
        Command::Reach { cmd } => reach::run(&ctx, cmd),
        Command::Roadmap {
            cmd: RoadmapCmd::Build(a),
        } => roadmap::build(&ctx, a),
        Command::Serve(a) => serve::run(&ctx, a),
        Command::Loadtest(a) => loadtest::run(&ctx, a),
        Command::Bench { cmd } => bench::run(&ctx, cmd),
        Command::Plan { cmd } => plan::run(&ctx, cmd),
        Command::Query(a) => query::run(&ctx, a),
        Command::Schedule(a) => multi_robot::schedule(&ctx, a),
        Command::Time(a) => time::run(&ctx, a),
        Command::Data { cmd } => data::run(&ctx, cmd),
    }
}
