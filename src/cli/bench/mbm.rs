//! `manyhands bench mbm`: the MotionBenchMaker problem sets (Panda, Baxter) planned with
//! RRT-Connect one problem at a time on one thread, every returned path re-checked by the exact
//! checker; statistics per set and overall, printed beside VAMP's reference figures.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde::Serialize;
use serde_json::json;

use manyhands::benchmark::mbm::{MbmFile, MbmProblem};
use manyhands::benchmark::mbm_data;
use manyhands::collision::{AutoChecker, ExactChecker, FastChecker, FastModelSettings};
use manyhands::planning::base::range::{self, DerivedSettings};
use manyhands::planning::{
    PlanError, RrtConnect, RrtConnectSettings, Sampler, ShortcutSettings, SpaceValidator,
    Termination,
};
use manyhands::Robot;

use super::super::commands::Ctx;

/// `--sampler` of `bench mbm`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplerArg {
    Uniform,
    Halton,
}

impl From<SamplerArg> for Sampler {
    fn from(s: SamplerArg) -> Sampler {
        match s {
            SamplerArg::Uniform => Sampler::Uniform,
            SamplerArg::Halton => Sampler::Halton,
        }
    }
}

#[derive(Args, Debug, Clone)]
pub struct MbmArgs {
    /// `panda` or `baxter` (the benchmark's robot and problems from the MotionBenchMaker data
    /// folder: $MANYHANDS_MBM_DIR, ../shared/benchmarks/mbm or the cache of `manyhands data
    /// mbm`), or the path of a robot's URDF (then --problems is needed).
    #[arg(long, required_unless_present = "suite")]
    pub robot: Option<PathBuf>,
    /// A suite of robots instead of one: `generality` (the MotionBenchMaker Panda when its data
    /// is found, and every robot folder of benchmarks/generality/ with its problems.json),
    /// each planned certified and, with the same settings and seeds, without the certificate
    /// (as --uncertified); one line per robot (see the README, "Generality suite").
    #[arg(long, value_enum, conflicts_with_all = ["robot", "problems", "uncertified", "out", "ompl_log"])]
    pub suite: Option<super::mbm_suite::Suite>,
    /// The folder of the generality suite's robots (default: benchmarks/generality from the
    /// working directory).
    #[arg(long)]
    pub suite_dir: Option<PathBuf>,
    /// **Benchmark only**: the same search without the certificate — the certified checks'
    /// states with plain (uninflated) spheres, so nothing is refined. Its paths may pass
    /// through collisions between checked states; the exact re-check counts them as invalid.
    /// Only with the sphere checker (a robot made of spheres). No planner setting or request
    /// can do this.
    #[arg(long, conflicts_with = "fast_checker")]
    pub uncertified: bool,
    /// Its SRDF (default: the .srdf beside the URDF, when present).
    #[arg(long)]
    pub srdf: Option<PathBuf>,
    /// The problems.json file (default with --robot NAME: the data folder's NAME/problems.json).
    #[arg(long)]
    pub problems: Option<PathBuf>,
    /// Only these sets (comma-separated); default all.
    #[arg(long, value_delimiter = ',')]
    pub sets: Vec<String>,
    /// Runs per problem (different seeds).
    #[arg(long, default_value_t = 1)]
    pub trials: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// At most N valid problems per set (0 = all).
    #[arg(long, default_value_t = 0)]
    pub limit: usize,
    /// Time limit per query, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub time_limit: f64,
    /// Planning motion-check resolution: largest joint step between checked states, degrees.
    /// The default equals the exact re-check's resolution, so every state the re-check visits
    /// was checked by the (conservative) planning model.
    #[arg(long, default_value_t = 0.25)]
    pub resolution: f64,
    /// Resolution of the exact re-check of returned paths, degrees.
    #[arg(long, default_value_t = 0.25)]
    pub check_resolution: f64,
    /// RRT-Connect range (joint-space distance); default derived from the robot: the step
    /// that moves its collision geometry at most 2 m (`planning::base::range`, README "Settings
    /// derived from the robot").
    #[arg(long)]
    pub range: Option<f64>,
    /// Padding added to every robot sphere of the planner's collision model, metres (a safety
    /// margin; 0 = the benchmark's own model, which is what the exact re-check uses).
    #[arg(long, default_value_t = 0.0)]
    pub padding: f64,
    /// Certified motion checks (sphere model): every tree edge and shortcut is proven free as a
    /// continuous motion, spheres inflated by at most this many metres per checked state (0 =
    /// off: states at --resolution instead). Independent of it, returned paths are re-checked
    /// exactly at --check-resolution.
    #[arg(long, default_value_t = 0.04)]
    pub certify: f64,
    /// Dynamic-domain radius (joint-space distance) of RRT-Connect; 0 = off. Default derived
    /// from the space: 0.3 × its maximum extent (the Panda's is VAMP's 4).
    #[arg(long)]
    pub dynamic_domain: Option<f64>,
    /// Sample source: `uniform` (seeded draws) or `halton` (the Halton sequence from its first
    /// point for every problem, VAMP's default; see the README, "Where the time goes against
    /// VAMP")
    #[arg(long, value_enum, default_value = "uniform")]
    pub sampler: SamplerArg,
    /// Alternate the trees instead of growing the smaller one (VAMP and this bench balance).
    #[arg(long)]
    pub no_balance: bool,
    /// Lazy certification instead of the default (the product's) eager one: edges whose
    /// certificate's first pass finds their states free are added at once and fully certified
    /// (refined from that pass) only when they lie on a found path (see
    /// `RrtConnectSettings::lazy`). Returned paths are fully certified either way.
    #[arg(long, conflicts_with = "eager_certify")]
    pub lazy_certify: bool,
    /// Eager certification (the default; kept for older scripts).
    #[arg(long, hide = true)]
    pub eager_certify: bool,
    /// Plan with the general primitive checker (FastChecker) even when the robot is made of
    /// spheres (default: the f32 8-lane sphere checker whenever it applies).
    #[arg(long)]
    pub fast_checker: bool,
    /// Re-validate each raw path with the planning checker inside the timed planning (its
    /// segments are the tree edges already validated; the exact re-check is done regardless).
    #[arg(long)]
    pub revalidate: bool,
    /// Return raw paths (no shortcutting).
    #[arg(long)]
    pub no_simplify: bool,
    /// Write per-problem results (each returned path included) and the summaries as JSON to
    /// this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the runs in OMPL's benchmark log format (one experiment, planner
    /// `manyhands_RRTConnect`, the problem set as an enum), for `ompl_benchmark_statistics.py`
    /// and Planner Arena.
    #[arg(long)]
    pub ompl_log: Option<PathBuf>,
}

#[derive(Debug, Clone, Serialize)]
pub(super) struct Run {
    pub(super) set: String,
    pub(super) index: usize,
    pub(super) trial: usize,
    pub(super) seed: u64,
    pub(super) solved: bool,
    /// Solved by the planner but rejected by the exact re-check.
    pub(super) invalid: bool,
    pub(super) error: Option<String>,
    pub(super) setup_us: f64,
    pub(super) plan_us: f64,
    pub(super) simplify_us: f64,
    pub(super) iterations: u64,
    pub(super) collision_checks: u64,
    pub(super) start_tree: usize,
    pub(super) goal_tree: usize,
    pub(super) length_raw: f64,
    pub(super) length_simplified: f64,
    pub(super) vertices: usize,
    /// The returned path (states of the problem's joint space, start first), empty when none.
    pub(super) path: Vec<Vec<f64>>,
    /// The fast checker's certified motion checks of the search (when it planned with it).
    pub(super) certification: Option<manyhands::collision::CertifyStats>,
    /// The sphere checker's certified checks and refinement calls of the search and the
    /// start/goal checks (when it planned with it).
    pub(super) certify_counts: Option<manyhands::collision::CertifyCounts>,
}

#[derive(Debug, Clone, Serialize)]
struct Summary {
    set: String,
    runs: usize,
    solved: usize,
    invalid: usize,
    median_us: f64,
    mean_us: f64,
    p95_us: f64,
    max_us: f64,
    simplify_median_us: f64,
    total_median_us: f64,
    length_raw_median: f64,
    length_simplified_median: f64,
    iterations_median: f64,
    checks_median: f64,
    setup_median_us: f64,
    vamp_median_us: Option<f64>,
}

/// VAMP 0.6.4 RRT-Connect, one core, this machine type, run alternated with manyhands 7f3f3ea
/// (`../shared/benchmarks/mbm/README.md`, 2026-12-01): median planning µs per set and overall,
/// of the benchmark's data sets by the problem file's robot name. Labels of the comparison
/// only: no planner setting depends on them.
const VAMP_PANDA: &[(&str, f64)] = &[
    ("table_pick", 44.6),
    ("table_under_pick", 88.6),
    ("box", 106.1),
    ("bookshelf_small", 53.0),
    ("bookshelf_tall", 56.3),
    ("bookshelf_thin", 61.4),
    ("cage", 330.2),
    ("overall", 72.9),
];
const VAMP_BAXTER: &[(&str, f64)] = &[
    ("bookshelf_tall_both_arms_easy", 8720.0),
    ("bookshelf_tall_both_arms_medium", 7570.0),
    ("bookshelf_tall_both_arms_hard", 8310.0),
    ("overall", 8090.0),
];

/// VAMP's median of a set (or "overall") of the benchmark's data set `robot`, when known.
fn vamp_median(robot: &str, set: &str) -> Option<f64> {
    let table = match robot {
        "panda" => VAMP_PANDA,
        "baxter" => VAMP_BAXTER,
        _ => return None,
    };
    table.iter().find(|(n, _)| *n == set).map(|x| x.1)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

fn sorted(v: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = v.collect();
    v.sort_by(|a, b| a.total_cmp(b));
    v
}

fn summarize(set: &str, runs: &[&Run], vamp: Option<f64>) -> Summary {
    let ok: Vec<&&Run> = runs.iter().filter(|r| r.solved).collect();
    let t = sorted(ok.iter().map(|r| r.plan_us));
    let med = |v: Vec<f64>| percentile(&v, 0.5);
    Summary {
        set: set.to_string(),
        runs: runs.len(),
        solved: ok.len(),
        invalid: runs.iter().filter(|r| r.invalid).count(),
        median_us: percentile(&t, 0.5),
        mean_us: if t.is_empty() {
            f64::NAN
        } else {
            t.iter().sum::<f64>() / t.len() as f64
        },
        p95_us: percentile(&t, 0.95),
        max_us: t.last().copied().unwrap_or(f64::NAN),
        simplify_median_us: med(sorted(ok.iter().map(|r| r.simplify_us))),
        total_median_us: med(sorted(ok.iter().map(|r| r.plan_us + r.simplify_us))),
        length_raw_median: med(sorted(ok.iter().map(|r| r.length_raw))),
        length_simplified_median: med(sorted(ok.iter().map(|r| r.length_simplified))),
        iterations_median: med(sorted(ok.iter().map(|r| r.iterations as f64))),
        checks_median: med(sorted(ok.iter().map(|r| r.collision_checks as f64))),
        setup_median_us: med(sorted(runs.iter().map(|r| r.setup_us))),
        vamp_median_us: vamp,
    }
}

/// A seed per (base seed, set, problem, trial) — SplitMix64 of the combination.
fn derive_seed(seed: u64, set: usize, index: usize, trial: usize) -> u64 {
    let mut z = seed
        ^ (set as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (index as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9)
        ^ (trial as u64).wrapping_mul(0x94D0_49BB_1331_11EB);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn run_problem(
    robot: &Arc<Robot>,
    vars: &[usize],
    p: &MbmProblem,
    settings: &RrtConnectSettings,
    a: &MbmArgs,
    trial: usize,
    seed: u64,
) -> Result<Run> {
    let t_setup = Instant::now();
    let world = p.world(robot.clone());
    let space = p.space(&world, vars)?;
    let checker = if a.fast_checker {
        AutoChecker::Fast(FastChecker::with_settings(
            &world,
            FastModelSettings { padding: a.padding },
        ))
    } else {
        AutoChecker::new(&world, a.padding)
    };
    let mut checker = checker;
    if a.uncertified {
        match &mut checker {
            AutoChecker::Spheres(s) => s.set_uncertified_for_benchmark(true),
            AutoChecker::Fast(_) => bail!(
                "--uncertified needs the sphere checker: robot {} is not made of spheres",
                robot.name
            ),
        }
    }
    let mut planner = RrtConnect::with_checker(space.clone(), &world, checker, *settings)?;
    let setup_us = t_setup.elapsed().as_secs_f64() * 1e6;
    let mut run = Run {
        set: p.set.clone(),
        index: p.index,
        trial,
        seed,
        solved: false,
        invalid: false,
        error: None,
        setup_us,
        plan_us: f64::NAN,
        simplify_us: f64::NAN,
        iterations: 0,
        collision_checks: 0,
        start_tree: 0,
        goal_tree: 0,
        length_raw: f64::NAN,
        length_simplified: f64::NAN,
        vertices: 0,
        path: Vec::new(),
        certification: None,
        certify_counts: None,
    };
    let mut term = Termination::new().with_time_limit(Duration::from_secs_f64(a.time_limit));
    let planned = planner.plan(&p.start, &p.goals, &mut term, seed);
    if let AutoChecker::Spheres(s) = planner.validator().checker() {
        run.certify_counts = Some(s.certify_counts());
    }
    match planned {
        Ok(r) => {
            let s = &r.stats;
            run.plan_us = s.time.as_secs_f64() * 1e6;
            run.simplify_us = s.simplify_time.as_secs_f64() * 1e6;
            run.iterations = s.iterations;
            run.collision_checks = s.collision_checks;
            run.start_tree = s.start_tree_size;
            run.goal_tree = s.goal_tree_size;
            run.length_raw = s.length_raw;
            run.length_simplified = s.length_simplified;
            run.vertices = r.path.len();
            run.path = r.path.clone();
            run.certification = s.certification;
            // Planned; `recheck` decides (after the set's timed plans).
            run.solved = true;
        }
        Err(e) => {
            if let Some(s) = e.stats() {
                run.plan_us = s.time.as_secs_f64() * 1e6;
                run.iterations = s.iterations;
            }
            run.error = Some(e.to_string());
            if matches!(e, PlanError::PathInvalid { .. }) {
                run.invalid = true;
            }
        }
    }
    Ok(run)
}

/// The exact re-check of a run's path (at `--check-resolution`, ends must be the problem's):
/// a solved run it rejects becomes invalid. Runs after the timed plans of the whole set, so its
/// work (far more than the planning's) does not evict the planner's data between two timed
/// plans (measured on easy sets: planning medians about 20 % higher when interleaved).
fn recheck(
    robot: &Arc<Robot>,
    vars: &[usize],
    p: &MbmProblem,
    a: &MbmArgs,
    run: &mut Run,
) -> Result<()> {
    if !run.solved {
        return Ok(());
    }
    run.solved = false;
    let world = p.world(robot.clone());
    let space = p.space(&world, vars)?;
    let mut exact = SpaceValidator::new(
        space,
        &world,
        ExactChecker::new(&world),
        a.check_resolution.to_radians(),
        0.005,
    );
    // The planner clamps values within `Limits::TOLERANCE` outside the limits.
    let near = |a: &[f64], b: &[f64]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= manyhands::model::Limits::TOLERANCE)
    };
    let path = &run.path;
    let ends_ok = path.first().is_some_and(|q| near(q, &p.start))
        && path
            .last()
            .is_some_and(|q| p.goals.iter().any(|g| near(q, g)));
    match exact.validate_path(path) {
        Ok(()) if ends_ok => run.solved = true,
        Ok(()) => {
            run.invalid = true;
            run.error = Some("path does not join the start to a goal".into());
        }
        Err(k) => {
            run.invalid = true;
            run.error = Some(format!("exact check failed at state/segment {k}"));
        }
    }
    Ok(())
}

fn fmt_us(us: f64) -> String {
    if us.is_nan() {
        "—".into()
    } else if us < 1000.0 {
        format!("{us:.1} µs")
    } else if us < 1e6 {
        format!("{:.2} ms", us / 1e3)
    } else {
        format!("{:.2} s", us / 1e6)
    }
}

/// The URDF and problem file of `--robot` / `--problems`: a benchmark robot's name resolves in
/// the MotionBenchMaker data folder ([`mbm_data::locate`]).
fn resolve_files(a: &MbmArgs) -> Result<(PathBuf, PathBuf)> {
    let robot = a.robot.clone().context("--robot is needed (or --suite)")?;
    let name = robot.to_str().unwrap_or_default();
    if !robot.exists() && mbm_data::ROBOTS.contains(&name) {
        let dir = mbm_data::locate().map_err(|why| {
            anyhow!("--robot {name}: no MotionBenchMaker data: {why}; or give the URDF's path")
        })?;
        let f = mbm_data::robot_files(&dir, name);
        return Ok((f.urdf, a.problems.clone().unwrap_or(f.problems)));
    }
    let problems = a.problems.clone().with_context(|| {
        format!(
            "--problems FILE is needed with --robot {} (or --robot {})",
            robot.display(),
            mbm_data::ROBOTS.join("|")
        )
    })?;
    Ok((robot, problems))
}

pub fn run(ctx: &Ctx, a: &MbmArgs) -> Result<()> {
    if let Some(suite) = a.suite {
        return super::mbm_suite::run(ctx, a, suite);
    }
    run_one(ctx, a, false).map(|_| ())
}

/// What [`run_one`] planned: the robot's size, its derived range and every run.
pub(super) struct Outcome {
    /// Planned joints.
    pub dof: usize,
    /// Robot spheres of the sphere checker (`None`: the robot is not made of spheres).
    pub spheres: Option<usize>,
    pub range: f64,
    pub runs: Vec<Run>,
}

/// Plans every valid problem of one robot's file; prints the per-set table (and writes --out,
/// --ompl-log) unless `quiet` (the suite prints its own lines).
pub(super) fn run_one(ctx: &Ctx, a: &MbmArgs, inner: bool) -> Result<Outcome> {
    let quiet = inner || ctx.json;
    if !(a.time_limit.is_finite() && a.time_limit > 0.0) {
        bail!("--time-limit must be > 0");
    }
    if !(a.padding.is_finite() && a.padding >= 0.0) {
        bail!("--padding must be ≥ 0");
    }
    if !(a.certify.is_finite() && a.certify >= 0.0) {
        bail!("--certify must be ≥ 0 metres");
    }
    if a.dynamic_domain
        .is_some_and(|d| !(d.is_finite() && d >= 0.0))
    {
        bail!("--dynamic-domain must be ≥ 0");
    }
    if a.trials == 0 {
        bail!("--trials must be ≥ 1");
    }
    if a.uncertified && a.certify == 0.0 {
        bail!("--uncertified drops the certificate of certified checks: it needs --certify > 0");
    }
    let (urdf, problems) = resolve_files(a)?;
    let file = MbmFile::load(&problems)?;
    // Default SRDF: NAME.srdf beside the URDF, else ROBOT.srdf (the problem file's robot name).
    let srdf = a.srdf.clone().or_else(|| {
        [
            urdf.with_extension("srdf"),
            urdf.with_file_name(format!("{}.srdf", file.robot)),
        ]
        .into_iter()
        .find(|s| s.is_file())
    });
    if srdf.is_none() && !quiet {
        println!("warning: no SRDF found (give --srdf): no self-collision pair is disabled");
    }
    let robot = Arc::new(
        Robot::from_files(&urdf, srdf.as_deref())
            .with_context(|| format!("loading {}", urdf.display()))?,
    );
    let vars = file.joint_vars(&robot)?;
    for s in &a.sets {
        if file.set(s).is_none() {
            let names: Vec<&str> = file.sets.iter().map(|s| s.name.as_str()).collect();
            bail!("unknown set '{s}' (the file has {names:?})");
        }
    }
    // Range and dynamic-domain radius from the robot and the planned joints (the obstacles do
    // not enter): the space of any problem of the file, without its obstacles.
    let derived = {
        let empty = MbmProblem {
            obstacles: Vec::new(),
            ..file
                .sets
                .iter()
                .flat_map(|s| s.problems.iter())
                .next()
                .context("the problem file has no problem")?
                .clone()
        };
        let world = empty.world(robot.clone());
        let space = empty.space(&world, &vars)?;
        DerivedSettings::of(&world, &space)
            .context("no link with collision geometry moves with the problem's joints")?
    };
    let dynamic_domain = a.dynamic_domain.unwrap_or(derived.dynamic_domain);
    let settings = RrtConnectSettings {
        range: Some(a.range.unwrap_or(derived.range)),
        angular_resolution: a.resolution.to_radians(),
        linear_resolution: 0.005,
        direct_connect: true,
        shortcut: (!a.no_simplify).then(ShortcutSettings::default),
        revalidate: a.revalidate,
        certify: (a.certify > 0.0).then_some(a.certify),
        dynamic_domain: (dynamic_domain > 0.0).then_some(dynamic_domain),
        balance: !a.no_balance,
        // Eager by default, as the product plans: with the chord certificate few edges need
        // refining, and lazily accepted edges that fail later cost Baxter's searches more
        // (callgrind, planning only, `--limit 10 --trials 3`: 6 612 → 5 733 M instructions,
        // −13 %; Panda, all 699 problems, +0.7 %; UR5-like +1.3 %). Lazy had fewer instructions
        // on every Panda set with the earlier, linear certificate.
        // (`--eager-certify` conflicts with `--lazy-certify`: the default, named.)
        lazy: a.lazy_certify,
        sampler: a.sampler.into(),
    };
    let started = chrono_like_now();
    let t_all = Instant::now();
    let mut runs: Vec<Run> = Vec::new();
    let mut summaries: Vec<Summary> = Vec::new();
    if !quiet {
        println!(
            "{} ({} DoF planned of {}), {} trial(s), seed {}, time limit {} s, motion checks: {}, range {:.4}{}, dynamic domain {}, {} trees, {} samples, padding {} m, exact re-check at {}°, {}",
            file.robot,
            vars.len(),
            robot.dof(),
            a.trials,
            a.seed,
            a.time_limit,
            if a.uncertified {
                "UNCERTIFIED (benchmark only: the certified checks' states with plain spheres)"
                    .to_string()
            } else if a.certify > 0.0 {
                format!("certified continuous (inflation ≤ {} m)", a.certify)
            } else {
                format!("states every {}°", a.resolution)
            },
            settings.range.unwrap_or(derived.range),
            if a.range.is_none() {
                format!(
                    " (= {} m / motion scale {:.4} m)",
                    range::WORKSPACE_STEP,
                    derived.motion.scale
                )
            } else {
                String::new()
            },
            if dynamic_domain > 0.0 {
                format!(
                    "{dynamic_domain:.4}{}",
                    if a.dynamic_domain.is_none() {
                        format!(" (= {} × extent)", range::DOMAIN_PER_EXTENT)
                    } else {
                        String::new()
                    }
                )
            } else {
                "off".into()
            },
            if a.no_balance { "alternating" } else { "balanced" },
            match a.sampler {
                SamplerArg::Uniform => "uniform (seeded)",
                SamplerArg::Halton => "Halton (from its first point)",
            },
            a.padding,
            a.check_resolution,
            if a.no_simplify { "no simplification" } else { "shortcutting on" }
        );
        println!(
            "{:<32} {:>9} {:>4} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9} {:>8} {:>10}",
            "set",
            "solved",
            "inv",
            "median",
            "mean",
            "p95",
            "max",
            "simplify",
            "VAMP med",
            "len raw",
            "len simp",
            "iters",
            "setup"
        );
    }
    for (si, set) in file.sets.iter().enumerate() {
        if !a.sets.is_empty() && !a.sets.contains(&set.name) {
            continue;
        }
        let problems: Vec<&MbmProblem> = set
            .problems
            .iter()
            .filter(|p| p.valid)
            .take(if a.limit == 0 { usize::MAX } else { a.limit })
            .collect();
        let first = runs.len();
        for (pi, p) in problems.iter().enumerate() {
            for trial in 0..a.trials {
                let seed = derive_seed(a.seed, si, pi, trial);
                runs.push(run_problem(&robot, &vars, p, &settings, a, trial, seed)?);
            }
        }
        for (k, run) in runs[first..].iter_mut().enumerate() {
            recheck(&robot, &vars, problems[k / a.trials], a, run)?;
        }
        let vamp = vamp_median(&file.robot, &set.name).filter(|_| !file.generated);
        let refs: Vec<&Run> = runs[first..].iter().collect();
        let s = summarize(&set.name, &refs, vamp);
        print_summary(quiet, &s);
        summaries.push(s);
    }
    let all: Vec<&Run> = runs.iter().collect();
    let overall = summarize(
        "overall",
        &all,
        vamp_median(&file.robot, "overall").filter(|_| !file.generated),
    );
    print_summary(quiet, &overall);
    if !quiet {
        match file.robot.as_str() {
            _ if file.generated => println!("problems made by `manyhands data problems` (MotionBenchMaker-like, benchmark::mbm_gen): no published reference figures apply."),
            "panda" => println!("VAMP 0.6.4 (../shared/benchmarks/mbm/README.md, 699 problems, one core, alternated with manyhands 7f3f3ea): median 72.9 µs, all solved. OMPL RRTConnect: median 5.2 ms."),
            "baxter" => println!("VAMP 0.6.4 (../shared/benchmarks/mbm/README.md, 1 470 problems, one core): 1 398 solved, median 8.09 ms."),
            _ => {}
        }
        println!(
            "times: planning = search + start/goal checks{} (setup of the collision model excluded, shown as 'setup'); collision model: {}; obstacles' cylinders are exact cylinders.",
            if a.revalidate { " + re-validation of the raw path" } else { "" },
            if a.fast_checker { "FastChecker (f64 primitives)" } else { "SphereChecker (f32, 8 lanes) when the robot is made of spheres, else FastChecker" }
        );
        for r in runs.iter().filter(|r| r.invalid) {
            println!(
                "INVALID {}[{}] trial {}: {}",
                r.set,
                r.index,
                r.trial,
                r.error.as_deref().unwrap_or("")
            );
        }
        for r in runs.iter().filter(|r| !r.solved && !r.invalid).take(20) {
            println!(
                "unsolved {}[{}] trial {}: {}",
                r.set,
                r.index,
                r.trial,
                r.error.as_deref().unwrap_or("")
            );
        }
    }
    let outcome = Outcome {
        dof: vars.len(),
        spheres: {
            let empty = MbmProblem {
                obstacles: Vec::new(),
                ..file
                    .sets
                    .iter()
                    .flat_map(|s| s.problems.iter())
                    .next()
                    .context("the problem file has no problem")?
                    .clone()
            };
            match AutoChecker::new(&empty.world(robot.clone()), a.padding) {
                AutoChecker::Spheres(s) => Some(s.sphere_count()),
                AutoChecker::Fast(_) => None,
            }
        },
        range: settings.range.unwrap_or(derived.range),
        runs,
    };
    if inner {
        return Ok(outcome);
    }
    let runs = &outcome.runs;
    let report = json!({
        "robot": file.robot,
        "settings": settings,
        "trials": a.trials,
        "seed": a.seed,
        "time_limit_s": a.time_limit,
        "check_resolution_deg": a.check_resolution,
        "padding_m": a.padding,
        "sets": summaries,
        "overall": overall,
        "runs": runs,
    });
    if ctx.json {
        println!(
            "{}",
            serde_json::to_string_pretty(
                &json!({"sets": report["sets"], "overall": report["overall"]})
            )?
        );
    }
    if let Some(out) = &a.out {
        std::fs::write(out, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    if let Some(path) = &a.ompl_log {
        let text = ompl_log(
            &file,
            &problems,
            a,
            &settings,
            runs,
            started,
            t_all.elapsed().as_secs_f64(),
        );
        std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(outcome)
}

/// The runs as an OMPL benchmark log (grammar: OMPL's `doc/markdown/benchmark.md`, "The
/// benchmark logfile format"): one experiment `mbm_<robot>`, one planner, one line per run.
/// "correct solution" is the exact re-check's verdict; an invalid path is not "solved".
fn ompl_log(
    file: &MbmFile,
    problems: &std::path::Path,
    a: &MbmArgs,
    settings: &RrtConnectSettings,
    runs: &[Run],
    started: String,
    total_s: f64,
) -> String {
    use std::fmt::Write as _;
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .ok()
        .filter(|h| !h.is_empty() && !h.contains(char::is_whitespace))
        .unwrap_or_else(|| "unknown".into());
    let set_names: Vec<&str> = file.sets.iter().map(|s| s.name.as_str()).collect();
    let mut o = String::new();
    let _ = writeln!(o, "manyhands version {}", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(o, "Experiment mbm_{}", file.robot);
    let _ = writeln!(o, "Running on {host}");
    let _ = writeln!(o, "Starting at {started}");
    let _ = writeln!(o, "<<<|");
    let _ = writeln!(
        o,
        "MotionBenchMaker problems {} ({} joints); exact re-check at {} deg",
        problems.display(),
        file.joints.len(),
        a.check_resolution
    );
    let _ = writeln!(o, "|>>>");
    let _ = writeln!(o, "<<<|");
    let _ = writeln!(o, "|>>>");
    let _ = writeln!(o, "{} is the random seed", a.seed);
    let _ = writeln!(o, "{} seconds per run", a.time_limit);
    let _ = writeln!(o, "0 MB per run");
    let _ = writeln!(o, "{} runs per planner", runs.len());
    let _ = writeln!(o, "{total_s} seconds spent to collect the data");
    let _ = writeln!(o, "1 enum types");
    let _ = writeln!(o, "problem set|{}", set_names.join("|"));
    let _ = writeln!(o, "1 planners");
    let _ = writeln!(o, "manyhands_RRTConnect");
    let common = [
        (
            "range",
            settings
                .range
                .map_or("0.2 x extent".into(), |r| r.to_string()),
        ),
        (
            "certify inflation",
            settings.certify.map_or("off".into(), |d| d.to_string()),
        ),
        (
            "dynamic domain",
            settings
                .dynamic_domain
                .map_or("off".into(), |r| r.to_string()),
        ),
        ("balance", settings.balance.to_string()),
        ("sampler", format!("{:?}", settings.sampler).to_lowercase()),
        ("simplify", settings.shortcut.is_some().to_string()),
    ];
    let _ = writeln!(o, "{} common properties", common.len());
    for (k, v) in common {
        let _ = writeln!(o, "{k} = {}", v.replace(' ', "_"));
    }
    let props = [
        "problem set ENUM",
        "problem index INTEGER",
        "seed INTEGER",
        "time REAL",
        "solved BOOLEAN",
        "correct solution BOOLEAN",
        "simplification time REAL",
        "solution length REAL",
        "simplified solution length REAL",
        "simplified solution segments INTEGER",
        "iterations INTEGER",
        "collision checks INTEGER",
        "graph states INTEGER",
        "setup time REAL",
    ];
    let _ = writeln!(o, "{} properties for each run", props.len());
    for p in props {
        let _ = writeln!(o, "{p}");
    }
    let _ = writeln!(o, "{} runs", runs.len());
    let real = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{v}")
        }
    };
    for r in runs {
        let set = set_names.iter().position(|n| *n == r.set).unwrap_or(0);
        let planned = !r.plan_us.is_nan() && (r.solved || r.invalid);
        let fields = [
            set.to_string(),
            r.index.to_string(),
            r.seed.to_string(),
            real(r.plan_us / 1e6),
            u8::from(r.solved).to_string(),
            if planned {
                u8::from(r.solved).to_string()
            } else {
                String::new()
            },
            real(r.simplify_us / 1e6),
            real(r.length_raw),
            real(r.length_simplified),
            if planned {
                r.vertices.saturating_sub(1).to_string()
            } else {
                String::new()
            },
            r.iterations.to_string(),
            r.collision_checks.to_string(),
            (r.start_tree + r.goal_tree).to_string(),
            real(r.setup_us / 1e6),
        ];
        for f in fields {
            let _ = write!(o, "{f}; ");
        }
        o.push('\n');
    }
    o.push_str(".\n");
    o
}

fn print_summary(quiet: bool, s: &Summary) {
    if quiet {
        return;
    }
    println!(
        "{:<32} {:>9} {:>4} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9.2} {:>9.2} {:>8.0} {:>10}",
        s.set,
        format!("{}/{}", s.solved, s.runs),
        s.invalid,
        fmt_us(s.median_us),
        fmt_us(s.mean_us),
        fmt_us(s.p95_us),
        fmt_us(s.max_us),
        fmt_us(s.simplify_median_us),
        s.vamp_median_us.map(fmt_us).unwrap_or_else(|| "—".into()),
        s.length_raw_median,
        s.length_simplified_median,
        s.iterations_median,
        fmt_us(s.setup_median_us),
    );
}

/// The current UTC time as `YYYY-MM-DD HH:MM:SS UTC` (civil date from days since the epoch,
/// H. Hinnant's algorithm), for the OMPL log's "Starting at" line.
fn chrono_like_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}
