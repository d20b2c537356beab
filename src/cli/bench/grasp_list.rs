//! `manyhands bench grasp-list`: paper 003's single-grasp lists (§IV-A), one list per hand
//! built from scratch (no cache) `--runs` times with seeds 1..=runs: per hand the median, min
//! and max build seconds beside 003's "about 1 min" and this project's ≤ 2 s target, the list
//! size (median and smallest) beside 003's 17 (right hand) and 22 (left hand) grasps, the
//! diversity of the lists (the smallest separation between two grasps of one list, which the
//! list keeps at or above its near-duplicate distance, and the number of distinct contact-finger
//! sets), the ε range, and where the frames' searches stop (the list's stats, summed over the
//! runs).

use std::time::Instant;

use anyhow::{anyhow, Result};
use clap::Args;
use serde_json::json;

use manyhands::grasp::list::workspace_params;
use manyhands::grasp::{build_grasp_list, separation, GraspListStats, Hand};

use super::super::commands::Ctx;
use super::super::grasp::{mesh_object, ListParamArgs};

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

/// The smallest separation between two grasps of a list (infinite below two grasps) and the
/// number of distinct contact-finger sets.
fn diversity(l: &manyhands::grasp::GraspList) -> (f64, usize) {
    let mut min = f64::INFINITY;
    for (i, a) in l.grasps.iter().enumerate() {
        for b in &l.grasps[i + 1..] {
            min = min.min(separation(a, b));
        }
    }
    let mut sets: Vec<Vec<&str>> = l
        .grasps
        .iter()
        .map(|g| g.contacts.iter().map(|c| c.finger.as_str()).collect())
        .collect();
    sets.sort();
    sets.dedup();
    (min, sets.len())
}

fn add_stats(a: &mut GraspListStats, b: &GraspListStats) {
    a.frames += b.frames;
    a.palm_free += b.palm_free;
    a.thumb_contacts += b.thumb_contacts;
    a.candidates += b.candidates;
    a.force_closure += b.force_closure;
    a.closures += b.closures;
    a.closure_candidates += b.closure_candidates;
    a.one_sided += b.one_sided;
    a.duplicates += b.duplicates;
    a.min_separation = b.min_separation;
    if a.finger_contacts.len() < b.finger_contacts.len() {
        a.finger_contacts.resize(b.finger_contacts.len(), 0);
    }
    for (x, y) in a.finger_contacts.iter_mut().zip(&b.finger_contacts) {
        *x += y;
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
        let mut stats = GraspListStats::default();
        let (mut sep, mut sets) = (f64::INFINITY, usize::MAX);
        let (mut eps_lo, mut eps_hi) = (f64::INFINITY, 0.0f64);
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
            add_stats(&mut stats, &l.stats);
            let (s, k) = diversity(&l);
            sep = sep.min(s);
            sets = sets.min(k);
            for g in &l.grasps {
                eps_lo = eps_lo.min(g.epsilon);
                eps_hi = eps_hi.max(g.epsilon);
            }
        }
        let (lo, hi) = (
            secs.iter().copied().fold(f64::INFINITY, f64::min),
            secs.iter().copied().fold(0.0f64, f64::max),
        );
        let med = median(&mut secs.clone());
        let fewest = grasps.iter().copied().fold(f64::INFINITY, f64::min);
        let g = median(&mut grasps);
        rows.push(
            json!({"hand": group, "runs": secs.len(), "median_s": med, "min_s": lo,
            "max_s": hi, "median_grasps": g, "min_grasps": fewest,
            "min_separation_m": sep.is_finite().then_some(sep),
            "near_duplicate_m": stats.min_separation, "fewest_finger_sets": sets,
            "epsilon_min": eps_lo.is_finite().then_some(eps_lo), "epsilon_max": eps_hi,
            "stats": stats}),
        );
    }
    let v = json!({"robot": a.robot, "object": a.mesh, "params": base, "rows": rows,
        "target_s": 2.0, "paper_s": 60.0, "paper_grasps": {"right": 17, "left": 22}});
    ctx.print(&v, || {
        let mut t = format!(
            "single-grasp list, {} × {} ({} positions × {} orientations), over {} seeded builds:\n",
            a.robot,
            a.mesh,
            base.positions,
            manyhands::grasp::so3_grid::so3_grid_len(base.orientation_level),
            a.runs.max(1)
        );
        t += &format!(
            "  {:<12} {:>9} {:>7} {:>7} {:>7} {:>7} {:>10} {:>6} {:>19}\n",
            "hand", "median s", "min s", "max s", "grasps", "fewest", "min sep mm", "sets",
            "ε range"
        );
        let f = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap_or(f64::NAN);
        for r in &rows {
            t += &format!(
                "  {:<12} {:>9.3} {:>7.3} {:>7.3} {:>7} {:>7} {:>10.1} {:>6} {:>9.5}–{:<9.5}\n",
                r["hand"].as_str().unwrap_or(""),
                f(r, "median_s"),
                f(r, "min_s"),
                f(r, "max_s"),
                f(r, "median_grasps"),
                f(r, "min_grasps"),
                f(r, "min_separation_m") * 1e3,
                r["fewest_finger_sets"].as_u64().unwrap_or(0),
                f(r, "epsilon_min"),
                f(r, "epsilon_max"),
            );
        }
        t += &format!(
            "  target ≤ 2 s per hand on the machine's cores; near-duplicates (same fingers, palm and \
             contacts all within {:.1} mm) are dropped, so min sep ≥ that\n",
            rows.first()
                .map_or(f64::NAN, |r| f(r, "near_duplicate_m") * 1e3)
        );
        t += "  [paper 003: 17 grasps (right hand), 22 (left hand), about 1 min each]\n";
        t += "  where the searches stop (summed over the runs):\n";
        for r in &rows {
            let s = &r["stats"];
            let u = |k: &str| s[k].as_u64().unwrap_or(0);
            t += &format!(
                "  {:<12} frames {} → palm free {} → thumb contact {} → ≥ 3 contacts {} → force \
                 closure {} → kept {} ({} near-duplicates); closures {}: ≥ 3 contacts {}, \
                 one-sided {}; contacts per finger {}\n",
                r["hand"].as_str().unwrap_or(""),
                u("frames"),
                u("palm_free"),
                u("thumb_contacts"),
                u("candidates"),
                u("force_closure"),
                u("force_closure") - u("duplicates"),
                u("duplicates"),
                u("closures"),
                u("closure_candidates"),
                u("one_sided"),
                s["finger_contacts"]
            );
        }
        t.trim_end().to_string()
    });
    Ok(())
}
