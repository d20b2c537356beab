//! `manyhands bench timing`: median µs to time a path (TOPP-RA on the polyline,
//! [`manyhands::trajectory::timing`]) — the kitchen task's plan (000 §VI-C, planned once here,
//! every variable of the scene, at rest at its grasps and releases) and 100-waypoint random
//! paths of a Panda-like 7-DoF arm (libfranka's published velocity and acceleration limits) —
//! alone and with sampling at 10 ms. A benchmark, not a test: the target (≤ 200 µs for the
//! 100-waypoint path, issue 25) is printed beside the median.

use std::time::Instant;

use anyhow::Result;
use clap::Args;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::json;

use super::super::commands::Ctx;
use manyhands::collision::CollisionWorld;
use manyhands::planning::tasks::task::{kitchen_task, KitchenTask};
use manyhands::planning::Termination;
use manyhands::trajectory::timing::{
    time_polyline, world_limits, TimingLimits, DEFAULT_SAMPLE_PERIOD,
};

#[derive(Args, Debug)]
pub struct TimingBenchArgs {
    /// Timed runs per row (each on its own seeded path for the random rows).
    #[arg(long, default_value_t = 2000)]
    pub runs: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Scene of the kitchen task.
    #[arg(long, default_value = "kitchen")]
    pub scene: String,
}

fn median_mean(mut t: Vec<f64>) -> (f64, f64) {
    let mean = t.iter().sum::<f64>() / t.len().max(1) as f64;
    t.sort_by(|a, b| a.total_cmp(b));
    (t.get(t.len() / 2).copied().unwrap_or(0.0), mean)
}

/// (median, mean) µs of `f` over `runs` calls, each given its run index.
fn time_runs(runs: usize, mut f: impl FnMut(usize)) -> (f64, f64) {
    for i in 0..runs.min(50) {
        f(i);
    }
    let t = (0..runs)
        .map(|i| {
            let s = Instant::now();
            f(i);
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    median_mean(t)
}

pub fn run(ctx: &Ctx, a: &TimingBenchArgs) -> Result<()> {
    let runs = a.runs.max(1);
    let mut rows = Vec::new();
    // The kitchen task's path, planned once (seeded; no reachability grids).
    let scene = ctx.scene(&a.scene)?;
    let plan = kitchen_task(
        &scene,
        &KitchenTask::armar_wok(),
        &mut Termination::new().with_time_limit(std::time::Duration::from_secs(60)),
        a.seed,
    )?;
    let world = CollisionWorld::from_scene(&scene);
    let limits = world_limits(&world);
    let rest: Vec<usize> = plan.events.iter().map(|e| e.waypoint).collect();
    let wps = &plan.waypoints;
    let timed = time_polyline(wps, &limits, &rest)?;
    let note = format!(
        "{} waypoints × {} variables, {:.2} s trajectory",
        wps.len(),
        limits.velocity.len(),
        timed.duration
    );
    let (m, mean) = time_runs(runs, |_| {
        std::hint::black_box(time_polyline(wps, &limits, &rest).map(|t| t.duration).ok());
    });
    rows.push(("kitchen task: parameterise", m, mean, note.clone(), "-"));
    let (m, mean) = time_runs(runs, |_| {
        let t = time_polyline(wps, &limits, &rest).ok();
        std::hint::black_box(t.and_then(|t| t.sample(DEFAULT_SAMPLE_PERIOD, "").ok()));
    });
    rows.push((
        "kitchen task: parameterise + sample 10 ms",
        m,
        mean,
        note,
        "-",
    ));
    // Panda-like 7-DoF: 100 random waypoints per run within the Panda's joint ranges.
    let lo = [
        -2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973,
    ];
    let hi = [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973];
    let panda = TimingLimits {
        velocity: vec![2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61],
        acceleration: vec![15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
    };
    let paths: Vec<Vec<Vec<f64>>> = (0..runs)
        .map(|i| {
            let mut rng = ChaCha8Rng::seed_from_u64(a.seed.wrapping_add(i as u64));
            (0..100)
                .map(|_| (0..7).map(|j| rng.random_range(lo[j]..hi[j])).collect())
                .collect()
        })
        .collect();
    let mean_duration = paths
        .iter()
        .filter_map(|p| time_polyline(p, &panda, &[]).ok())
        .map(|t| t.duration)
        .sum::<f64>()
        / runs as f64;
    let note = format!("100 waypoints × 7, mean {mean_duration:.1} s trajectory");
    let (m, mean) = time_runs(runs, |i| {
        std::hint::black_box(
            time_polyline(&paths[i], &panda, &[])
                .map(|t| t.duration)
                .ok(),
        );
    });
    rows.push((
        "panda-like 100 waypoints: parameterise",
        m,
        mean,
        note.clone(),
        "≤ 200 µs",
    ));
    let (m, mean) = time_runs(runs, |i| {
        let t = time_polyline(&paths[i], &panda, &[]).ok();
        std::hint::black_box(t.and_then(|t| t.sample(DEFAULT_SAMPLE_PERIOD, "").ok()));
    });
    rows.push((
        "panda-like 100 waypoints: + sample 10 ms",
        m,
        mean,
        note,
        "-",
    ));
    if ctx.json {
        let v: Vec<_> = rows
            .iter()
            .map(|(w, m, mean, note, target)| {
                json!({"what": w, "median_us": m, "mean_us": mean, "n": runs, "note": note, "target": target})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{:<44} {:>12} {:>12} {:>7}  {:<10} note",
            "measurement", "median", "mean", "n", "target"
        );
        for (w, m, mean, note, target) in rows {
            println!(
                "{w:<44} {:>9.1} µs {:>9.1} µs {runs:>7}  {target:<10} {note}",
                m, mean
            );
        }
    }
    Ok(())
}
