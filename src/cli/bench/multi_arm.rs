//! `manyhands bench multi-arm`: the multi-arm planner (src/planning/planners/multi_arm/) on seeded
//! crossing tasks in the VAMP-MR cells (src/benchmark/multi_arm_cells.rs, over the
//! MotionBenchMaker Panda that `manyhands data mbm` installs): per cell, success within the
//! time limit, median planning time, the methods that succeeded and the makespan before and
//! after shortcutting, for the automatic choice beside decoupled-only (each arm alone, then the
//! phase-space schedule) and composite-only (RRT-Connect in the joint space of all arms).
//! Every plan of the automatic choice is re-checked with the exact checker, all arms moving
//! together, at most 0.005 rad of any joint between two checked states.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use clap::Args;

use manyhands::benchmark::multi_arm_cells::{crossing_task, vamp_mr, CrossingSettings, VampMrCell};
use manyhands::collision::{CollisionChecker, CollisionWorld, ExactChecker};
use manyhands::planning::planners::multi_arm::{
    plan_multi_arm, Arm, Methods, MultiArmPlan, MultiArmProblem, MultiArmSettings,
};
use manyhands::planning::Termination;

use super::super::commands::Ctx;

#[derive(Args, Debug)]
pub struct MultiArmBenchArgs {
    /// Crossing tasks per cell (seeds `seed`, `seed + 1`, …).
    #[arg(long, default_value_t = 30)]
    pub tasks: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seconds per query.
    #[arg(long, default_value_t = 5.0)]
    pub time_limit: f64,
    /// Cells (default: all three): panda_two_rod, panda_four, panda_four_bins.
    #[arg(long = "cell", value_delimiter = ',')]
    pub cells: Vec<String>,
    /// After the decoupled method failed, try the composite search over the arms in conflict
    /// before prioritized planning (the planner's `composite_first` setting).
    #[arg(long)]
    pub composite_first: bool,
    /// Iteration budget of the phase-space scheduler (default: the planner's).
    #[arg(long)]
    pub phase_iterations: Option<u64>,
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The exact re-check (module documentation): the number of colliding checked states.
fn penetrations(p: &MultiArmProblem, plan: &MultiArmPlan) -> usize {
    let mut exact = ExactChecker::new(&p.world);
    let vars = p.vars();
    let mut bad = 0;
    let mut q = p.world_q.clone();
    for w in plan.path.windows(2) {
        let delta = w[0]
            .iter()
            .zip(&w[1])
            .map(|(a, b)| (b - a).abs())
            .fold(0.0, f64::max);
        let steps = (delta / 0.005).ceil().max(1.0) as usize;
        for i in 0..=steps {
            let f = i as f64 / steps as f64;
            for ((&v, a), b) in vars.iter().zip(&w[0]).zip(&w[1]) {
                q[v] = a + (b - a) * f;
            }
            if !exact.is_free(&q) {
                bad += 1;
            }
        }
    }
    bad
}

struct Row {
    solved: usize,
    times: Vec<f64>,
    before: Vec<f64>,
    after: Vec<f64>,
    ratios: Vec<f64>,
    methods: std::collections::BTreeMap<&'static str, usize>,
    checked: usize,
    penetrating: usize,
    /// Per method, the time of each attempt (ms), solved or not.
    attempts: std::collections::BTreeMap<&'static str, Vec<f64>>,
}

pub fn run(ctx: &Ctx, a: &MultiArmBenchArgs) -> Result<()> {
    let _ = ctx;
    let dir = manyhands::benchmark::mbm_data::locate().map_err(|e| anyhow!(e))?;
    let cells: Vec<VampMrCell> = if a.cells.is_empty() {
        VampMrCell::ALL.to_vec()
    } else {
        a.cells
            .iter()
            .map(|n| {
                VampMrCell::from_name(n)
                    .or_else(|| VampMrCell::from_name(&format!("vamp_mr_{n}")))
                    .ok_or_else(|| anyhow!("unknown cell '{n}'"))
            })
            .collect::<Result<_>>()?
    };
    if !(a.time_limit.is_finite() && a.time_limit > 0.0) {
        return Err(anyhow!(
            "time_limit: {} is not a positive number",
            a.time_limit
        ));
    }
    let variants: [(&str, Methods); 3] = [
        ("auto", Methods::default()),
        (
            "decoupled-only",
            Methods {
                decoupled: true,
                prioritized: false,
                composite: false,
            },
        ),
        (
            "composite-only",
            Methods {
                decoupled: false,
                prioritized: false,
                composite: true,
            },
        ),
    ];
    println!(
        "multi-arm planning on seeded crossing tasks, {} per cell, {} s each (this machine, \
         single thread; targets: four-Panda median ≤ 50 ms, two-Panda-with-rods ≤ 10 ms, \
         makespan after ≤ 0.8 × before)",
        a.tasks, a.time_limit
    );
    for cell in cells {
        let c = vamp_mr(cell, &dir)?;
        let world = CollisionWorld::from_scene(&c.scene);
        let mut problems = Vec::new();
        let mut seeds = Vec::new();
        let mut skipped = 0;
        let mut k = 0;
        // Seeds for which the generator finds no crossing task are skipped (at most as many
        // seeds again as tasks are tried).
        while (problems.len() as u64) < a.tasks && k < 2 * a.tasks {
            let seed = a.seed + k;
            k += 1;
            let task = match crossing_task(&c.scene, seed, &CrossingSettings::default()) {
                Ok(t) => t,
                Err(_) => {
                    skipped += 1;
                    continue;
                }
            };
            let arms = (0..world.robots.len())
                .map(|r| Arm {
                    robot: r,
                    vars: (0..world.robots[r].robot.dof()).collect(),
                    goal: task.goals[r].clone(),
                })
                .collect();
            problems.push(MultiArmProblem::new(
                world.clone(),
                task.start_config(),
                arms,
            )?);
            seeds.push(seed);
        }
        if skipped > 0 {
            println!(
                "\n{}: {skipped} seeds without a crossing task skipped",
                cell.name()
            );
        }
        println!("\n{} ({} arms)", cell.name(), world.robots.len());
        println!(
            "  {:<15} {:>9} {:>12} {:>12} {:>12} {:>8}  methods",
            "variant", "solved", "median ms", "before s", "after s", "after/b"
        );
        for (name, methods) in variants {
            let mut row = Row {
                solved: 0,
                times: Vec::new(),
                before: Vec::new(),
                after: Vec::new(),
                ratios: Vec::new(),
                methods: Default::default(),
                checked: 0,
                penetrating: 0,
                attempts: Default::default(),
            };
            for (k, p) in problems.iter().enumerate() {
                let mut s = MultiArmSettings {
                    methods,
                    composite_first: a.composite_first,
                    ..MultiArmSettings::default()
                };
                if let Some(n) = a.phase_iterations {
                    s.phase.max_iterations = n;
                }
                let mut term =
                    Termination::new().with_time_limit(Duration::from_secs_f64(a.time_limit));
                let t0 = Instant::now();
                let r = plan_multi_arm(p, &s, &mut term, seeds[k]);
                let ms = t0.elapsed().as_secs_f64() * 1e3;
                if let Ok(plan) = r {
                    if ms <= a.time_limit * 1e3 {
                        row.solved += 1;
                    }
                    row.times.push(ms);
                    row.before.push(plan.makespan_before);
                    row.after.push(plan.makespan);
                    row.ratios.push(plan.makespan / plan.makespan_before);
                    *row.methods.entry(plan.method.name()).or_default() += 1;
                    for at in &plan.stats.attempts {
                        row.attempts
                            .entry(at.method.name())
                            .or_default()
                            .push(at.time.as_secs_f64() * 1e3);
                    }
                    if name == "auto" {
                        row.checked += 1;
                        if penetrations(p, &plan) > 0 {
                            row.penetrating += 1;
                        }
                    }
                }
            }
            let methods: Vec<String> = row
                .methods
                .iter()
                .map(|(m, n)| format!("{m} {n}"))
                .collect();
            println!(
                "  {:<15} {:>5}/{:<3} {:>12.1} {:>12.3} {:>12.3} {:>8.2}  {}",
                name,
                row.solved,
                problems.len(),
                median(&mut row.times),
                median(&mut row.before),
                median(&mut row.after),
                median(&mut row.ratios),
                methods.join(", ")
            );
            if name == "auto" {
                println!(
                    "  {:<15} exact re-check of {} plans (all arms moving, ≤ 0.005 rad): {} with a \
                     penetration",
                    "", row.checked, row.penetrating
                );
                let attempts: Vec<String> = row
                    .attempts
                    .iter_mut()
                    .map(|(m, t)| format!("{m} {} × median {:.1} ms", t.len(), median(t)))
                    .collect();
                println!(
                    "  {:<15} attempts of the solved plans: {}",
                    "",
                    attempts.join(", ")
                );
            }
        }
    }
    Ok(())
}
