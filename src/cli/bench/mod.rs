//! `manyhands bench …`: medians over many seeded runs, printed beside the targets.

mod collision_multi;
mod grasp_list;
mod ik;
mod mbm;
mod mbm_suite;
mod multi_arm;
mod planners;
mod timing;

use std::time::Instant;

use anyhow::{anyhow, Result};
use clap::Subcommand;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use manyhands::collision::{
    random_boxes, random_config_near, CollisionChecker, CollisionWorld, ExactChecker, FastChecker,
    RandomBoxes,
};
use manyhands::geometry::Pose;
use manyhands::kinematics::numeric::NumericIk;
use manyhands::kinematics::srs::SrsArm;
use manyhands::kinematics::{forward, Chain, FkModel, Frame};
use manyhands::{Robot, Scene};

use super::commands::Ctx;

#[derive(Subcommand, Debug)]
pub enum BenchCmd {
    /// Fast and exact collision checks of `armar` in `kitchen` and among 30 random boxes, plus FK and IK.
    Collision {
        /// Random configurations per measurement.
        #[arg(long, default_value_t = 20_000)]
        samples: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Instead: single-state and motion checks of several arms at once in the VAMP-MR
        /// cells (two Pandas with rods, four Pandas, four Pandas with bins; needs the
        /// MotionBenchMaker data, `manyhands data mbm`), beside VAMP-MR's published figures.
        #[arg(long)]
        multi_arm: bool,
    },
    /// FK and IK (analytic S-R-S, numeric DLS) only.
    Kinematics {
        #[arg(long, default_value_t = 20_000)]
        samples: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Randomized IK (paper 000 Tables 1 and 2): 10-DoF hip + arm and dual-arm IK on the wok,
    /// with/without reachability, without/with obstacle.
    Ik(ik::IkBenchArgs),
    /// Grasp planners (paper 000 Tables 3–5, 002 Bimanual IK-RRT): N seeded runs per row,
    /// without and with the obstacle, the paper's figure beside ours.
    Planners(planners::PlannersBenchArgs),
    /// MotionBenchMaker problem sets (Panda, Baxter) with RRT-Connect, paths verified exactly.
    Mbm(mbm::MbmArgs),
    /// Multi-Robot-RRT (002 Tables I and II): two robots in `kitchen_two`, three robots in
    /// `boxes_three` with 30 random boxes per seed; N seeded runs each, the paper's row beside.
    MultiRobot(super::multi_robot::BenchArgs),
    /// The multi-arm planner on seeded crossing tasks in VAMP-MR's cells (needs the
    /// MotionBenchMaker data): success, median time, method, makespan before/after shortcutting,
    /// beside decoupled-only and composite-only.
    MultiArm(multi_arm::MultiArmBenchArgs),
    /// Trajectory timing (TOPP-RA on the polyline): the kitchen task's path and 100-waypoint
    /// Panda-like paths, median µs per parameterisation.
    Timing(timing::TimingBenchArgs),
    /// Single-grasp lists (paper 003 §IV-A): one list per hand from scratch, median seconds
    /// over seeded builds beside the ≤ 1 s target [paper: about 1 min].
    GraspList(Box<grasp_list::GraspListBenchArgs>),
    /// The configuration phase of a two-hand pick-and-place (003 §IV-B double grasps + §V-C
    /// exchange position and grasp/exchange/place configurations), median ms over seeded runs
    /// beside the ≤ 50 ms target [paper: 4.2 s + 2.6 s].
    Exchange(Box<super::exchange::ExchangeBenchArgs>),
    /// The super graph (003 §V-A/B): offline build time beside the ≤ 10 s target, then seeded
    /// queries with the scene's object resting and carried (connection, search, lazy
    /// revalidation, RRT repair and shortcut times).
    Roadmap(Box<super::roadmap::BenchArgs>),
    /// The whole two-hand pick-and-place task (003 Table I's shape): per query nodes, planning
    /// and validation time over seeded runs, the single-query baseline (RRT-Connect) beside
    /// it, and the offline costs; targets ≤ 100 ms online, ≤ 50 ms configurations.
    PickPlace(Box<super::pick_place::PickPlaceBenchArgs>),
}

pub fn run(ctx: &Ctx, cmd: &BenchCmd) -> Result<()> {
    match cmd {
        BenchCmd::Collision {
            samples,
            seed,
            multi_arm: true,
        } => {
            let rows = collision_multi::rows(*samples, *seed)?;
            print_rows(ctx, &rows);
        }
        BenchCmd::Collision {
            samples,
            seed,
            multi_arm: false,
        } => {
            let mut rows = collision_rows(ctx, *samples, *seed)?;
            rows.extend(kinematics_rows(ctx, *samples, *seed)?);
            print_rows(ctx, &rows);
        }
        BenchCmd::Kinematics { samples, seed } => {
            let rows = kinematics_rows(ctx, *samples, *seed)?;
            print_rows(ctx, &rows);
        }
        BenchCmd::Mbm(a) => mbm::run(ctx, a)?,
        BenchCmd::MultiRobot(a) => super::multi_robot::bench(ctx, a)?,
        BenchCmd::MultiArm(a) => multi_arm::run(ctx, a)?,
        BenchCmd::Ik(a) => ik::run(ctx, a)?,
        BenchCmd::Planners(a) => planners::run(ctx, a)?,
        BenchCmd::Timing(a) => timing::run(ctx, a)?,
        BenchCmd::GraspList(a) => grasp_list::run(ctx, a)?,
        BenchCmd::Exchange(a) => super::exchange::bench(ctx, a)?,
        BenchCmd::Roadmap(a) => super::roadmap::bench(ctx, a)?,
        BenchCmd::PickPlace(a) => super::pick_place::bench(ctx, a)?,
    }
    Ok(())
}

pub(super) struct Row {
    pub(super) what: String,
    pub(super) median_ns: f64,
    pub(super) mean_ns: f64,
    pub(super) n: usize,
    pub(super) note: String,
    pub(super) target: &'static str,
}

fn print_rows(ctx: &Ctx, rows: &[Row]) {
    if ctx.json {
        let v: Vec<_> = rows.iter().map(|r| json!({"what": r.what, "median_ns": r.median_ns, "mean_ns": r.mean_ns, "n": r.n, "note": r.note, "target": r.target})).collect();
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return;
    }
    println!(
        "{:<46} {:>12} {:>12} {:>8}  {:<14} note",
        "measurement", "median", "mean", "n", "target"
    );
    for r in rows {
        println!(
            "{:<46} {:>12} {:>12} {:>8}  {:<14} {}",
            r.what,
            fmt_ns(r.median_ns),
            fmt_ns(r.mean_ns),
            r.n,
            r.target,
            r.note
        );
    }
}

fn fmt_ns(ns: f64) -> String {
    if ns < 10_000.0 {
        format!("{ns:.0} ns")
    } else {
        format!("{:.1} µs", ns / 1000.0)
    }
}

/// Times `f` once per input and returns (median, mean) in ns, with the clock's own cost (the
/// median of timing an empty call) subtracted.
pub(super) fn time_each<T>(inputs: &[T], mut f: impl FnMut(&T)) -> (f64, f64) {
    // Warm-up.
    for x in inputs.iter().take(100) {
        f(x);
    }
    let mut overhead: Vec<f64> = (0..1000)
        .map(|_| {
            let s = Instant::now();
            std::hint::black_box(());
            s.elapsed().as_nanos() as f64
        })
        .collect();
    overhead.sort_by(|a, b| a.total_cmp(b));
    let clock = overhead[overhead.len() / 2];
    let mut t: Vec<f64> = Vec::with_capacity(inputs.len());
    for x in inputs {
        let s = Instant::now();
        f(x);
        t.push((s.elapsed().as_nanos() as f64 - clock).max(0.0));
    }
    let mean = t.iter().sum::<f64>() / t.len().max(1) as f64;
    t.sort_by(|a, b| a.total_cmp(b));
    (t.get(t.len() / 2).copied().unwrap_or(0.0), mean)
}

/// Random world configurations: every robot near its start pose on the floor (base joints
/// ±0.3 m, ±0.5 rad around the start), all other joints uniform within their limits.
fn random_configs(scene: &Scene, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let world = CollisionWorld::from_scene(scene);
    let start = CollisionWorld::start_config(scene);
    (0..n)
        .map(|_| random_config_near(&world, &start, 0.3, 0.5, rng))
        .collect()
}

fn collision_rows(ctx: &Ctx, samples: usize, seed: u64) -> Result<Vec<Row>> {
    let lib = ctx.library()?;
    let kitchen = ctx.scene("kitchen")?;
    let empty = ctx.scene("empty")?;
    let boxes = random_boxes(
        &empty,
        &RandomBoxes {
            count: 30,
            seed,
            ..RandomBoxes::default()
        },
        &lib,
    )?;
    let mut rows = Vec::new();
    for (label, scene) in [("kitchen", &kitchen), ("30 random boxes", &boxes)] {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let world = CollisionWorld::from_scene(scene);
        let configs = random_configs(scene, samples, &mut rng);
        let mut fast = FastChecker::new(&world);
        let mut exact = ExactChecker::new(&world);
        let mut fast_hits = 0usize;
        let (fm, fmean) = time_each(&configs, |q| {
            if !fast.is_free(q) {
                fast_hits += 1;
            }
        });
        let free: Vec<Vec<f64>> = configs
            .iter()
            .filter(|q| fast.is_free(q))
            .cloned()
            .collect();
        let (ffm, ffmean) = time_each(&free, |q| {
            std::hint::black_box(fast.is_free(q));
        });
        let n_exact = (samples / 5).max(100).min(configs.len());
        let mut exact_hits = 0usize;
        let (em, emean) = time_each(&configs[..n_exact], |q| {
            if !exact.is_free(q) {
                exact_hits += 1;
            }
        });
        let dof = world.dof();
        rows.push(Row {
            what: format!("fast check, armar ({dof} DoF) in {label}"),
            median_ns: fm,
            mean_ns: fmean,
            n: configs.len(),
            note: format!(
                "{:.0} % in collision (incl. warm-up), {} body pairs",
                100.0 * fast_hits as f64 / (configs.len() + 100) as f64,
                fast.pair_count()
            ),
            target: "≤ 2 µs",
        });
        rows.push(Row {
            what: format!("fast check, free configurations only, {label}"),
            median_ns: ffm,
            mean_ns: ffmean,
            n: free.len(),
            note: "no early exit: every pair tested".into(),
            target: "≤ 2 µs",
        });
        rows.push(Row {
            what: format!("exact check (parry), armar in {label}"),
            median_ns: em,
            mean_ns: emean,
            n: n_exact,
            note: format!(
                "{:.0} % in collision",
                100.0 * exact_hits as f64 / (n_exact + 100) as f64
            ),
            target: "reference",
        });
    }
    Ok(rows)
}

fn kinematics_rows(ctx: &Ctx, samples: usize, seed: u64) -> Result<Vec<Row>> {
    let armar = ctx.robot("armar")?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let configs: Vec<Vec<f64>> = (0..samples).map(|_| uniform(&armar, &mut rng)).collect();
    let mut rows = Vec::new();
    let mut poses = vec![Pose::identity(); armar.links.len()];
    let (m, mean) = time_each(&configs, |q| {
        forward(&armar, &Pose::identity(), q, &mut poses);
        std::hint::black_box(&poses);
    });
    rows.push(Row {
        what: format!("FK as isometries, all {} links of armar", armar.links.len()),
        median_ns: m,
        mean_ns: mean,
        n: samples,
        note: "kinematics::forward".into(),
        target: "≤ 1 µs",
    });
    let model = FkModel::new(&armar);
    let mut frames = vec![Frame::identity(); armar.links.len()];
    let (m, mean) = time_each(&configs, |q| {
        model.compute(&Frame::identity(), q, &mut frames);
        std::hint::black_box(&frames);
    });
    rows.push(Row {
        what: format!("FK as frames, all {} links of armar", armar.links.len()),
        median_ns: m,
        mean_ns: mean,
        n: samples,
        note: "kinematics::FkModel (collision hot path)".into(),
        target: "≤ 1 µs",
    });

    let chain = Chain::from_group(&armar, "right_arm")
        .ok_or_else(|| anyhow!("armar has no right_arm chain"))?;
    let arm = SrsArm::new(&armar, &chain)?;
    let targets: Vec<(Pose, f64)> = configs
        .iter()
        .map(|q| {
            let mut q7 = [0.0; 7];
            for (i, &v) in arm.vars().iter().enumerate() {
                q7[i] = q[v];
            }
            (chain.tip_pose(&armar, q), arm.arm_angle(&q7))
        })
        .collect();
    let mut out = [[0.0; 7]; 8];
    let mut found = 0usize;
    let (m, mean) = time_each(&targets, |(t, psi)| {
        found += arm.solve(t, *psi, &mut out);
    });
    rows.push(Row {
        what: "analytic S-R-S IK, armar right arm (one ψ)".into(),
        median_ns: m,
        mean_ns: mean,
        n: samples,
        note: format!(
            "{:.2} solutions per call within limits",
            found as f64 / (samples + 100) as f64
        ),
        target: "≤ 5 µs",
    });

    let mut ik = NumericIk::new(&armar, &chain);
    let n_num = (samples / 20).clamp(50, 2000);
    let seed_q = armar
        .named_config("home")
        .unwrap_or_else(|| armar.zero_config());
    let mut ok = 0usize;
    let (m, mean) = time_each(&targets[..n_num], |(t, _)| {
        if ik.solve(t, &seed_q, &mut rng).is_ok() {
            ok += 1;
        }
    });
    rows.push(Row {
        what: "numeric DLS IK, armar right arm".into(),
        median_ns: m,
        mean_ns: mean,
        n: n_num,
        note: format!(
            "{:.0} % solved",
            100.0 * ok as f64 / (n_num + n_num.min(100)) as f64
        ),
        target: "—",
    });
    Ok(rows)
}

fn uniform(r: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut q = r.zero_config();
    let all: Vec<usize> = (0..r.dof()).collect();
    r.sample_vars(&all, &mut q, rng);
    q
}
