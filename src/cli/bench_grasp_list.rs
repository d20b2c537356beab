//! `manyhands bench grasp-list`: the offline cost of paper 003's single-grasp lists (§IV-A),
//! one list per hand built from scratch (no cache) `--runs` times with seeds 1..=runs; median,
//! min and max seconds per hand beside 003's "about 1 min" and this project's ≤ 1 s target.

use std::time::Instant;

use anyhow::{anyhow, Result};
use clap::Args;
use serde_json::json;

use manyhands::grasp::list::workspace_params;
use manyhands::grasp::{build_grasp_list, Hand};

use super::commands::Ctx;
use super::grasp::{mesh_object, ListParamArgs};

#[derive(Args, Debug)]
pub struct GraspListBenchArgs {
    /// Robot (name in robots/ or a .urdf path).
    #[arg(long, default_value = "justin")]
    pub robot: String,
    /// Hand groups, comma-separated.
    #[arg(long, default_value = "right_hand,left_hand")]
    pub hands: String,
    /// The object: a mesh file or the name of one in the scenes folder's meshes/.
    #[arg(long, default_value = "statuette")]
    pub mesh: String,
    /// Builds per hand (seed = run number unless --seed is given).
    #[arg(long, default_value_t = 5)]
    pub runs: u64,
    #[command(flatten)]
    pub params: ListParamArgs,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

pub fn run(ctx: &Ctx, a: &GraspListBenchArgs) -> Result<()> {
    let base = a.params.params()?;
    let robot = ctx.robot(&a.robot)?;
    let object = mesh_object(ctx, &a.mesh)?;
    let mut rows = Vec::new();
    for group in a.hands.split(',').map(str::trim) {
        let mut secs = Vec::new();
        let mut grasps = Vec::new();
        for run in 1..=a.runs.max(1) {
            let mut p = base.clone();
            if a.params.seed.is_none() {
                p.seed = run;
            }
            let t0 = Instant::now();
            // The hand (its workspace spheres, 003 Alg. 1) is part of the offline cost.
            let hand = Hand::new(
                robot.clone(),
                group,
                p.fingers.as_deref(),
                &workspace_params(&p),
            )
            .map_err(|e| anyhow!("{e}"))?;
            let l = build_grasp_list(&hand, &object, &p, &|_, _| {}, &|| false)
                .map_err(|e| anyhow!("{e}"))?;
            secs.push(t0.elapsed().as_secs_f64());
            grasps.push(l.grasps.len() as f64);
        }
        let (lo, hi) = (
            secs.iter().copied().fold(f64::INFINITY, f64::min),
            secs.iter().copied().fold(0.0f64, f64::max),
        );
        let med = median(&mut secs.clone());
        let g = median(&mut grasps);
        rows.push(
            json!({"hand": group, "runs": secs.len(), "median_s": med, "min_s": lo,
            "max_s": hi, "median_grasps": g}),
        );
    }
    let v = json!({"robot": a.robot, "object": a.mesh, "params": base, "rows": rows,
        "target_s": 1.0, "paper_s": 60.0});
    ctx.print(&v, || {
        let mut t = format!(
            "single-grasp list, {} × {} ({} positions × {} orientations), median over {} seeded builds:\n",
            a.robot,
            a.mesh,
            base.positions,
            manyhands::grasp::so3_grid::so3_grid_len(base.orientation_level),
            a.runs.max(1)
        );
        t += &format!(
            "  {:<12} {:>10} {:>10} {:>10} {:>8}   target ≤ 1 s [paper: about 1 min]\n",
            "hand", "median s", "min s", "max s", "grasps"
        );
        for r in &rows {
            t += &format!(
                "  {:<12} {:>10.3} {:>10.3} {:>10.3} {:>8}\n",
                r["hand"].as_str().unwrap_or(""),
                r["median_s"].as_f64().unwrap_or(f64::NAN),
                r["min_s"].as_f64().unwrap_or(f64::NAN),
                r["max_s"].as_f64().unwrap_or(f64::NAN),
                r["median_grasps"].as_f64().unwrap_or(0.0)
            );
        }
        t.trim_end().to_string()
    });
    Ok(())
}
