//! Profiling aid: loops the fast checker over free random configurations of armar in a scene.
use manyhands::collision::{CollisionChecker, CollisionWorld, FastChecker};
use manyhands::model::{data_root, load_robot_dir};
use manyhands::Scene;
use rand::{Rng, SeedableRng};
fn main() {
    let name = std::env::args().nth(1).unwrap_or_else(|| "kitchen".into());
    let lib = load_robot_dir(&data_root().join("robots")).unwrap();
    let s = Scene::from_file(&data_root().join(format!("scenes/{name}.json")), &lib).unwrap();
    let w = CollisionWorld::from_scene(&s);
    let mut f = FastChecker::new(&w);
    let start = CollisionWorld::start_config(&s);
    let r = &w.robots[0].robot;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut free = Vec::new();
    while free.len() < 5000 {
        let mut q = start.clone();
        for (v, x) in q.iter_mut().enumerate().take(r.dof()).skip(3) {
            let l = r.var_limits(v);
            *x = rng.random_range(l.lower..=l.upper);
        }
        if f.is_free(&q) {
            free.push(q);
        }
    }
    let t = std::time::Instant::now();
    let reps: usize = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    for _ in 0..reps {
        for q in &free {
            std::hint::black_box(f.is_free(q));
        }
    }
    println!(
        "{name}: {:.0} ns per free check",
        t.elapsed().as_nanos() as f64 / (reps * free.len()) as f64
    );
}
