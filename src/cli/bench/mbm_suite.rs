//! `manyhands bench mbm --suite generality`: the MotionBenchMaker Panda (when its data is
//! found) and every robot of the generality suite (`benchmarks/generality/*/`: a spherized
//! URDF, its SRDF and a `problems.json` from `manyhands data problems`), each planned twice with
//! the same settings and seeds — certified (the product's checks) and without the certificate
//! (`--uncertified`, benchmark only) — every path re-checked by the exact checker. One line per
//! robot: what the search costs, what the certificate costs in it, and what it buys (the
//! invalid paths of the uncertified search).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::json;

use manyhands::benchmark::mbm_data;

use super::super::commands::Ctx;
use super::mbm::{run_one, MbmArgs, Outcome, Run};

/// `--suite` of `bench mbm`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Suite {
    /// The Panda beside robots of other shapes (benchmarks/generality/).
    Generality,
}

/// The default folder of the generality suite, from the working directory.
pub const GENERALITY_DIR: &str = "benchmarks/generality";

/// A suite member: its name and the `--robot` / `--problems` to plan it with.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    pub name: String,
    pub robot: PathBuf,
    pub problems: Option<PathBuf>,
}

/// The robot folders of `dir`: each sub-folder with a `problems.json` and one URDF (a
/// `*_spherized.urdf` preferred when there are several), in name order.
pub fn suite_members(dir: &Path) -> Result<Vec<Member>> {
    let mut out = Vec::new();
    let entries = std::fs::read_dir(dir)
        .with_context(|| format!("reading the suite folder {}", dir.display()))?;
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for d in dirs {
        let problems = d.join("problems.json");
        if !problems.is_file() {
            continue;
        }
        let mut urdfs: Vec<PathBuf> = std::fs::read_dir(&d)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "urdf"))
            .collect();
        urdfs.sort();
        let spherized: Vec<&PathBuf> = urdfs
            .iter()
            .filter(|p| {
                p.file_stem()
                    .and_then(|s| s.to_str())
                    .is_some_and(|s| s.ends_with("_spherized"))
            })
            .collect();
        let urdf = match (spherized.as_slice(), urdfs.as_slice()) {
            ([one], _) => (*one).clone(),
            ([], [one]) => one.clone(),
            _ => bail!(
                "{}: a suite folder needs one URDF (or one *_spherized.urdf), found {}",
                d.display(),
                urdfs.len()
            ),
        };
        out.push(Member {
            name: d
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            robot: urdf,
            problems: Some(problems),
        });
    }
    Ok(out)
}

/// One robot's line of the suite.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Line {
    pub robot: String,
    pub dof: usize,
    pub spheres: Option<usize>,
    pub range: f64,
    pub problems: usize,
    pub solved: usize,
    pub invalid: usize,
    pub median_us: f64,
    pub iterations_median: f64,
    /// Certified motion checks (first passes) per RRT-Connect iteration, over all solved runs.
    pub checks_per_iteration: f64,
    /// 8-lane refinement calls per certified motion check, over all solved runs.
    pub refinements_per_check: f64,
    /// The same search without the certificate (`--uncertified`).
    pub uncertified_solved: usize,
    pub uncertified_invalid: usize,
    pub uncertified_median_us: f64,
    pub uncertified_iterations_median: f64,
    /// `1 − uncertified median / certified median`: the certificate's share of the planning
    /// time (inflated first passes and refinement of tight path edges).
    pub certificate_share: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The suite line of a robot from its certified and uncertified outcomes.
pub(super) fn line(name: &str, cert: &Outcome, unc: &Outcome) -> Line {
    let solved = |r: &&Run| r.solved;
    let ok: Vec<&Run> = cert.runs.iter().filter(solved).collect();
    let uok: Vec<&Run> = unc.runs.iter().filter(solved).collect();
    let iterations: u64 = ok.iter().map(|r| r.iterations).sum();
    let (segments, refinements) = ok
        .iter()
        .filter_map(|r| r.certify_counts)
        .fold((0u64, 0u64), |(s, f), c| {
            (s + c.segments, f + c.refinements)
        });
    let ratio = |a: u64, b: u64| {
        if b == 0 {
            f64::NAN
        } else {
            a as f64 / b as f64
        }
    };
    let median_us = median(ok.iter().map(|r| r.plan_us).collect());
    let uncertified_median_us = median(uok.iter().map(|r| r.plan_us).collect());
    Line {
        robot: name.to_string(),
        dof: cert.dof,
        spheres: cert.spheres,
        range: cert.range,
        problems: cert.runs.len(),
        solved: ok.len(),
        invalid: cert.runs.iter().filter(|r| r.invalid).count(),
        median_us,
        iterations_median: median(ok.iter().map(|r| r.iterations as f64).collect()),
        checks_per_iteration: ratio(segments, iterations),
        refinements_per_check: ratio(refinements, segments),
        uncertified_solved: uok.len(),
        uncertified_invalid: unc.runs.iter().filter(|r| r.invalid).count(),
        uncertified_median_us,
        uncertified_iterations_median: median(uok.iter().map(|r| r.iterations as f64).collect()),
        certificate_share: 1.0 - uncertified_median_us / median_us,
    }
}

fn us(v: f64) -> String {
    if v.is_nan() {
        "—".into()
    } else if v < 1000.0 {
        format!("{v:.1} µs")
    } else {
        format!("{:.2} ms", v / 1e3)
    }
}

pub fn run(ctx: &Ctx, a: &MbmArgs, suite: Suite) -> Result<()> {
    let Suite::Generality = suite;
    let dir = a
        .suite_dir
        .clone()
        .unwrap_or_else(|| PathBuf::from(GENERALITY_DIR));
    let mut members = Vec::new();
    match mbm_data::locate() {
        Ok(_) => members.push(Member {
            name: "panda".into(),
            robot: PathBuf::from("panda"),
            problems: None,
        }),
        Err(why) if !ctx.json => {
            println!("(no MotionBenchMaker Panda: {why})")
        }
        Err(_) => {}
    }
    members.extend(suite_members(&dir)?);
    if members.is_empty() {
        bail!(
            "the suite has no robot: no MotionBenchMaker data and no robot folder in {}",
            dir.display()
        );
    }
    if !ctx.json {
        println!(
            "generality suite: {} robots, RRT-Connect as `bench mbm` (derived range and dynamic domain, balanced trees, eager certification), no simplification, seed {}, {} trial(s); each planned certified and without the certificate (benchmark only); every path re-checked exactly at {}°",
            members.len(),
            a.seed,
            a.trials,
            a.check_resolution
        );
        println!(
            "{:<12} {:>4} {:>5} {:>6} {:>9} {:>4} {:>10} {:>7} {:>11} {:>11} {:>6} | {:>9} {:>4} {:>10} {:>7}",
            "robot",
            "dof",
            "sph",
            "range",
            "solved",
            "inv",
            "median",
            "iters",
            "checks/it",
            "refine/chk",
            "cert%",
            "solved",
            "inv",
            "median",
            "iters"
        );
    }
    let mut lines = Vec::new();
    for m in &members {
        let mut base = a.clone();
        base.suite = None;
        base.robot = Some(m.robot.clone());
        base.problems = m.problems.clone();
        base.srdf = None;
        base.no_simplify = true;
        base.out = None;
        base.ompl_log = None;
        base.uncertified = false;
        let cert = run_one(ctx, &base, true).with_context(|| format!("robot {}", m.name))?;
        base.uncertified = true;
        let unc = run_one(ctx, &base, true).with_context(|| format!("robot {}", m.name))?;
        let l = line(&m.name, &cert, &unc);
        if !ctx.json {
            println!(
                "{:<12} {:>4} {:>5} {:>6.3} {:>9} {:>4} {:>10} {:>7.1} {:>11.2} {:>11.2} {:>5.1}% | {:>9} {:>4} {:>10} {:>7.1}",
                l.robot,
                l.dof,
                l.spheres.map_or("—".into(), |s| s.to_string()),
                l.range,
                format!("{}/{}", l.solved, l.problems),
                l.invalid,
                us(l.median_us),
                l.iterations_median,
                l.checks_per_iteration,
                l.refinements_per_check,
                100.0 * l.certificate_share,
                format!("{}/{}", l.uncertified_solved, l.problems),
                l.uncertified_invalid,
                us(l.uncertified_median_us),
                l.uncertified_iterations_median,
            );
        }
        lines.push(l);
    }
    if ctx.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({ "robots": lines }))?
        );
    } else {
        println!("left: certified (the product's checks); right: the same search without the certificate (benchmark only). median = planning time over solved problems; iters = RRT-Connect iterations (median); checks/it = certified motion checks per iteration; refine/chk = 8-lane refinement calls per certified check; cert% = 1 − uncertified / certified median; inv = paths the exact re-check rejects.");
    }
    Ok(())
}
