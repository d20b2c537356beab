//! `manyhands bench ik`: the shape of paper 000 Table 1 (10-DoF hip + arm IK, with/without
//! reachability space, without/with obstacle) and Table 2 (dual-arm IK: flexible grasp selection,
//! object grasped with the left hand), 100 seeded queries each, the paper's figures beside ours.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use clap::Args;
use nalgebra::{Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use manyhands::collision::CollisionWorld;
use manyhands::geometry::Pose;
use manyhands::kinematics::randomized::{IkCounters, RandomizedIkSettings};
use manyhands::kinematics::Chain;
use manyhands::reachability::queries::{DualArmProblem, SingleArmProblem};
use manyhands::reachability::{GridParams, ObjectPlacement, ReachabilityGrid};
use manyhands::{Robot, Scene};

use super::super::commands::Ctx;

#[derive(Args, Debug)]
pub struct IkBenchArgs {
    /// Queries per row.
    #[arg(long, default_value_t = 100)]
    pub queries: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Samples of each reachability grid built for the benchmark (when no file is given).
    #[arg(long, default_value_t = 4_000_000)]
    pub reach_samples: u64,
    /// Right-arm grid file (`reach build armar --chain right_arm`); built when absent.
    #[arg(long)]
    pub grid_right: Option<PathBuf>,
    /// Left-arm grid file (`reach build armar --chain left_arm`); built when absent.
    #[arg(long)]
    pub grid_left: Option<PathBuf>,
    /// Tries before "no solution".
    #[arg(long, default_value_t = 20_000)]
    pub max_tries: u64,
    /// Probability of the gradient ascent on the free object pose (dual-arm, 000 §II-C).
    #[arg(long, default_value_t = 0.5)]
    pub gradient_probability: f64,
    /// Reachability threshold of the single-arm rows: the arm IK is called only above it.
    #[arg(long, default_value_t = 0.02)]
    pub threshold: f64,
    /// Reachability threshold of the dual-arm rows.
    #[arg(long, default_value_t = 0.0)]
    pub dual_threshold: f64,
    /// Swivel angles enumerated per analytic-IK query.
    #[arg(long, default_value_t = 8)]
    pub psi_samples: u32,
}

/// One row of results.
struct Stat {
    what: String,
    times_us: Vec<f64>,
    counters: IkCounters,
    /// Times and counters of the solved queries only.
    ok_times_us: Vec<f64>,
    ok_counters: IkCounters,
    ok: usize,
    n: usize,
    paper: &'static str,
}

impl Stat {
    fn median(&self) -> f64 {
        median(&self.times_us)
    }
    fn ok_median(&self) -> f64 {
        median(&self.ok_times_us)
    }
    fn mean(&self) -> f64 {
        self.times_us.iter().sum::<f64>() / self.times_us.len().max(1) as f64
    }
    fn per(&self, v: u64) -> f64 {
        v as f64 / self.n.max(1) as f64
    }
    fn ok_per(&self, v: u64) -> f64 {
        v as f64 / self.ok.max(1) as f64
    }
}

fn median(t: &[f64]) -> f64 {
    {
        let mut t = t.to_vec();
        t.sort_by(|a, b| a.total_cmp(b));
        t.get(t.len() / 2).copied().unwrap_or(0.0)
    }
}

fn grid(
    ctx: &Ctx,
    robot: &Arc<Robot>,
    group: &str,
    file: Option<&PathBuf>,
    samples: u64,
    seed: u64,
) -> Result<Arc<ReachabilityGrid>> {
    if let Some(f) = file {
        return Ok(Arc::new(ReachabilityGrid::load(f, robot, group, None)?));
    }
    let chain = Chain::from_group(robot, group).ok_or_else(|| anyhow!("no chain group {group}"))?;
    let p = GridParams::auto(robot, &chain, 0.05, 8, samples, seed)?;
    let t = Instant::now();
    let g = ReachabilityGrid::build(robot, group, &p, &|_| {})?;
    if !ctx.json {
        eprintln!(
            "built {group} grid: {} samples, {} cells filled, {:.1} s",
            samples,
            g.stats().filled,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(Arc::new(g))
}

/// Wok poses on the table in front of the robot (x ∈ [0.52, 0.75], y ∈ [−0.45, 0.15], table
/// height, handle toward the robot: yaw π ± 1 rad), free of the obstacles of `scene` (seeded).
fn wok_poses(scene: &Scene, n: usize, seed: u64) -> Result<Vec<Pose>> {
    let world = CollisionWorld::from_scene(scene);
    let mut place = ObjectPlacement::new(&world, "wok").context("scene has no wok")?;
    let z = scene
        .object("wok")
        .map(|o| o.body.pose.translation.z)
        .unwrap_or(0.901);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(n);
    let mut attempts = 0;
    while out.len() < n {
        attempts += 1;
        if attempts > 1000 * n.max(1) {
            return Err(anyhow!("no free wok pose found on the table"));
        }
        let p = Pose::from_parts(
            Translation3::new(
                rng.random_range(0.52..0.75),
                rng.random_range(-0.45..0.15),
                z,
            ),
            UnitQuaternion::from_euler_angles(
                0.0,
                0.0,
                std::f64::consts::PI + rng.random_range(-1.0..1.0),
            ),
        );
        if place.is_free(&p) {
            out.push(p);
        }
    }
    Ok(out)
}

fn single_row(
    prob: &mut SingleArmProblem,
    poses: &[Pose],
    use_grid: bool,
    settings: &RandomizedIkSettings,
    seed: u64,
    what: String,
    paper: &'static str,
) -> Stat {
    let mut st = Stat {
        what,
        times_us: Vec::new(),
        counters: IkCounters::default(),
        ok_times_us: Vec::new(),
        ok_counters: IkCounters::default(),
        ok: 0,
        n: poses.len(),
        paper,
    };
    for (i, p) in poses.iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(i as u64));
        let t = Instant::now();
        let r = prob.solve(p, use_grid, settings, &mut rng);
        st.times_us.push(t.elapsed().as_secs_f64() * 1e6);
        match r {
            Ok(s) => {
                st.ok += 1;
                st.counters.add(&s.counters);
                st.ok_counters.add(&s.counters);
                st.ok_times_us
                    .push(st.times_us.last().copied().unwrap_or(0.0));
            }
            Err(manyhands::kinematics::randomized::RandomizedIkError::NoSolution {
                counters,
                ..
            }) => st.counters.add(&counters),
            Err(_) => {}
        }
    }
    st
}

#[allow(clippy::too_many_arguments)]
fn dual_row(
    prob: &mut DualArmProblem,
    region: ([f64; 3], [f64; 3]),
    held: Option<usize>,
    n: usize,
    settings: &RandomizedIkSettings,
    seed: u64,
    what: String,
    paper: &'static str,
) -> Stat {
    let mut st = Stat {
        what,
        times_us: Vec::new(),
        counters: IkCounters::default(),
        ok_times_us: Vec::new(),
        ok_counters: IkCounters::default(),
        ok: 0,
        n,
        paper,
    };
    for i in 0..n {
        let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(i as u64));
        let held = held.map(|_| rng.random_range(0..prob.left_grasps.tcps.len()));
        let t = Instant::now();
        let r = prob.solve(region, held, true, settings, &mut rng);
        st.times_us.push(t.elapsed().as_secs_f64() * 1e6);
        match r {
            Ok(s) => {
                st.ok += 1;
                st.counters.add(&s.counters);
                st.ok_counters.add(&s.counters);
                st.ok_times_us
                    .push(st.times_us.last().copied().unwrap_or(0.0));
            }
            Err(manyhands::kinematics::randomized::RandomizedIkError::NoSolution {
                counters,
                ..
            }) => st.counters.add(&counters),
            Err(_) => {}
        }
    }
    st
}

pub fn run(ctx: &Ctx, a: &IkBenchArgs) -> Result<()> {
    let with_obstacle = ctx.scene("obstacle")?;
    let mut without = with_obstacle.clone();
    without.obstacles.retain(|b| b.name != "obstacle");
    let robot = with_obstacle
        .robots
        .first()
        .map(|r| r.robot.clone())
        .ok_or_else(|| anyhow!("scene 'obstacle' has no robot"))?;
    let gr = grid(
        ctx,
        &robot,
        "right_arm",
        a.grid_right.as_ref(),
        a.reach_samples,
        a.seed,
    )?;
    let gl = grid(
        ctx,
        &robot,
        "left_arm",
        a.grid_left.as_ref(),
        a.reach_samples,
        a.seed + 1,
    )?;
    let poses = wok_poses(&with_obstacle, a.queries, a.seed)?;
    let settings = RandomizedIkSettings {
        max_tries: a.max_tries,
        gradient_probability: a.gradient_probability,
        psi_samples: a.psi_samples,
        threshold: a.threshold,
        ..RandomizedIkSettings::default()
    };
    let mut rows = Vec::new();
    for (scene, sname) in [
        (&without, "without obstacle"),
        (&with_obstacle, "with obstacle"),
    ] {
        let mut prob = SingleArmProblem::new(scene, "armar", "torso_right_arm", "wok")?;
        prob.set_grid(Some(gr.clone()))?;
        let obst = sname == "with obstacle";
        rows.push(single_row(
            &mut prob,
            &poses,
            false,
            &settings,
            a.seed,
            format!("10-DoF IK, no reachability, {sname}"),
            if obst {
                "2 880 ms, 217.3 calls"
            } else {
                "1 404 ms, 101.9 calls"
            },
        ));
        rows.push(single_row(
            &mut prob,
            &poses,
            true,
            &settings,
            a.seed,
            format!("10-DoF IK, reachability, {sname}"),
            if obst {
                "144 ms, 13.6 calls"
            } else {
                "60 ms, 6.1 calls"
            },
        ));
    }
    let region = ([0.3, -0.3, 1.0], [0.6, 0.2, 1.4]);
    let settings = RandomizedIkSettings {
        threshold: a.dual_threshold,
        ..settings
    };
    for (scene, sname) in [
        (&without, "without obstacle"),
        (&with_obstacle, "with obstacle"),
    ] {
        let mut prob =
            DualArmProblem::new(scene, "armar", "torso_left_arm", "torso_right_arm", "wok")?;
        prob.set_grids(Some((gl.clone(), gr.clone())))?;
        let obst = sname == "with obstacle";
        rows.push(dual_row(
            &mut prob,
            region,
            None,
            a.queries,
            &settings,
            a.seed,
            format!("dual-arm IK, flexible grasps, {sname}"),
            if obst {
                "161 ms, 6.5 calls"
            } else {
                "47 ms, 3.3 calls"
            },
        ));
        rows.push(dual_row(
            &mut prob,
            region,
            Some(0),
            a.queries,
            &settings,
            a.seed,
            format!("dual-arm IK, held in left hand, {sname}"),
            if obst {
                "220 ms, 4.3 calls"
            } else {
                "162 ms, 3.2 calls"
            },
        ));
    }
    rows.push(base_placement_row(ctx, a)?);
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if ctx.json {
        let v: Vec<_> = rows
            .iter()
            .map(|r| {
                json!({"what": r.what, "median_us": r.median(), "mean_us": r.mean(),
                "mean_ik_calls": r.per(r.counters.ik_calls), "mean_tries": r.per(r.counters.tries),
                "mean_collision_checks": r.per(r.counters.collision_checks),
                "success": r.ok as f64 / r.n.max(1) as f64, "n": r.n, "paper": r.paper,
                "solved_median_us": r.ok_median(), "solved_mean_ik_calls": r.ok_per(r.ok_counters.ik_calls),
                "solved_mean_tries": r.ok_per(r.ok_counters.tries), "mean_psi_solves": r.per(r.counters.psi_solves)})
            })
            .collect();
        let _ = writeln!(
            out,
            "{}",
            serde_json::to_string_pretty(&v).unwrap_or_default()
        );
        return Ok(());
    }
    let _ = writeln!(out, "all queries (failures run to --max-tries) | solved queries only | paper (000 Tables 1/2, 2 GHz, all solved)");
    let _ = writeln!(
        out,
        "{:<48} {:>10} {:>11} {:>9} {:>8} {:>7} | {:>10} {:>8} {:>8} | paper",
        "query (seeded, wok)",
        "median",
        "mean",
        "IK calls",
        "coll.chk",
        "success",
        "median",
        "IK calls",
        "tries"
    );
    for r in &rows {
        let _ = writeln!(
            out,
            "{:<48} {:>7.1} µs {:>8.1} µs {:>9.1} {:>8.1} {:>6.0} % | {:>7.1} µs {:>8.1} {:>8.1} | {}",
            r.what,
            r.median(),
            r.mean(),
            r.per(r.counters.ik_calls),
            r.per(r.counters.collision_checks),
            100.0 * r.ok as f64 / r.n.max(1) as f64,
            r.ok_median(),
            r.ok_per(r.ok_counters.ik_calls),
            r.ok_per(r.ok_counters.tries),
            r.paper
        );
    }
    Ok(())
}

/// IkDualArm (002 Alg. 1) on the kitchen wok: platform-frame grids of both 10-DoF chains,
/// inverse maps around the wok, R_bi, then seeded base-placement queries.
fn base_placement_row(ctx: &Ctx, a: &IkBenchArgs) -> Result<Stat> {
    use manyhands::collision::{BodyId, CollisionChecker, FastChecker};
    use manyhands::kinematics::dual_arm::DualArmIk;
    use manyhands::reachability::inverse::{bimanual, ik_dual_arm, inverse_map, placement_cdf};
    use manyhands::reachability::{hand_links, queries::grasp_set};

    let sc = ctx.scene("kitchen")?;
    let placement = sc
        .robots
        .first()
        .ok_or_else(|| anyhow!("kitchen has no robot"))?;
    let robot = placement.robot.clone();
    let base = placement.base_pose;
    let start = placement.start_config();
    let t0 = Instant::now();
    let mk = |group: &str, seed: u64| -> Result<ReachabilityGrid> {
        let chain =
            Chain::from_group(&robot, group).ok_or_else(|| anyhow!("no chain group {group}"))?;
        let p = GridParams::auto(&robot, &chain, 0.1, 8, a.reach_samples / 2, seed)?;
        Ok(ReachabilityGrid::build(&robot, group, &p, &|_| {})?)
    };
    let (gl, gr) = (
        mk("torso_left_arm", a.seed)?,
        mk("torso_right_arm", a.seed + 1)?,
    );
    let wok = sc
        .object("wok")
        .ok_or_else(|| anyhow!("kitchen has no wok"))?
        .body
        .pose;
    let lg = grasp_set(&sc, "wok", "left_hand")?;
    let rg = grasp_set(&sc, "wok", "right_hand")?;
    let tl: Vec<Pose> = lg.tcps.iter().map(|g| wok * g).collect();
    let tr: Vec<Pose> = rg.tcps.iter().map(|g| wok * g).collect();
    let mut bv = [0usize; 3];
    for (k, n) in ["base_x", "base_y", "base_yaw"].iter().enumerate() {
        bv[k] = robot
            .var(n)
            .ok_or_else(|| anyhow!("robot has no joint {n}"))?;
    }
    let c = [wok.translation.x, wok.translation.y];
    let t1 = Instant::now();
    let ml = inverse_map(&robot, &base, &start, &bv, &gl, &tl, c, 0.1, 1.2, 16, 0.0)
        .ok_or_else(|| anyhow!("inverse map"))?;
    let mr = inverse_map(&robot, &base, &start, &bv, &gr, &tr, c, 0.1, 1.2, 16, 0.0)
        .ok_or_else(|| anyhow!("inverse map"))?;
    let (bi, rights) = bimanual(&ml, &mr).ok_or_else(|| anyhow!("maps differ"))?;
    let cdf = placement_cdf(&bi);
    let map_ms = t1.elapsed().as_secs_f64() * 1e3;
    if !ctx.json {
        eprintln!(
            "base placement: platform grids {:.1} s, inverse maps + R_bi {:.1} ms",
            (t1 - t0).as_secs_f64(),
            map_ms
        );
    }
    let mut world = CollisionWorld::from_scene(&sc);
    let wi = world
        .statics
        .iter()
        .position(|s| s.name == "wok")
        .ok_or_else(|| anyhow!("no wok body"))?;
    let mut hands = hand_links(&robot, "left_hand").unwrap_or_default();
    hands.extend(hand_links(&robot, "right_hand").unwrap_or_default());
    for &l in &hands {
        world.allow(BodyId::Link { robot: 0, link: l }, BodyId::Static(wi));
    }
    let mut fast = FastChecker::new(&world);
    let ik = DualArmIk::new(robot.clone(), "torso_left_arm", "torso_right_arm")?;
    let settings = RandomizedIkSettings {
        max_tries: a.max_tries,
        ..RandomizedIkSettings::default()
    };
    let mut st = Stat {
        what: "IkDualArm base placement, kitchen wok".into(),
        times_us: Vec::new(),
        counters: IkCounters::default(),
        ok_times_us: Vec::new(),
        ok_counters: IkCounters::default(),
        ok: 0,
        n: a.queries,
        paper: "002: no per-query figure",
    };
    for i in 0..a.queries {
        let mut rng = ChaCha8Rng::seed_from_u64(a.seed.wrapping_add(i as u64));
        let t = Instant::now();
        let r = ik_dual_arm(
            &ik,
            &base,
            &start,
            &bv,
            &bi,
            &cdf,
            &rights,
            &tl,
            &tr,
            &settings,
            &mut rng,
            |q| fast.is_free(q),
        );
        let us = t.elapsed().as_secs_f64() * 1e6;
        st.times_us.push(us);
        match r {
            Ok(s) => {
                st.ok += 1;
                st.counters.add(&s.counters);
                st.ok_counters.add(&s.counters);
                st.ok_times_us.push(us);
            }
            Err(manyhands::kinematics::randomized::RandomizedIkError::NoSolution {
                counters,
                ..
            }) => st.counters.add(&counters),
            Err(_) => {}
        }
    }
    Ok(st)
}
