//! Scene generators that need collision checking: "N random boxes without initial collision"
//! (paper 002, vahrenkamp2010 §VI-B: 3 robots among 30 boxes).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{CollisionChecker, CollisionWorld, ExactChecker};
use crate::geometry::PoseJson;
use crate::model::{BodyJson, GeometryJson, ModelError, RobotLibrary, Scene};

/// Parameters of [`random_boxes`].
#[derive(Debug, Clone, PartialEq)]
pub struct RandomBoxes {
    pub count: usize,
    pub seed: u64,
    /// Box centres are drawn uniformly in `[lo, hi]` (world frame).
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    /// Edge lengths are drawn uniformly in `[min_edge, max_edge]`.
    pub min_edge: f64,
    pub max_edge: f64,
    /// Give up after this many rejected draws.
    pub max_tries: usize,
}

impl Default for RandomBoxes {
    fn default() -> Self {
        RandomBoxes {
            count: 30,
            seed: 1,
            lo: [-2.5, -2.5, 0.1],
            hi: [2.5, 2.5, 1.8],
            min_edge: 0.1,
            max_edge: 0.35,
            max_tries: 100_000,
        }
    }
}

/// Adds `count` randomly placed and oriented boxes to `base`, rejecting every box that touches
/// a robot at its start configuration (checked with the exact checker) or another box. The same
/// seed gives the same scene.
pub fn random_boxes(
    base: &Scene,
    p: &RandomBoxes,
    robots: &RobotLibrary,
) -> Result<Scene, ModelError> {
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let mut json = base.json.clone();
    json.name = format!("{}_{}boxes_seed{}", base.name, p.count, p.seed);
    json.description = format!(
        "{} + {} random boxes (seed {}), none touching a robot at its start configuration",
        base.description, p.count, p.seed
    );
    let q0 = CollisionWorld::start_config(base);
    let mut added = 0;
    let mut tries = 0;
    while added < p.count {
        tries += 1;
        if tries > p.max_tries {
            return Err(ModelError::invalid(
                "random_boxes",
                "count",
                format!(
                    "placed only {added} of {} boxes in {} tries",
                    p.count, p.max_tries
                ),
            ));
        }
        let mut pos = [0.0; 3];
        let mut half = [0.0; 3];
        for i in 0..3 {
            pos[i] = rng.random_range(p.lo[i]..=p.hi[i]);
            half[i] = 0.5 * rng.random_range(p.min_edge..=p.max_edge);
        }
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let body = BodyJson {
            name: format!("box_{added:02}"),
            pose: PoseJson {
                position: Some(pos),
                rpy: Some([0.0, 0.0, yaw]),
                quat_xyzw: None,
            },
            shapes: vec![GeometryJson {
                kind: "box".into(),
                half_extents: Some(half),
                radius: None,
                length: None,
                path: None,
                scale: None,
                pose: None,
            }],
            mass: None,
            grasps: Vec::new(),
            goal: None,
        };
        let mut trial = json.clone();
        trial.obstacles.push(body.clone());
        let scene = Scene::from_json(
            trial.clone(),
            "random_boxes",
            std::path::Path::new("."),
            robots,
        )?;
        // The new box alone against robots and the other boxes.
        let mut world = CollisionWorld::from_scene(&scene);
        let new_idx = world
            .statics
            .iter()
            .position(|s| s.name == body.name)
            .unwrap_or(0);
        let new_box = world.statics.remove(new_idx);
        let others = std::mem::take(&mut world.statics);
        world.statics.push(new_box.clone());
        let mut checker = ExactChecker::new(&world);
        if !checker.is_free(&q0) {
            continue;
        }
        if others.iter().any(|o| overlaps(&new_box, o)) {
            continue;
        }
        json = trial;
        added += 1;
    }
    Scene::from_json(json, "random_boxes", std::path::Path::new("."), robots)
}

/// Conservative box–body overlap test through bounding spheres of the shapes.
fn overlaps(a: &super::StaticBody, b: &super::StaticBody) -> bool {
    a.shapes.iter().any(|ga| {
        b.shapes.iter().any(|gb| {
            let ca = (a.pose * ga.origin).translation.vector;
            let cb = (b.pose * gb.origin).translation.vector;
            (ca - cb).norm() < ga.shape.bounding_radius() + gb.shape.bounding_radius()
        })
    })
}

/// A random world configuration around `start`: the variables of each robot's SRDF `base` group
/// move at most `linear` metres (prismatic) or `angular` radians (revolute) from the start,
/// clamped into the limits; every other variable is uniform within its limits. Used by the
/// collision benchmarks and the fast-vs-exact tests.
pub fn random_config_near<R: Rng + ?Sized>(
    world: &CollisionWorld,
    start: &[f64],
    linear: f64,
    angular: f64,
    rng: &mut R,
) -> Vec<f64> {
    let mut q = start.to_vec();
    for p in &world.robots {
        let r = &p.robot;
        let base = r.group("base").map(|g| g.vars.as_slice()).unwrap_or(&[]);
        for v in 0..r.dof() {
            let l = r.var_limits(v);
            let i = p.offset + v;
            q[i] = if base.contains(&v) {
                let w = if r.joints[r.vars[v]].kind == crate::model::JointKind::Prismatic {
                    linear
                } else {
                    angular
                };
                (start[i] + rng.random_range(-w..w)).clamp(l.lower, l.upper)
            } else {
                l.sample(rng)
            };
        }
    }
    q
}
