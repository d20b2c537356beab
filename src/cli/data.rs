//! `manyhands data mbm`: fetches the MotionBenchMaker problem sets (Panda, Baxter) from their
//! public source into the cache, checks them and converts what needs converting
//! (`manyhands::benchmark::mbm_data`).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use manyhands::benchmark::mbm_data::{self, FetchProgress};

use super::commands::Ctx;

#[derive(Subcommand, Debug)]
pub enum DataCmd {
    /// The MotionBenchMaker sets: `resources/` of the vamp-planner 0.6.4 source package (PyPI,
    /// Apache-2.0), downloaded with `python3 -m pip download`, sha256-checked, problems converted
    /// to problems.json. Into $MANYHANDS_CACHE_DIR/mbm, else $XDG_CACHE_HOME/manyhands/mbm, else
    /// ~/.cache/manyhands/mbm.
    Mbm(MbmDataArgs),
    /// MotionBenchMaker-like problems for any robot (`benchmark::mbm_gen`): box, cage, shelf and table
    /// scenes scaled to its reach, start and goal with the end effector inside them, written as
    /// problems.json for `manyhands bench mbm --robot URDF --problems FILE`.
    Problems(ProblemsArgs),
}

#[derive(Args, Debug)]
pub struct ProblemsArgs {
    /// The robot's URDF (its SRDF beside it, or --srdf).
    #[arg(long)]
    pub robot: PathBuf,
    #[arg(long)]
    pub srdf: Option<PathBuf>,
    /// Joints to plan (comma-separated; default all the robot's variables).
    #[arg(long, value_delimiter = ',')]
    pub joints: Vec<String>,
    /// Problems per set (box, cage, shelf, table), 1–1000.
    #[arg(long, default_value_t = 20)]
    pub per_set: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RRT-Connect's iterations to solve a problem for it to be marked valid (1–10⁷).
    #[arg(long, default_value_t = 20_000)]
    pub solve_iterations: u64,
    /// Output file (problems.json format).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Args, Debug)]
pub struct MbmDataArgs {
    /// Write the data folder here instead of the cache (tests and `bench mbm` then need
    /// MANYHANDS_MBM_DIR=DIR).
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Use this vamp_planner-0.6.4.tar.gz instead of downloading it (its sha256 is checked).
    #[arg(long)]
    pub sdist: Option<PathBuf>,
    /// Fetch again even when the folder is already complete.
    #[arg(long)]
    pub force: bool,
}

/// indicatif bars for the fetch stages: a spinner with pip's last line while it downloads,
/// bars of bytes or problems where the total is known.
struct Bars {
    bar: Option<ProgressBar>,
    hidden: bool,
}

impl Bars {
    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish();
        }
    }
}

impl FetchProgress for Bars {
    fn stage(&mut self, what: &str, total: Option<u64>) {
        self.finish();
        let bar = match total {
            _ if self.hidden => ProgressBar::hidden(),
            Some(n) => {
                let b = ProgressBar::new(n);
                let unit = if what == "sha256" || what == "unpack" {
                    "{bytes}/{total_bytes}"
                } else {
                    "{pos}/{len}"
                };
                b.set_style(
                    ProgressStyle::with_template(&format!(
                        "{{msg:32}} [{{bar:30}}] {unit} {{elapsed}}"
                    ))
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> "),
                );
                b
            }
            None => {
                let b = ProgressBar::new_spinner();
                b.set_style(
                    ProgressStyle::with_template("{spinner} {msg} {elapsed}")
                        .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                );
                b.enable_steady_tick(Duration::from_millis(120));
                b
            }
        };
        bar.set_message(what.to_string());
        self.bar = Some(bar);
    }

    fn advance(&mut self, n: u64) {
        if let Some(b) = &self.bar {
            b.inc(n);
        }
    }

    fn note(&mut self, line: &str) {
        if let Some(b) = &self.bar {
            if !line.is_empty() {
                let short: String = line.chars().take(90).collect();
                b.set_message(format!("pip: {short}"));
            }
        }
    }
}

fn folder_bytes(dir: &Path) -> u64 {
    let mut n = 0;
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                n += folder_bytes(&p);
            } else if let Ok(m) = e.metadata() {
                n += m.len();
            }
        }
    }
    n
}

pub fn run(ctx: &Ctx, cmd: &DataCmd) -> Result<()> {
    match cmd {
        DataCmd::Mbm(a) => mbm(ctx, a),
        DataCmd::Problems(a) => problems(ctx, a),
    }
}

fn problems(ctx: &Ctx, a: &ProblemsArgs) -> Result<()> {
    use manyhands::benchmark::mbm_gen;
    if !(1..=1000).contains(&a.per_set) {
        bail!("--per-set must be within 1..=1000, got {}", a.per_set);
    }
    if !(1..=10_000_000).contains(&a.solve_iterations) {
        bail!("--solve-iterations must be within 1..=10000000");
    }
    let srdf = a.srdf.clone().or_else(|| {
        let p = a.robot.with_extension("srdf");
        p.is_file().then_some(p)
    });
    let robot = manyhands::Robot::from_files(&a.robot, srdf.as_deref())
        .with_context(|| format!("loading {}", a.robot.display()))?;
    let t0 = Instant::now();
    let (file, stats) = mbm_gen::generate(
        std::sync::Arc::new(robot),
        &a.joints,
        &mbm_gen::GenSettings {
            per_set: a.per_set,
            seed: a.seed,
            solve_iterations: a.solve_iterations,
        },
    )?;
    std::fs::write(&a.out, serde_json::to_string_pretty(&file)?)
        .with_context(|| format!("writing {}", a.out.display()))?;
    if ctx.json {
        println!(
            "{}",
            serde_json::json!({"out": a.out, "stats": stats, "generator": file["generator"]})
        );
    } else {
        println!(
            "{}: {} problems ({} valid: solved by RRT-Connect within {} iterations) in {} scenes, {} configurations drawn, {:.1} s; reach {:.3} m, tip {}",
            a.out.display(),
            stats.problems,
            stats.valid,
            a.solve_iterations,
            stats.scenes_drawn,
            stats.configurations_drawn,
            t0.elapsed().as_secs_f64(),
            file["generator"]["reach_m"].as_f64().unwrap_or(f64::NAN),
            file["generator"]["tip_link"].as_str().unwrap_or("?"),
        );
    }
    Ok(())
}

fn mbm(ctx: &Ctx, a: &MbmDataArgs) -> Result<()> {
    let dest = match &a.dir {
        Some(d) => d.clone(),
        None => mbm_data::cache_dir().context(
            "no cache folder: set MANYHANDS_CACHE_DIR, XDG_CACHE_HOME or HOME, or pass --dir",
        )?,
    };
    let t0 = Instant::now();
    if !a.force && mbm_data::missing_file(&dest).is_none() {
        let bytes = folder_bytes(&dest);
        report(ctx, &dest, bytes, None, t0.elapsed(), a.dir.is_some(), true);
        return Ok(());
    }
    let mut bars = Bars {
        bar: None,
        hidden: ctx.json,
    };
    let tmp = std::env::temp_dir().join(format!("manyhands-sdist-{}", std::process::id()));
    let result = (|| -> Result<mbm_data::InstallReport> {
        let sdist = match &a.sdist {
            Some(f) => {
                if !f.is_file() {
                    bail!("--sdist {}: no such file", f.display());
                }
                f.clone()
            }
            None => mbm_data::download_sdist(&tmp, &mut bars)?,
        };
        Ok(mbm_data::install_from_sdist(&sdist, &dest, &mut bars)?)
    })();
    bars.finish();
    let _ = std::fs::remove_dir_all(&tmp);
    let r = result?;
    report(
        ctx,
        &r.dir,
        r.bytes,
        Some(&r.robots),
        t0.elapsed(),
        a.dir.is_some(),
        false,
    );
    Ok(())
}

fn report(
    ctx: &Ctx,
    dir: &Path,
    bytes: u64,
    robots: Option<&[(String, usize, usize)]>,
    took: Duration,
    custom_dir: bool,
    already: bool,
) {
    if ctx.json {
        let v = serde_json::json!({
            "dir": dir.display().to_string(),
            "bytes": bytes,
            "seconds": took.as_secs_f64(),
            "already_there": already,
            "robots": robots.map(|rs| rs.iter().map(|(r, n, v)| serde_json::json!({"robot": r, "problems": n, "valid": v})).collect::<Vec<_>>()),
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return;
    }
    if already {
        println!(
            "MotionBenchMaker data already in {} ({:.1} MB; --force fetches again)",
            dir.display(),
            bytes as f64 / 1e6
        );
    } else {
        println!(
            "MotionBenchMaker data in {} ({:.1} MB, {:.1} s)",
            dir.display(),
            bytes as f64 / 1e6,
            took.as_secs_f64()
        );
    }
    for (r, n, v) in robots.unwrap_or_default() {
        println!("  {r}: {n} problems, {v} valid");
    }
    if custom_dir {
        println!(
            "  (not the cache: set {}={} for the tests and `bench mbm --robot NAME`)",
            mbm_data::MBM_DIR_ENV,
            dir.display()
        );
    }
}
