//! Timing of the sphere checker against the fast checker on one Panda problem per MBM set
//! (`cargo run --release --example sphere_perf`).

use std::path::PathBuf;
use std::sync::Arc;

use manyhands::collision::{CollisionChecker, SphereChecker};
use manyhands::planning::mbm::MbmFile;
use manyhands::Robot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn mbm(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/benchmarks/mbm")
        .join(p)
}

fn robot(name: &str) -> Arc<Robot> {
    Arc::new(
        Robot::from_files(
            &mbm(&format!("{name}/{name}_spherized.urdf")),
            Some(&mbm(&format!("{name}/{name}.srdf"))),
        )
        .expect("robot"),
    )
}

fn main() {
    let r = robot("panda");
    let file = MbmFile::load(&mbm("panda/problems.json")).expect("problems");
    for set in &file.sets {
        let p = set.problems.iter().find(|p| p.valid).expect("valid");
        let world = p.world(r.clone());
        let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let n = 20000;
        let qs: Vec<Vec<f64>> = (0..n)
            .map(|_| {
                (0..7)
                    .map(|v| {
                        let l = r.var_limits(v);
                        rng.random_range(l.lower..=l.upper)
                    })
                    .collect()
            })
            .collect();
        let t = std::time::Instant::now();
        let mut free = 0;
        for q in &qs {
            free += sc.is_free(q) as usize;
        }
        let single = t.elapsed().as_nanos() as f64 / n as f64;
        let mut fast = manyhands::collision::FastChecker::new(&world);
        let t = std::time::Instant::now();
        let mut ffree = 0;
        for q in &qs {
            ffree += fast.is_free(q) as usize;
        }
        println!(
            "fast {:.0} ns/check ({ffree} free)",
            t.elapsed().as_nanos() as f64 / n as f64
        );
        // Short free segments near the start: the planner's common case.
        let a = p.start.clone();
        let t = std::time::Instant::now();
        let mut ok = 0;
        let m = 2000;
        for k in 0..m {
            let b: Vec<f64> = a
                .iter()
                .map(|v| v + 0.01 * ((k % 7) as f64 - 3.0))
                .collect();
            ok += sc.segment_free(&a, &b, 64) as usize;
        }
        let seg = t.elapsed().as_nanos() as f64 / (m * 64) as f64;
        println!(
            "{:<20} single {single:.0} ns/check ({free}/{n} free), segment {seg:.1} ns/state ({ok}/{m} free) {:?}",
            set.name, sc.model_size()
        );
    }
}
