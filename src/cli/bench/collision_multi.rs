//! `manyhands bench collision --multi-arm`: the sphere checker on several arms at once, in the
//! VAMP-MR cells (src/benchmark/multi_arm_cells.rs), timed as VAMP-MR's Table 1 times its
//! checker: "single" checks one multi-robot configuration, "motion" one straight segment
//! between two, over random samples (every arm uniform within its joint limits; VAMP-MR's
//! benchmark script checks motions every 0.1 rad). Their figures (on their machine) are
//! printed beside; ours are from this machine, so compare ratios measured in one sitting, not
//! absolute times across machines.

use anyhow::{anyhow, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use manyhands::benchmark::multi_arm_cells::{vamp_mr, VampMrCell};
use manyhands::collision::{CollisionChecker, CollisionWorld, SphereChecker};

use super::super::bench::{time_each, Row};

/// VAMP-MR's step between checked states of a motion (rad), as in their benchmark script.
const VAMP_MR_STEP: f64 = 0.1;
/// Sphere inflation bound of the certified motion check (m): `bench mbm`'s default.
const CERTIFY: f64 = 0.04;

fn published(cell: VampMrCell, motion: bool) -> &'static str {
    match (cell, motion) {
        (VampMrCell::PandaTwoRod, false) => "VAMP-MR 8.60 µs",
        (VampMrCell::PandaTwoRod, true) => "VAMP-MR 36.0 µs",
        (VampMrCell::PandaFour, false) => "VAMP-MR 15.0 µs",
        (VampMrCell::PandaFour, true) => "VAMP-MR 32.6 µs",
        (VampMrCell::PandaFourBins, false) => "VAMP-MR 13.7 µs",
        (VampMrCell::PandaFourBins, true) => "VAMP-MR 14.2 µs",
    }
}

/// Random world configurations of `world`: every variable uniform within its limits.
fn random_configs(world: &CollisionWorld, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    (0..n)
        .map(|_| {
            let mut q = Vec::with_capacity(world.dof());
            for r in &world.robots {
                let mut c = r.robot.zero_config();
                let vars: Vec<usize> = (0..r.robot.dof()).collect();
                r.robot.sample_vars(&vars, &mut c, rng);
                q.extend(c);
            }
            q
        })
        .collect()
}

fn pct(k: usize, n: usize) -> f64 {
    100.0 * k as f64 / n.max(1) as f64
}

/// The rows of every cell: single state (all bodies; then arms against each other only),
/// motion every 0.1 rad, certified continuous motion.
pub(super) fn rows(samples: usize, seed: u64) -> Result<Vec<Row>> {
    let dir = manyhands::benchmark::mbm_data::locate().map_err(|e| anyhow!(e))?;
    let samples = samples.max(200);
    let mut rows = Vec::new();
    for cell in VampMrCell::ALL {
        let c = vamp_mr(cell, &dir)?;
        let world = CollisionWorld::from_scene(&c.scene);
        let name = cell.name().trim_start_matches("vamp_mr_");
        let arms = world.robots.len();
        let mut sc = SphereChecker::new(&world, 0.0)
            .ok_or_else(|| anyhow!("{name}: the arms are not sphere models"))?;
        let between = world.between_robots();
        let mut rr = SphereChecker::new(&between, 0.0)
            .ok_or_else(|| anyhow!("{name}: the arms are not sphere models"))?;
        let (bodies, spheres, _, _, pairs) = sc.model_size();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let configs = random_configs(&world, samples, &mut rng);
        let mut hits = 0usize;
        let (m, mean) = time_each(&configs, |q| hits += usize::from(!sc.is_free(q)));
        rows.push(Row {
            what: format!("{name}: single ({arms} arms, {} DoF)", world.dof()),
            median_ns: m,
            mean_ns: mean,
            n: configs.len(),
            note: format!(
                "{:.0} % in collision (incl. warm-up); {spheres} spheres, {bodies} bodies, \
                 {pairs} body pairs",
                pct(hits, configs.len() + 100)
            ),
            target: published(cell, false),
        });
        let mut hits = 0usize;
        let (m, mean) = time_each(&configs, |q| hits += usize::from(!rr.is_free(q)));
        rows.push(Row {
            what: format!("{name}: single, arm–arm only"),
            median_ns: m,
            mean_ns: mean,
            n: configs.len(),
            note: format!(
                "{:.0} % in collision (incl. warm-up)",
                pct(hits, configs.len() + 100)
            ),
            target: "share of above",
        });
        let free: Vec<Vec<f64>> = configs.iter().filter(|q| sc.is_free(q)).cloned().collect();
        if free.len() >= 10 {
            let (m, mean) = time_each(&free, |q| {
                std::hint::black_box(sc.is_free(q));
            });
            rows.push(Row {
                what: format!("{name}: single, free ones"),
                median_ns: m,
                mean_ns: mean,
                n: free.len(),
                note: "no early exit: every test made".into(),
                target: "",
            });
        }
        let ends = random_configs(&world, configs.len(), &mut rng);
        let pairs: Vec<(&Vec<f64>, &Vec<f64>)> = configs.iter().zip(&ends).collect();
        let mut hits = 0usize;
        let (m, mean) = time_each(&pairs, |(a, b)| {
            let step = a
                .iter()
                .zip(b.iter())
                .map(|(x, y)| (y - x).abs())
                .fold(0.0, f64::max);
            let n = (step / VAMP_MR_STEP).ceil().max(1.0) as usize;
            hits += usize::from(!sc.segment_free(a, b, n));
        });
        rows.push(Row {
            what: format!("{name}: motion, every 0.1 rad"),
            median_ns: m,
            mean_ns: mean,
            n: pairs.len(),
            note: format!(
                "{:.0} % in collision (incl. warm-up); random start and end",
                pct(hits, pairs.len() + 100)
            ),
            target: published(cell, true),
        });
        let mut hits = 0usize;
        let (m, mean) = time_each(&pairs, |(a, b)| {
            hits += usize::from(!sc.segment_certified(a, b, CERTIFY));
        });
        rows.push(Row {
            what: format!("{name}: motion, certified"),
            median_ns: m,
            mean_ns: mean,
            n: pairs.len(),
            note: format!(
                "{:.0} % not certified (incl. warm-up); inflation ≤ {CERTIFY} m",
                pct(hits, pairs.len() + 100)
            ),
            target: "stronger check",
        });
        // Motions between free states (what a planner mostly asks): both ends free.
        let free_pairs: Vec<(&Vec<f64>, &Vec<f64>)> =
            free.iter().zip(free.iter().skip(1)).collect();
        if free_pairs.len() >= 10 {
            let mut hits = 0usize;
            let (m, mean) = time_each(&free_pairs, |(a, b)| {
                hits += usize::from(!sc.segment_certified(a, b, CERTIFY));
            });
            rows.push(Row {
                what: format!("{name}: certified, free ends"),
                median_ns: m,
                mean_ns: mean,
                n: free_pairs.len(),
                note: format!(
                    "{:.0} % not certified (incl. warm-up)",
                    pct(hits, free_pairs.len() + 100)
                ),
                target: "",
            });
        }
    }
    Ok(rows)
}
