//! MotionBenchMaker-like problem sets for any robot (issue 28 item 3: the same speed on robots
//! never seen needs problems posed on them). MotionBenchMaker (Chamzas et al., RA-L 2022) places
//! parameterised scenes — tables with clutter, bookshelves, cages — around a robot and asks for
//! motions between configurations whose end effector is inside them. This module does the same
//! for a robot it is given, with every size derived from the robot:
//!
//! - the **anchor**: the rest position of the first link the planned joints move (the shoulder);
//!   the **reach** R: the largest distance from it of any moved link origin over 2 000 seeded
//!   random configurations of the planned joints; the **tip**: the moved link farthest from it
//!   on average (the end effector). Scenes are placed around the anchor, in the robot's base
//!   frame (x forward, z up);
//! - `table`: a top of 0.5 R × 0.8 R at 0.6 R in a random direction within ±45° of +x, its height
//!   0–0.35 R below the anchor, with 3–6 boxes and cylinders on it; start and goal have the tip
//!   above the top;
//! - `shelf`: a bookshelf 0.7 R wide and 0.25 R deep at 0.65 R, facing the robot, with four
//!   boards (three compartments), sides and a back; start and goal tips in two different
//!   compartments;
//! - `cage`: an open-fronted box of 0.5 R at 0.55 R; the start anywhere free, the goal's tip
//!   inside;
//! - `box`: an open-topped bin (0.4 R × 0.5 R, walls 0.2 R high) on a table top of 0.6 R × 0.9 R
//!   at 0.55 R, the top 0.2–0.45 R below the anchor: the start's tip above the table beside the
//!   bin, the goal's tip inside the bin (MotionBenchMaker's `box`: reaching down into a
//!   container).
//!
//! Start and goal are drawn by rejection (seeded), must be collision-free under the exact
//! checker, their tips at least 0.25 R apart and the straight motion between them in collision
//! (at the benchmark's 0.25° resolution), so no problem is trivial. A problem is marked `valid`
//! when RRT-Connect (the benchmark's settings, certified sphere checks) solves it within the
//! generator's iteration bound (20 000 by default) — the role of MotionBenchMaker's `valid` flag (a problem someone
//! solved); the others are written too and never planned. The output is the benchmark's own
//! `problems.json` format, read back by [`crate::benchmark::mbm::MbmFile`], so `manyhands bench mbm --robot
//! URDF --problems FILE` runs on it unchanged.

use std::sync::Arc;
use std::time::Duration;

use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use crate::benchmark::mbm::{MbmError, MbmObstacle, MbmProblem};
use crate::collision::{AutoChecker, CollisionWorld, ExactChecker};
use crate::geometry::{Pose, Shape};
use crate::kinematics::forward as fk_forward;
use crate::planning::base::range::DerivedSettings;
use crate::planning::{
    JointSpace, RrtConnect, RrtConnectSettings, ShortcutSettings, SpaceValidator, Termination,
};
use crate::Robot;

/// The scene families, in the order they are written (alphabetical: the file's sets are a JSON
/// object, written in key order).
pub const SETS: [&str; 4] = ["box", "cage", "shelf", "table"];

/// The random stream of a set: the order the sets were introduced in (`cage`, `shelf`,
/// `table`, then `box`), so adding a set leaves the problems of the others unchanged.
fn set_stream(set: &str) -> u64 {
    match set {
        "cage" => 1,
        "shelf" => 2,
        "table" => 3,
        _ => 4,
    }
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct GenSettings {
    /// Problems per set.
    pub per_set: usize,
    pub seed: u64,
    /// RRT-Connect's iterations to solve a problem for it to be marked valid (an iteration
    /// bound, not a time, so the same seed gives the same file on any machine).
    pub solve_iterations: u64,
}

impl Default for GenSettings {
    fn default() -> Self {
        GenSettings {
            per_set: 20,
            seed: 1,
            solve_iterations: 20_000,
        }
    }
}

/// Sizes derived from the robot (see the module docs).
#[derive(Debug, Clone, Copy)]
pub struct RobotScale {
    /// Largest distance of a moved link origin from the anchor.
    pub reach: f64,
    pub tip: usize,
    /// The rest position of the first link the planned joints move (the shoulder), in the
    /// robot's base frame: scenes are placed around it.
    pub anchor: Vector3<f64>,
}

/// An axis-aligned region in a frame (`pose`), where a tip must lie.
#[derive(Debug, Clone, Copy)]
struct Region {
    pose: Pose,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl Region {
    fn contains(&self, p: &Vector3<f64>) -> bool {
        let l = self.pose.inverse_transform_point(&(*p).into()).coords;
        (0..3).all(|i| l[i] >= self.lo[i] && l[i] <= self.hi[i])
    }
}

struct SceneDraft {
    obstacles: Vec<MbmObstacle>,
    /// Where the start's tip must be (anywhere when empty).
    start_regions: Vec<Region>,
    goal_regions: Vec<Region>,
    /// Start and goal tips must be in different regions of the lists (shelf compartments).
    distinct: bool,
}

fn boxed(name: String, pose: Pose, h: [f64; 3]) -> MbmObstacle {
    MbmObstacle {
        name,
        pose,
        shape: Shape::Box {
            half_extents: Vector3::from(h),
        },
    }
}

fn facing(s: &RobotScale, d: f64, theta: f64, z: f64) -> Pose {
    Pose::from_parts(
        Vector3::new(
            s.anchor.x + d * theta.cos(),
            s.anchor.y + d * theta.sin(),
            z,
        )
        .into(),
        UnitQuaternion::from_euler_angles(0.0, 0.0, theta),
    )
}

fn local(frame: &Pose, x: f64, y: f64, z: f64) -> Pose {
    frame * Pose::translation(x, y, z)
}

fn table(s: &RobotScale, rng: &mut ChaCha8Rng) -> SceneDraft {
    let r = s.reach;
    let theta = rng.random_range(-0.785..0.785);
    let z = s.anchor.z - rng.random_range(0.0..0.35) * r;
    let frame = facing(s, 0.6 * r, theta, z);
    let (hx, hy, t) = (0.25 * r, 0.4 * r, 0.015 * r);
    let mut obstacles = vec![boxed(
        "table_top".into(),
        local(&frame, 0.0, 0.0, -t),
        [hx, hy, t],
    )];
    let n = rng.random_range(3..=6);
    for k in 0..n {
        let h = rng.random_range(0.05..0.15) * r;
        let w = rng.random_range(0.03..0.07) * r;
        let x = rng.random_range(-hx + w..hx - w);
        let y = rng.random_range(-hy + w..hy - w);
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let pose = local(&frame, x, y, h) * Pose::rotation(Vector3::z() * yaw);
        obstacles.push(if rng.random_bool(0.5) {
            boxed(format!("clutter_{k}"), pose, [w, 0.7 * w, h])
        } else {
            MbmObstacle {
                name: format!("clutter_{k}"),
                pose,
                shape: Shape::Cylinder {
                    radius: w,
                    half_length: h,
                },
            }
        });
    }
    let above = Region {
        pose: frame,
        lo: Vector3::new(-hx, -hy, 0.05 * r),
        hi: Vector3::new(hx, hy, 0.3 * r),
    };
    SceneDraft {
        obstacles,
        start_regions: vec![above],
        goal_regions: vec![above],
        distinct: false,
    }
}

fn shelf(s: &RobotScale, rng: &mut ChaCha8Rng) -> SceneDraft {
    let r = s.reach;
    let theta = rng.random_range(-0.785..0.785);
    // The shelf's frame: x away from the robot (depth), y across, z up from its floor.
    let floor = s.anchor.z - rng.random_range(0.35..0.5) * r;
    let frame = facing(s, 0.65 * r, theta, floor);
    let (hd, hw, t) = (0.125 * r, 0.35 * r, 0.01 * r);
    let boards = [0.0, 0.3 * r, 0.6 * r, 0.9 * r];
    let top = boards[boards.len() - 1];
    let mut obstacles = Vec::new();
    for (k, z) in boards.iter().enumerate() {
        obstacles.push(boxed(
            format!("board_{k}"),
            local(&frame, 0.0, 0.0, *z),
            [hd, hw, t],
        ));
    }
    for (k, y) in [-hw, hw].iter().enumerate() {
        obstacles.push(boxed(
            format!("side_{k}"),
            local(&frame, 0.0, *y, 0.5 * top),
            [hd, t, 0.5 * top + t],
        ));
    }
    obstacles.push(boxed(
        "back".into(),
        local(&frame, hd, 0.0, 0.5 * top),
        [t, hw, 0.5 * top + t],
    ));
    let compartments = boards
        .windows(2)
        .map(|w| Region {
            pose: frame,
            lo: Vector3::new(-hd, -hw + 0.03 * r, w[0] + 0.04 * r),
            hi: Vector3::new(hd - 0.03 * r, hw - 0.03 * r, w[1] - 0.04 * r),
        })
        .collect::<Vec<_>>();
    SceneDraft {
        obstacles,
        start_regions: compartments.clone(),
        goal_regions: compartments,
        distinct: true,
    }
}

fn bin(s: &RobotScale, rng: &mut ChaCha8Rng) -> SceneDraft {
    let r = s.reach;
    let theta = rng.random_range(-0.785..0.785);
    let z = s.anchor.z - rng.random_range(0.2..0.45) * r;
    let frame = facing(s, 0.55 * r, theta, z);
    let (hx, hy, t) = (0.3 * r, 0.45 * r, 0.015 * r);
    // The bin on one side of the table (across it, in the table's frame), the rest free.
    let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    let (bx, by, bh) = (0.2 * r, 0.25 * r, 0.2 * r);
    let cy = side * (hy - by);
    let bin = local(&frame, 0.0, cy, 0.0);
    let w = 0.008 * r;
    let obstacles = vec![
        boxed("table_top".into(), local(&frame, 0.0, 0.0, -t), [hx, hy, t]),
        boxed(
            "bin_front".into(),
            local(&bin, -bx, 0.0, 0.5 * bh),
            [w, by, 0.5 * bh],
        ),
        boxed(
            "bin_back".into(),
            local(&bin, bx, 0.0, 0.5 * bh),
            [w, by, 0.5 * bh],
        ),
        boxed(
            "bin_left".into(),
            local(&bin, 0.0, by, 0.5 * bh),
            [bx, w, 0.5 * bh],
        ),
        boxed(
            "bin_right".into(),
            local(&bin, 0.0, -by, 0.5 * bh),
            [bx, w, 0.5 * bh],
        ),
    ];
    let inside = Region {
        pose: bin,
        lo: Vector3::new(-bx + 0.03 * r, -by + 0.03 * r, 0.03 * r),
        hi: Vector3::new(bx - 0.03 * r, by - 0.03 * r, 0.8 * bh),
    };
    let beside = Region {
        pose: frame,
        lo: Vector3::new(-hx, if side > 0.0 { -hy } else { hy - 2.0 * by }, 0.05 * r),
        hi: Vector3::new(hx, if side > 0.0 { -hy + 2.0 * by } else { hy }, 0.35 * r),
    };
    SceneDraft {
        obstacles,
        start_regions: vec![beside],
        goal_regions: vec![inside],
        distinct: false,
    }
}

fn cage(s: &RobotScale, rng: &mut ChaCha8Rng) -> SceneDraft {
    let r = s.reach;
    let theta = rng.random_range(-0.785..0.785);
    let h = 0.25 * r;
    let z = s.anchor.z + rng.random_range(-0.3..0.0) * r;
    let frame = facing(s, 0.55 * r, theta, z);
    let t = 0.01 * r;
    let obstacles = vec![
        boxed("bottom".into(), local(&frame, 0.0, 0.0, -h), [h, h, t]),
        boxed("top".into(), local(&frame, 0.0, 0.0, h), [h, h, t]),
        boxed("back".into(), local(&frame, h, 0.0, 0.0), [t, h, h]),
        boxed("left".into(), local(&frame, 0.0, h, 0.0), [h, t, h]),
        boxed("right".into(), local(&frame, 0.0, -h, 0.0), [h, t, h]),
    ];
    let inside = Region {
        pose: frame,
        lo: Vector3::new(-0.3 * h, -0.7 * h, -0.7 * h),
        hi: Vector3::new(0.7 * h, 0.7 * h, 0.7 * h),
    };
    SceneDraft {
        obstacles,
        start_regions: Vec::new(),
        goal_regions: vec![inside],
        distinct: false,
    }
}

/// The robot's reach, tip link and shoulder height (module docs), from 2 000 seeded samples of
/// the variables `vars` (the others at zero).
pub fn robot_scale(robot: &Robot, vars: &[usize], seed: u64) -> Option<RobotScale> {
    const SAMPLES: usize = 2000;
    let n = robot.links.len();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut q = robot.zero_config();
    let mut poses = vec![Pose::identity(); n];
    fk_forward(robot, &Pose::identity(), &q, &mut poses);
    let rest: Vec<Vector3<f64>> = poses.iter().map(|p| p.translation.vector).collect();
    let mut samples = Vec::with_capacity(SAMPLES);
    let mut moved = vec![false; n];
    for _ in 0..SAMPLES {
        for &v in vars {
            let l = robot.var_limits(v);
            q[v] = rng.random_range(l.lower..=l.upper);
        }
        fk_forward(robot, &Pose::identity(), &q, &mut poses);
        let x: Vec<Vector3<f64>> = poses.iter().map(|p| p.translation.vector).collect();
        for k in 0..n {
            moved[k] |= (x[k] - rest[k]).norm() > 1e-6;
        }
        samples.push(x);
    }
    // The first moved link in tree order: the shoulder, where the scenes are centred.
    let first = (0..n).find(|&k| moved[k])?;
    let anchor = rest[first];
    let mut mean = vec![0.0; n];
    let mut reach: f64 = 0.0;
    for x in &samples {
        for k in (0..n).filter(|&k| moved[k]) {
            let d = (x[k] - anchor).norm();
            mean[k] += d / SAMPLES as f64;
            reach = reach.max(d);
        }
    }
    let tip = (0..n)
        .filter(|&k| moved[k])
        .max_by(|&a, &b| mean[a].total_cmp(&mean[b]))?;
    (reach > 0.0).then_some(RobotScale { reach, tip, anchor })
}

fn obstacle_json(o: &MbmObstacle) -> (String, Value) {
    let t = o.pose.translation.vector;
    let q = o.pose.rotation.coords; // (x, y, z, w)
    let pos = [t.x, t.y, t.z];
    let quat = [q[0], q[1], q[2], q[3]];
    match &o.shape {
        Shape::Box { half_extents } => (
            "box".into(),
            json!({"name": o.name, "half_extents": [half_extents.x, half_extents.y, half_extents.z],
                   "position": pos, "orientation_quat_xyzw": quat}),
        ),
        Shape::Cylinder {
            radius,
            half_length,
        } => (
            "cylinder".into(),
            json!({"name": o.name, "radius": radius, "length": 2.0 * half_length,
                   "position": pos, "orientation_quat_xyzw": quat}),
        ),
        other => (
            "sphere".into(),
            json!({"name": o.name, "radius": other.bounding_radius(), "position": pos}),
        ),
    }
}

/// RRT-Connect's settings that decide a problem's `valid` flag: `bench mbm`'s defaults (0.25°
/// states, certified continuous checks with inflation ≤ 0.04 m, shortcutting and re-validation,
/// balanced trees, range and dynamic domain derived from the robot).
pub fn solve_settings(world: &CollisionWorld, space: &JointSpace) -> RrtConnectSettings {
    let derived = DerivedSettings::of(world, space);
    RrtConnectSettings {
        range: derived.as_ref().map(|d| d.range),
        angular_resolution: 0.25f64.to_radians(),
        linear_resolution: 0.005,
        direct_connect: true,
        shortcut: Some(ShortcutSettings::default()),
        revalidate: true,
        certify: Some(0.04),
        dynamic_domain: derived.as_ref().map(|d| d.dynamic_domain),
        balance: true,
        lazy: false,
        sampler: crate::planning::Sampler::Uniform,
    }
}

/// Counters of a generation run (what was tried, what was kept).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct GenStats {
    pub scenes_drawn: u64,
    pub configurations_drawn: u64,
    pub problems: usize,
    pub valid: usize,
}

/// Generates `s.per_set` problems per set in [`SETS`] for `robot`, planning `joints` (all its
/// variables when empty). Returns the `problems.json` value and the counters.
pub fn generate(
    robot: Arc<Robot>,
    joints: &[String],
    s: &GenSettings,
) -> Result<(Value, GenStats), MbmError> {
    let joints: Vec<String> = if joints.is_empty() {
        (0..robot.dof())
            .map(|v| robot.var_name(v).to_string())
            .collect()
    } else {
        joints.to_vec()
    };
    let vars = joints
        .iter()
        .map(|j| {
            robot.var(j).ok_or_else(|| MbmError::UnknownJoint {
                joint: j.clone(),
                robot: robot.name.clone(),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let bad = |reason: String| MbmError::Problem {
        set: "generator".into(),
        index: 0,
        reason,
    };
    let scale = robot_scale(&robot, &vars, s.seed)
        .ok_or_else(|| bad("no link moves with the planned joints".into()))?;
    let mut stats = GenStats::default();
    let mut sets = serde_json::Map::new();
    let mut tip_poses = vec![Pose::identity(); robot.links.len()];
    for set in SETS.iter() {
        let mut out = Vec::new();
        let mut rng =
            ChaCha8Rng::seed_from_u64(s.seed ^ set_stream(set).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut attempts = 0;
        while out.len() < s.per_set {
            attempts += 1;
            if attempts > 40 * s.per_set.max(1) {
                return Err(bad(format!(
                    "set {set}: no well-posed problem in {} scenes (is the robot too small or blocked by its own base?)",
                    attempts - 1
                )));
            }
            stats.scenes_drawn += 1;
            let draft = match *set {
                "table" => table(&scale, &mut rng),
                "shelf" => shelf(&scale, &mut rng),
                "box" => bin(&scale, &mut rng),
                _ => cage(&scale, &mut rng),
            };
            let mut p = MbmProblem {
                set: set.to_string(),
                index: out.len() + 1,
                valid: false,
                start: Vec::new(),
                goals: Vec::new(),
                obstacles: draft.obstacles,
            };
            let world = p.world(robot.clone());
            let space = p.space(&world, &vars)?;
            let mut exact = SpaceValidator::new(
                space.clone(),
                &world,
                ExactChecker::new(&world),
                0.25f64.to_radians(),
                0.005,
            );
            // A free configuration whose tip lies in one of `regions` (anywhere when empty).
            let mut draw = |regions: &[Region],
                            rng: &mut ChaCha8Rng,
                            exact: &mut SpaceValidator<ExactChecker>,
                            stats: &mut GenStats|
             -> Option<(Vec<f64>, usize, Vector3<f64>)> {
                let mut q = vec![0.0; space.dim()];
                for _ in 0..20_000 {
                    stats.configurations_drawn += 1;
                    space.sample_uniform(rng, &mut q);
                    let wq = space.to_world(&q);
                    fk_forward(&robot, &Pose::identity(), &wq, &mut tip_poses);
                    let tip = tip_poses[scale.tip].translation.vector;
                    let region = if regions.is_empty() {
                        Some(0)
                    } else {
                        regions.iter().position(|r| r.contains(&tip))
                    };
                    if let Some(k) = region {
                        if exact.is_state_valid(&q) {
                            return Some((q, k, tip));
                        }
                    }
                }
                None
            };
            let Some((start, start_k, start_tip)) =
                draw(&draft.start_regions, &mut rng, &mut exact, &mut stats)
            else {
                continue;
            };
            let mut goal = None;
            for _ in 0..8 {
                let Some((g, k, tip)) = draw(&draft.goal_regions, &mut rng, &mut exact, &mut stats)
                else {
                    break;
                };
                if (!draft.distinct || k != start_k)
                    && (tip - start_tip).norm() >= 0.25 * scale.reach
                    && !exact.is_motion_valid(&start, &g)
                {
                    goal = Some(g);
                    break;
                }
            }
            let Some(goal) = goal else { continue };
            p.start = start;
            p.goals = vec![goal];
            // Valid: RRT-Connect (the benchmark's settings) solves it in the time given.
            let mut planner = RrtConnect::with_checker(
                space.clone(),
                &world,
                AutoChecker::new(&world, 0.0),
                solve_settings(&world, &space),
            )?;
            // The iteration bound decides; the time limit only guards against a pathological
            // robot (it is far above what the bound takes).
            let mut term = Termination::new()
                .with_iteration_limit(s.solve_iterations)
                .with_time_limit(Duration::from_secs(120));
            p.valid = planner
                .plan(&p.start, &p.goals, &mut term, s.seed ^ out.len() as u64)
                .is_ok();
            stats.problems += 1;
            stats.valid += usize::from(p.valid);
            let mut o = serde_json::Map::new();
            for key in ["sphere", "cylinder", "box"] {
                o.insert(key.into(), Value::Array(Vec::new()));
            }
            for ob in &p.obstacles {
                let (key, v) = obstacle_json(ob);
                if let Some(Value::Array(a)) = o.get_mut(&key) {
                    a.push(v);
                }
            }
            o.insert("start".into(), json!(p.start));
            o.insert("goals".into(), json!(p.goals));
            o.insert("valid".into(), json!(p.valid));
            o.insert("index".into(), json!(p.index));
            out.push(Value::Object(o));
        }
        sets.insert(set.to_string(), Value::Array(out));
    }
    Ok((
        json!({
            "robot": robot.name,
            "joints": joints,
            "generator": {
                "module": "manyhands benchmark::mbm_gen",
                "seed": s.seed,
                "per_set": s.per_set,
                "solve_iterations": s.solve_iterations,
                "reach_m": scale.reach,
                "tip_link": robot.links[scale.tip].name,
                "anchor_m": [scale.anchor.x, scale.anchor.y, scale.anchor.z],
            },
            "problems": Value::Object(sets),
        }),
        stats,
    ))
}
