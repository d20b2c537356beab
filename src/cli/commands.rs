//! Implementations of the inspection commands (robot, fk, ik, check, scene).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use manyhands::collision::{
    random_boxes as gen_boxes, CollisionChecker, CollisionWorld, ExactChecker, FastChecker,
    RandomBoxes,
};
use manyhands::geometry::{iso_from_rpy, quat_to_rpy, Pose, Shape};
use manyhands::kinematics::numeric::NumericIk;
use manyhands::kinematics::srs::{SolutionOrder, SrsArm};
use manyhands::kinematics::{forward, Chain};
use manyhands::model::{data_root, load_robot_dir, load_scene_dir, RobotLibrary};
use manyhands::{Robot, Scene};

use super::Cli;

pub struct Ctx {
    pub robots_dir: PathBuf,
    pub scenes_dir: PathBuf,
    pub json: bool,
}

impl Ctx {
    pub fn new(cli: &Cli) -> Ctx {
        let root = data_root();
        Ctx {
            robots_dir: cli.robots.clone().unwrap_or_else(|| root.join("robots")),
            scenes_dir: cli.scenes.clone().unwrap_or_else(|| root.join("scenes")),
            json: cli.json,
        }
    }

    pub fn library(&self) -> Result<RobotLibrary> {
        Ok(load_robot_dir(&self.robots_dir)?)
    }

    /// A model by name from the robots folder, or a path to a `.urdf` (its `.srdf` beside it).
    pub fn robot(&self, name: &str) -> Result<Arc<Robot>> {
        let p = Path::new(name);
        if p.extension().and_then(|e| e.to_str()) == Some("urdf") {
            let srdf = p.with_extension("srdf");
            return Ok(Arc::new(Robot::from_files(
                p,
                srdf.is_file().then_some(srdf.as_path()),
            )?));
        }
        let lib = self.library()?;
        lib.get(name).cloned().ok_or_else(|| {
            let mut names: Vec<&String> = lib.keys().collect();
            names.sort();
            anyhow!("unknown robot '{name}' (known: {names:?}; or give a path to a .urdf)")
        })
    }

    /// A scene by name from the scenes folder, or a path to a scene file.
    pub fn scene(&self, name: &str) -> Result<Scene> {
        let lib = self.library()?;
        let p = Path::new(name);
        let path = if p.extension().and_then(|e| e.to_str()) == Some("json") {
            p.to_path_buf()
        } else {
            let path = self.scenes_dir.join(format!("{name}.json"));
            if !path.is_file() {
                let mut names: Vec<String> = std::fs::read_dir(&self.scenes_dir)
                    .map(|rd| {
                        rd.filter_map(|e| e.ok())
                            .filter_map(|e| {
                                let p = e.path();
                                (p.extension().and_then(|x| x.to_str()) == Some("json"))
                                    .then(|| p.file_stem()?.to_str().map(str::to_string))
                                    .flatten()
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                names.sort();
                return Err(anyhow!(
                    "unknown scene '{name}' (known in {}: {}; or give a path to a .json)",
                    self.scenes_dir.display(),
                    names.join(", ")
                ));
            }
            path
        };
        Ok(Scene::from_file(&path, &lib)?)
    }

    /// Prints JSON (with `--json`) or text; a closed pipe (`| head`) is not an error.
    pub fn print(&self, v: &Value, text: impl FnOnce() -> String) {
        use std::io::Write;
        let s = if self.json {
            serde_json::to_string_pretty(v).unwrap_or_default()
        } else {
            text()
        };
        let _ = writeln!(std::io::stdout().lock(), "{s}");
    }
}

pub fn robot_list(ctx: &Ctx) -> Result<()> {
    let lib = ctx.library()?;
    let mut names: Vec<_> = lib.iter().map(|(k, r)| (k.clone(), r.dof())).collect();
    names.sort();
    let v = json!(names
        .iter()
        .map(|(n, d)| json!({"name": n, "dof": d}))
        .collect::<Vec<_>>());
    ctx.print(&v, || {
        names
            .iter()
            .map(|(n, d)| format!("{n}\t{d} DoF"))
            .collect::<Vec<_>>()
            .join("\n")
    });
    Ok(())
}

fn shape_json(s: &Shape) -> Value {
    match s {
        Shape::Box { half_extents } => {
            json!({"type": "box", "half_extents": [half_extents.x, half_extents.y, half_extents.z]})
        }
        Shape::Cylinder {
            radius,
            half_length,
        } => json!({"type": "cylinder", "radius": radius, "length": 2.0 * half_length}),
        Shape::Sphere { radius } => json!({"type": "sphere", "radius": radius}),
        Shape::Capsule {
            radius,
            half_length,
        } => json!({"type": "capsule", "radius": radius, "length": 2.0 * half_length}),
        Shape::Mesh(m) => {
            let solid = match &m.solid {
                Ok(s) => json!({"components": s.components, "cover_boxes": s.cover.len(),
                                "cover_protrusion": s.cover_protrusion()}),
                Err(why) => json!({"not_solid": why}),
            };
            json!({"type": "mesh", "source": m.source, "vertices": m.vertices.len(),
                   "triangles": m.triangles.len(), "solid": solid})
        }
    }
}

fn pose_json(p: &Pose) -> Value {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    json!({"position": [t.x, t.y, t.z], "rpy": quat_to_rpy(&p.rotation), "quat_xyzw": [q.i, q.j, q.k, q.w]})
}

/// `robot check`: the always-colliding pairs found at load ([`manyhands::collision::always`]),
/// the revolute joints whose limits are ±π within the tolerance, and the load warnings.
#[derive(clap::Args, Debug)]
pub struct SpherizeArgs {
    /// Model name (from the robots folder) or a path to a .urdf file.
    pub robot: String,
    /// Largest protrusion wanted beyond a box face or capsule surface, metres (0.001–0.5).
    #[arg(long, default_value_t = 0.01)]
    pub tolerance: f64,
    /// Most spheres per collision primitive (2–4096).
    #[arg(long, default_value_t = 64)]
    pub max_per_shape: usize,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn robot_spherize(ctx: &Ctx, a: &SpherizeArgs) -> Result<()> {
    use manyhands::model::spherize::{spherize, SpherizeSettings};
    if !(0.001..=0.5).contains(&a.tolerance) {
        bail!(
            "--tolerance must be within [0.001, 0.5] m, got {}",
            a.tolerance
        );
    }
    if !(2..=4096).contains(&a.max_per_shape) {
        bail!(
            "--max-per-shape must be within 2..=4096, got {}",
            a.max_per_shape
        );
    }
    let r = ctx.robot(&a.robot)?;
    let (s, report) = spherize(
        &r,
        &SpherizeSettings {
            tolerance: a.tolerance,
            max_per_shape: a.max_per_shape,
        },
    );
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let urdf = a.out.join(format!("{}.urdf", s.name));
    let srdf = a.out.join(format!("{}.srdf", s.name));
    std::fs::write(&urdf, manyhands::model::to_urdf(&s))?;
    std::fs::write(&srdf, manyhands::model::to_srdf(&s))?;
    // Read back as any user's robot would be: load-time checks (always-colliding pairs) apply.
    let back = Robot::from_files(&urdf, Some(&srdf))
        .with_context(|| format!("reading back {}", urdf.display()))?;
    let spheres: usize = report.iter().map(|l| l.spheres).sum();
    let worst = report.iter().map(|l| l.max_protrusion).fold(0.0, f64::max);
    if ctx.json {
        println!(
            "{}",
            json!({"urdf": urdf, "srdf": srdf, "spheres": spheres, "max_protrusion_m": worst,
                   "links": report, "always_colliding_added": back.always_colliding.len()})
        );
    } else {
        println!(
            "{} → {}: {} spheres on {} links, largest protrusion {:.4} m; {} always-colliding pairs disabled at load",
            r.name,
            urdf.display(),
            spheres,
            report.len(),
            worst,
            back.always_colliding.len()
        );
        for l in &report {
            println!(
                "  {:<28} {:>3} primitives → {:>4} spheres, protrusion ≤ {:.4} m",
                l.link, l.primitives, l.spheres, l.max_protrusion
            );
        }
    }
    Ok(())
}

pub fn robot_check(ctx: &Ctx, name: &str, srdf: Option<&Path>) -> Result<()> {
    use manyhands::collision::always;
    let r = match srdf {
        Some(s) => Arc::new(
            Robot::from_files(Path::new(name), Some(s))
                .with_context(|| format!("loading {name} with {}", s.display()))?,
        ),
        None => ctx.robot(name)?,
    };
    let pairs: Vec<Value> = r
        .always_colliding
        .iter()
        .map(|c| {
            json!({"link1": r.links[c.a].name, "link2": r.links[c.b].name,
                "fraction": c.fraction, "srdf": always::srdf_line(&r, c)})
        })
        .collect();
    let pi_joints: Vec<Value> = (0..r.dof())
        .filter(|&v| r.var_limits(v).is_revolute_pi())
        .map(|v| {
            let l = r.var_limits(v);
            json!({"joint": r.var_name(v), "lower": l.lower, "upper": l.upper})
        })
        .collect();
    let v = json!({
        "name": r.name, "samples": always::SAMPLES, "min_fraction": always::MIN_FRACTION,
        "always_colliding": pairs, "revolute_pi_joints": pi_joints,
        "limit_tolerance": manyhands::model::Limits::TOLERANCE, "warnings": r.warnings,
    });
    ctx.print(&v, || {
        let mut s = format!(
            "robot {}: link pairs colliding in ≥ {:.0} % of {} random configurations, not disabled by the SRDF: {}\n",
            r.name,
            100.0 * always::MIN_FRACTION,
            always::SAMPLES,
            r.always_colliding.len()
        );
        for c in &r.always_colliding {
            s += &format!(
                "  {} – {} ({:.1} %): treated as disabled; SRDF line: {}\n",
                r.links[c.a].name,
                r.links[c.b].name,
                100.0 * c.fraction,
                always::srdf_line(&r, c)
            );
        }
        s += &format!(
            "revolute joints with limits ±π (within {:e}; values ±π accepted, clamped): {}\n",
            manyhands::model::Limits::TOLERANCE,
            pi_joints.len()
        );
        for v in (0..r.dof()).filter(|&v| r.var_limits(v).is_revolute_pi()) {
            let l = r.var_limits(v);
            s += &format!("  {} [{}, {}]\n", r.var_name(v), l.lower, l.upper);
        }
        s += &format!("warnings: {}\n", r.warnings.len());
        for w in &r.warnings {
            s += &format!("  {w}\n");
        }
        s.trim_end().to_string()
    });
    Ok(())
}

pub fn robot_show(ctx: &Ctx, name: &str) -> Result<()> {
    let r = ctx.robot(name)?;
    let joints: Vec<Value> = r
        .joints
        .iter()
        .map(|j| {
            json!({
                "name": j.name, "type": j.kind.name(),
                "parent": r.links[j.parent].name, "child": r.links[j.child].name,
                "axis": [j.axis.x, j.axis.y, j.axis.z],
                "variable": j.var,
                "mimic": j.mimic.map(|m| json!({"joint": r.var_name(m.var), "multiplier": m.multiplier, "offset": m.offset})),
                "limits": if j.is_movable() { json!({"lower": j.limits.lower, "upper": j.limits.upper, "velocity": j.limits.velocity, "effort": j.limits.effort, "bounded": j.limits.bounded}) } else { Value::Null },
            })
        })
        .collect();
    let links: Vec<Value> = r
        .links
        .iter()
        .map(|l| json!({"name": l.name, "collision": l.collision.iter().map(|g| json!({"origin": pose_json(&g.origin), "shape": shape_json(&g.shape)})).collect::<Vec<_>>()}))
        .collect();
    let groups: Vec<Value> = r
        .groups
        .iter()
        .map(|g| json!({"name": g.name, "dof": g.vars.len(), "joints": g.vars.iter().map(|&v| r.var_name(v)).collect::<Vec<_>>(),
            "chain": g.chain.map(|(b, t)| json!({"base_link": r.links[b].name, "tip_link": r.links[t].name}))}))
        .collect();
    let eefs: Vec<Value> = r
        .end_effectors
        .iter()
        .map(|e| json!({"name": e.name, "parent_link": r.links[e.parent_link].name, "group": e.group, "parent_group": e.parent_group}))
        .collect();
    let states: Vec<Value> = r
        .group_states
        .iter()
        .map(|s| json!({"name": s.name, "group": s.group}))
        .collect();
    let v = json!({
        "name": r.name, "dof": r.dof(), "links": links, "joints": joints, "groups": groups,
        "end_effectors": eefs, "group_states": states,
        "disabled_collision_pairs": r.disabled_reasons.len(), "warnings": r.warnings,
    });
    ctx.print(&v, || {
        let mut s = format!(
            "robot {}: {} DoF, {} links, {} joints\n",
            r.name,
            r.dof(),
            r.links.len(),
            r.joints.len()
        );
        s += "joints (variables):\n";
        for v in 0..r.dof() {
            let j = &r.joints[r.vars[v]];
            s += &format!(
                "  {:2} {:<22} {:<10} [{:>8.4}, {:>8.4}]  vel {:.2} effort {:.1}\n",
                v,
                j.name,
                j.kind.name(),
                j.limits.lower,
                j.limits.upper,
                j.limits.velocity,
                j.limits.effort
            );
        }
        s += "groups:\n";
        for g in &r.groups {
            let chain = g
                .chain
                .map(|(b, t)| format!(" chain {} → {}", r.links[b].name, r.links[t].name))
                .unwrap_or_default();
            s += &format!("  {:<18} {:2} DoF{}\n", g.name, g.vars.len(), chain);
        }
        s += "end effectors:\n";
        for e in &r.end_effectors {
            s += &format!(
                "  {} at {} (group {})\n",
                e.name, r.links[e.parent_link].name, e.group
            );
        }
        s += "named states: ";
        let mut names: Vec<&str> = r.group_states.iter().map(|s| s.name.as_str()).collect();
        names.dedup();
        s += &names.join(", ");
        s += "\nlinks and collision shapes:\n";
        for l in &r.links {
            let shapes: Vec<String> = l
                .collision
                .iter()
                .map(|g| g.shape.kind().to_string())
                .collect();
            s += &format!("  {:<24} {}\n", l.name, shapes.join(" "));
        }
        s += &format!("disabled collision pairs: {}", r.disabled_reasons.len());
        for w in &r.warnings {
            s += &format!("\nwarning: {w}");
        }
        s
    });
    Ok(())
}

/// Parses a configuration: either `dof` numbers (comma/space separated) or `joint=value` pairs
/// applied on top of `base`.
pub fn parse_config(robot: &Robot, text: &str, base: &[f64]) -> Result<Vec<f64>> {
    let parts: Vec<&str> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect();
    if parts.iter().all(|p| !p.contains('=')) {
        let mut q: Vec<f64> = parts
            .iter()
            .map(|p| {
                p.parse::<f64>()
                    .with_context(|| format!("--config: '{p}' is not a number"))
            })
            .collect::<Result<_>>()?;
        robot
            .accept_config(&mut q)
            .map_err(|e| anyhow!("--config: {e}"))?;
        return Ok(q);
    }
    let mut map = std::collections::BTreeMap::new();
    for p in parts {
        let (k, v) = p
            .split_once('=')
            .ok_or_else(|| anyhow!("--config: '{p}' is not joint=value"))?;
        map.insert(
            k.to_string(),
            v.parse::<f64>()
                .with_context(|| format!("--config: '{v}' is not a number"))?,
        );
    }
    robot
        .config_from_map(base, &map)
        .map_err(|e| anyhow!("--config: {e}"))
}

fn parse_pose(text: &str) -> Result<Pose> {
    let v: Vec<f64> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|p| {
            p.parse::<f64>()
                .with_context(|| format!("--pose: '{p}' is not a number"))
        })
        .collect::<Result<_>>()?;
    if v.iter().any(|x| !x.is_finite()) {
        bail!("--pose: values must be finite");
    }
    match v.len() {
        6 => Ok(iso_from_rpy([v[0], v[1], v[2]], [v[3], v[4], v[5]])),
        7 => manyhands::geometry::PoseJson {
            position: Some([v[0], v[1], v[2]]),
            rpy: None,
            quat_xyzw: Some([v[3], v[4], v[5], v[6]]),
        }
        .to_pose()
        .map_err(|e| anyhow!("--pose: {e}")),
        n => bail!(
            "--pose: expected 6 values (x y z roll pitch yaw) or 7 (x y z qx qy qz qw), got {n}"
        ),
    }
}

fn start_config(robot: &Robot, named: Option<&str>, config: Option<&str>) -> Result<Vec<f64>> {
    let base = match named {
        Some(n) => robot
            .named_config(n)
            .ok_or_else(|| anyhow!("--named: robot '{}' has no group state '{n}'", robot.name))?,
        None => robot
            .named_config("home")
            .unwrap_or_else(|| robot.zero_config()),
    };
    match config {
        Some(c) => parse_config(robot, c, &base),
        None => Ok(base),
    }
}

#[derive(Args, Debug)]
pub struct FkArgs {
    /// Model name or .urdf path.
    pub robot: String,
    /// `dof` values, or `joint=value` pairs on top of --named (default: the `home` state or zero).
    #[arg(long, allow_hyphen_values = true)]
    pub config: Option<String>,
    /// SRDF group state to start from.
    #[arg(long)]
    pub named: Option<String>,
    /// Only this link (default: all links).
    #[arg(long)]
    pub link: Option<String>,
}

pub fn fk(ctx: &Ctx, a: &FkArgs) -> Result<()> {
    let r = ctx.robot(&a.robot)?;
    let q = start_config(&r, a.named.as_deref(), a.config.as_deref())?;
    let mut poses = vec![Pose::identity(); r.links.len()];
    forward(&r, &Pose::identity(), &q, &mut poses);
    let links: Vec<usize> = match &a.link {
        Some(l) => vec![r
            .link(l)
            .ok_or_else(|| anyhow!("--link: unknown link '{l}'"))?],
        None => (0..r.links.len()).collect(),
    };
    let v = json!({"robot": r.name, "config": q, "links": links.iter().map(|&l| json!({"link": r.links[l].name, "pose": pose_json(&poses[l])})).collect::<Vec<_>>()});
    ctx.print(&v, || {
        links
            .iter()
            .map(|&l| {
                let t = poses[l].translation.vector;
                let rpy = quat_to_rpy(&poses[l].rotation);
                format!(
                    "{:<24} xyz [{:>8.4} {:>8.4} {:>8.4}]  rpy [{:>7.4} {:>7.4} {:>7.4}]",
                    r.links[l].name, t.x, t.y, t.z, rpy[0], rpy[1], rpy[2]
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    });
    Ok(())
}

#[derive(Args, Debug)]
pub struct IkArgs {
    /// Model name or .urdf path.
    pub robot: String,
    /// SRDF group whose chain is solved (e.g. right_arm).
    #[arg(long)]
    pub group: String,
    /// Target pose of the chain tip: x,y,z,roll,pitch,yaw or x,y,z,qx,qy,qz,qw.
    #[arg(long, allow_hyphen_values = true)]
    pub pose: String,
    /// Frame of --pose: `root` (robot root link, default) or `base` (the chain's base link).
    #[arg(long, default_value = "root")]
    pub frame: String,
    /// Configuration of the other joints and seed (`joint=value` pairs or all values).
    #[arg(long, allow_hyphen_values = true)]
    pub config: Option<String>,
    /// Use the numeric solver (damped least squares) even for S-R-S arms.
    #[arg(long)]
    pub numeric: bool,
    /// Swivel angles enumerated by the analytic solver over [-π, π).
    #[arg(long, default_value_t = 36)]
    pub psi_steps: usize,
    /// Order of solutions: `seed` (nearest to the configuration first) or `random`.
    #[arg(long, default_value = "seed")]
    pub order: String,
    /// At most this many solutions are printed.
    #[arg(long, default_value_t = 16)]
    pub max: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn ik(ctx: &Ctx, a: &IkArgs) -> Result<()> {
    let r = ctx.robot(&a.robot)?;
    let q0 = start_config(&r, None, a.config.as_deref())?;
    let chain = Chain::from_group(&r, &a.group).ok_or_else(|| {
        anyhow!(
            "--group: '{}' is not a chain group of robot '{}'",
            a.group,
            r.name
        )
    })?;
    let target_in = parse_pose(&a.pose)?;
    let base_pose = manyhands::kinematics::link_pose(&r, &q0, chain.base_link);
    let target = match a.frame.as_str() {
        "root" => base_pose.inverse() * target_in,
        "base" => target_in,
        f => bail!("--frame: '{f}' is not 'root' or 'base'"),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(a.seed);
    let started = std::time::Instant::now();
    let (solver, solutions): (&str, Vec<Vec<f64>>) = match (a.numeric, SrsArm::new(&r, &chain)) {
        (false, Ok(arm)) => {
            let order = match a.order.as_str() {
                "seed" => {
                    let mut s7 = [0.0; 7];
                    for (i, &v) in arm.vars().iter().enumerate() {
                        s7[i] = q0[v];
                    }
                    SolutionOrder::NearestTo(s7)
                }
                "random" => SolutionOrder::Random,
                o => bail!("--order: '{o}' is not 'seed' or 'random'"),
            };
            let sols = arm.solve_enumerate(&target, a.psi_steps.max(1), order, &mut rng);
            let full = sols
                .iter()
                .map(|s| {
                    let mut q = q0.clone();
                    arm.to_config(s, &mut q);
                    q
                })
                .collect();
            ("analytic S-R-S", full)
        }
        _ => {
            let mut ik = NumericIk::new(&r, &chain);
            match ik.solve(&target, &q0, &mut rng) {
                Ok(q) => ("numeric DLS", vec![q]),
                Err(_) => ("numeric DLS", vec![]),
            }
        }
    };
    let elapsed = started.elapsed();
    let shown: Vec<&Vec<f64>> = solutions.iter().take(a.max).collect();
    let group_vars = &chain.vars;
    let v = json!({
        "robot": r.name, "group": a.group, "solver": solver, "solutions_found": solutions.len(),
        "time_us": elapsed.as_secs_f64() * 1e6,
        "joints": group_vars.iter().map(|&v| r.var_name(v)).collect::<Vec<_>>(),
        "solutions": shown.iter().map(|q| group_vars.iter().map(|&v| q[v]).collect::<Vec<_>>()).collect::<Vec<_>>(),
    });
    ctx.print(&v, || serde_json::to_string_pretty(&v).unwrap_or_default());
    if solutions.is_empty() {
        bail!("no IK solution for the target pose ({solver})");
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Scene name or path to a scene .json.
    pub scene: String,
    /// Robot instance of the scene the configuration is for (default: the first).
    #[arg(long)]
    pub robot: Option<String>,
    /// `joint=value` pairs or all values, on top of the robot's start configuration.
    #[arg(long, allow_hyphen_values = true)]
    pub config: Option<String>,
    /// Named configuration of the placement (scene `configs`) or the model's group states.
    #[arg(long)]
    pub named: Option<String>,
}

pub fn check(ctx: &Ctx, a: &CheckArgs) -> Result<()> {
    let scene = ctx.scene(&a.scene)?;
    let world = CollisionWorld::from_scene(&scene);
    let mut q = CollisionWorld::start_config(&scene);
    if !scene.robots.is_empty() {
        let ri = match &a.robot {
            Some(n) => scene
                .robots
                .iter()
                .position(|r| &r.name == n)
                .ok_or_else(|| anyhow!("--robot: no robot '{n}' in scene"))?,
            None => 0,
        };
        let p = &scene.robots[ri];
        let mut base = p.start_config();
        if let Some(n) = &a.named {
            base = p
                .configs
                .get(n)
                .cloned()
                .or_else(|| p.robot.named_config(n))
                .ok_or_else(|| anyhow!("--named: no configuration '{n}'"))?;
        }
        let qr = match &a.config {
            Some(c) => parse_config(&p.robot, c, &base)?,
            None => base,
        };
        let off = world.robots[ri].offset;
        q[off..off + qr.len()].copy_from_slice(&qr);
    }
    let mut exact = ExactChecker::new(&world);
    let mut fast = FastChecker::new(&world);
    let ce = exact.first_contact(&q);
    let cf = fast.first_contact(&q);
    let v = json!({"scene": scene.name, "collision": ce.is_some(), "pair": ce.as_ref().map(|c| [c.a.clone(), c.b.clone()]),
        "fast_checker": {"collision": cf.is_some(), "pair": cf.as_ref().map(|c| [c.a.clone(), c.b.clone()])}});
    ctx.print(&v, || match (&ce, &cf) {
        (Some(c), _) => format!("collision: {} <-> {}", c.a, c.b),
        (None, Some(c)) => format!(
            "free (exact); the fast checker's conservative model touches {} <-> {}",
            c.a, c.b
        ),
        (None, None) => "free".to_string(),
    });
    Ok(())
}

pub fn scene_list(ctx: &Ctx) -> Result<()> {
    let lib = ctx.library()?;
    let scenes = load_scene_dir(&ctx.scenes_dir, &lib)?;
    let v = json!(scenes.values().map(|s| json!({"name": s.name, "robots": s.robots.len(), "obstacles": s.obstacles.len(), "objects": s.objects.len()})).collect::<Vec<_>>());
    ctx.print(&v, || {
        scenes
            .values()
            .map(|s| {
                format!(
                    "{:<12} {} robots, {} obstacles, {} objects — {}",
                    s.name,
                    s.robots.len(),
                    s.obstacles.len(),
                    s.objects.len(),
                    s.description
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    });
    Ok(())
}

#[derive(Args, Debug)]
pub struct RandomBoxesArgs {
    /// Scene the boxes are added to (its robots stay).
    #[arg(long, default_value = "empty")]
    pub base: String,
    #[arg(long, default_value_t = 30)]
    pub boxes: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct PandaFourArgs {
    /// Model name the scene's arms use.
    #[arg(long, default_value = "panda")]
    pub model: String,
    /// Folder to write `robots/` (the Panda of the fetched MotionBenchMaker data) and
    /// `scenes/panda_four.json` into (default: print the scene JSON).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn panda_four(a: &PandaFourArgs) -> Result<()> {
    let scene = manyhands::model::panda_four(&a.model);
    let text = serde_json::to_string_pretty(&scene)?;
    let Some(out) = &a.out else {
        println!("{text}");
        return Ok(());
    };
    let data = manyhands::benchmark::mbm_data::locate().map_err(|e| anyhow::anyhow!(e))?;
    let files = manyhands::benchmark::mbm_data::robot_files(&data, "panda");
    let (robots, scenes) = (out.join("robots"), out.join("scenes"));
    for d in [&robots, &scenes] {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    for (from, to) in [
        (&files.urdf, robots.join(format!("{}.urdf", a.model))),
        (&files.srdf, robots.join(format!("{}.srdf", a.model))),
    ] {
        std::fs::copy(from, &to)
            .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
    }
    let file = scenes.join("panda_four.json");
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))?;
    println!(
        "wrote {} and {}; use them with --robots {} --scenes {}",
        robots.display(),
        file.display(),
        robots.display(),
        scenes.display()
    );
    Ok(())
}

#[derive(Args, Debug)]
pub struct VampMrArgs {
    /// The cell: `panda_two_rod`, `panda_four` or `panda_four_bins`.
    pub cell: String,
    /// Folder to write `robots/` (the cell's arm model) and `scenes/vamp_mr_CELL.json` into
    /// (default: print the scene JSON).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn vamp_mr(a: &VampMrArgs) -> Result<()> {
    let data = manyhands::benchmark::mbm_data::locate().map_err(|e| anyhow::anyhow!(e))?;
    let cell = manyhands::benchmark::multi_arm_cells::vamp_mr_by_name(&a.cell, &data)?;
    let text = serde_json::to_string_pretty(&cell.json)?;
    let Some(out) = &a.out else {
        println!("{text}");
        return Ok(());
    };
    let (robots, scenes) = (out.join("robots"), out.join("scenes"));
    for d in [&robots, &scenes] {
        std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
    }
    for m in &cell.models {
        for (ext, body) in [("urdf", &m.urdf), ("srdf", &m.srdf)] {
            let f = robots.join(format!("{}.{ext}", m.name));
            std::fs::write(&f, body).with_context(|| format!("writing {}", f.display()))?;
        }
    }
    let file = scenes.join(format!("{}.json", cell.json.name));
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))?;
    println!(
        "wrote {} and {}; use them with --robots {} --scenes {}",
        robots.display(),
        file.display(),
        robots.display(),
        scenes.display()
    );
    Ok(())
}

pub fn random_boxes(ctx: &Ctx, a: &RandomBoxesArgs) -> Result<()> {
    let lib = ctx.library()?;
    let base = ctx.scene(&a.base)?;
    let s = gen_boxes(
        &base,
        &RandomBoxes {
            count: a.boxes,
            seed: a.seed,
            ..RandomBoxes::default()
        },
        &lib,
    )?;
    let text = serde_json::to_string_pretty(&s.json)?;
    match &a.out {
        Some(p) => std::fs::write(p, text).with_context(|| format!("writing {}", p.display()))?,
        None => println!("{text}"),
    }
    Ok(())
}
