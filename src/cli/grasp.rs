//! `manyhands grasp quality`: force closure, wrench rank and the Ferrari–Canny ε (L1 grasp wrench
//! space, [`manyhands::grasp`]) of a scene object's grasps or of contacts read from a file.
//! `manyhands grasp list`: the single-grasp list of a hand and an object (paper 003 §IV-A,
//! [`manyhands::grasp::list`]), cached in `data/grasps`, with a progress bar.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use clap::{ArgGroup, Args, Subcommand};
use nalgebra::Vector3;
use serde::Deserialize;
use serde_json::{json, Value};

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};
use manyhands::grasp::list::workspace_params;
use manyhands::grasp::list_cache::list_file_name;
use manyhands::grasp::{
    build_grasp_list, grasp_quality, load_grasp_list, save_grasp_list, score_object_grasps,
    Contact, GraspError, GraspList, GraspListCache, GraspListParams, GraspObject, GraspQuality,
    Hand, SingleGrasp, WrenchSpaceSettings,
};
use manyhands::model::{ContactPoint, GraspType};

use super::commands::Ctx;

#[derive(Subcommand, Debug)]
pub enum GraspCmd {
    /// Force closure, wrench rank and Ferrari–Canny ε of a scene object's grasps (--scene,
    /// --object) or of contacts from a JSON file (--contacts).
    Quality(QualityArgs),
    /// The single-grasp list of a multi-finger hand and an object (paper 003 §IV-A): built once
    /// and cached (refused and rebuilt when hand, object or parameters differ).
    List(Box<ListArgs>),
}

/// The parameters of a grasp list ([`GraspListParams`]); unset flags keep the defaults.
#[derive(Args, Debug, Clone)]
pub struct ListParamArgs {
    /// Grasp positions in the object's box (about).
    #[arg(long)]
    pub positions: Option<usize>,
    /// SO(3) grid level: 72 · 8^level orientations (0..=4).
    #[arg(long)]
    pub orientation_level: Option<u32>,
    /// Spacing of the surface samples in m (default: the smallest fingertip radius).
    #[arg(long)]
    pub spacing: Option<f64>,
    /// Grid values per finger joint for the workspace spheres (003 Alg. 1).
    #[arg(long)]
    pub workspace_steps: Option<usize>,
    /// Most workspace spheres per finger.
    #[arg(long)]
    pub max_spheres: Option<usize>,
    /// Surface points tried per workspace sphere.
    #[arg(long)]
    pub candidates: Option<usize>,
    /// Values tried for a thumb's base joint.
    #[arg(long)]
    pub base_steps: Option<usize>,
    /// Thumb contacts tried per grasp frame until a closure is force closure.
    #[arg(long)]
    pub thumb_contacts: Option<usize>,
    /// Near-duplicate distance in m (default: the narrowest fingertip's width).
    #[arg(long)]
    pub min_separation: Option<f64>,
    /// Depth in m by which a fingertip may enter the object at a contact.
    #[arg(long)]
    pub contact_tolerance: Option<f64>,
    /// Friction coefficient μ of the force-closure test.
    #[arg(long, allow_negative_numbers = true)]
    pub mu: Option<f64>,
    /// Quality weights: force closure, centroid, force ellipsoid, curvature (003: 1,1,1,6).
    #[arg(long, allow_negative_numbers = true)]
    pub weights: Option<String>,
    /// Most grasps kept.
    #[arg(long)]
    pub max_grasps: Option<usize>,
    /// Finger groups in search order, thumb first (default: most joints first).
    #[arg(long)]
    pub fingers: Option<String>,
    /// Seed of the surface sampling and IK restarts.
    #[arg(long)]
    pub seed: Option<u64>,
}

impl ListParamArgs {
    pub fn params(&self) -> Result<GraspListParams> {
        let mut p = GraspListParams::default();
        if let Some(v) = self.positions {
            p.positions = v;
        }
        if let Some(v) = self.orientation_level {
            p.orientation_level = v;
        }
        p.surface_spacing = self.spacing.or(p.surface_spacing);
        if let Some(v) = self.workspace_steps {
            p.workspace_steps = v;
        }
        if let Some(v) = self.max_spheres {
            p.max_spheres = v;
        }
        if let Some(v) = self.candidates {
            p.candidates_per_sphere = v;
        }
        if let Some(v) = self.base_steps {
            p.base_steps = v;
        }
        if let Some(v) = self.thumb_contacts {
            p.thumb_contacts = v;
        }
        p.min_separation = self.min_separation.or(p.min_separation);
        if let Some(v) = self.contact_tolerance {
            p.contact_tolerance = v;
        }
        if let Some(v) = self.mu {
            p.mu = v;
        }
        if let Some(w) = &self.weights {
            let v: Vec<f64> = w
                .split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| anyhow!("weights: '{w}': {e} (flag --weights)"))?;
            p.weights = v
                .try_into()
                .map_err(|_| anyhow!("weights: four values expected (flag --weights)"))?;
        }
        if let Some(v) = self.max_grasps {
            p.max_grasps = v;
        }
        if let Some(f) = &self.fingers {
            p.fingers = Some(f.split(',').map(|s| s.trim().to_string()).collect());
        }
        if let Some(v) = self.seed {
            p.seed = v;
        }
        p.validate().map_err(|e| anyhow!("{e}"))?;
        Ok(p)
    }
}

#[derive(Args, Debug)]
pub struct ListArgs {
    /// Robot (name in robots/ or a .urdf path).
    #[arg(long)]
    pub robot: String,
    /// The hand's SRDF group (its fingers are the chain groups within it).
    #[arg(long)]
    pub hand: String,
    /// The object: a mesh file, or the name of one in the scenes folder's meshes/ (e.g.
    /// statuette).
    #[arg(long)]
    pub mesh: String,
    #[command(flatten)]
    pub params: ListParamArgs,
    /// Folder of cached lists.
    #[arg(long, default_value = "data/grasps")]
    pub cache: PathBuf,
    /// Build even if a cached list exists (the cache is still updated).
    #[arg(long)]
    pub rebuild: bool,
    /// Also write the list to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Check this list file against the hand, object and parameters instead of building.
    #[arg(long, conflicts_with_all = ["out", "rebuild"])]
    pub load: Option<PathBuf>,
    /// Grasps to print (best first).
    #[arg(long, default_value_t = 5)]
    pub top: usize,
}

/// The object of `--mesh`: a path, else `scenes/meshes/NAME.obj`.
pub fn mesh_object(ctx: &Ctx, mesh: &str) -> Result<GraspObject> {
    let p = Path::new(mesh);
    let path = if p.is_file() {
        p.to_path_buf()
    } else {
        let named = ctx.scenes_dir.join("meshes").join(format!("{mesh}.obj"));
        if !named.is_file() {
            bail!(
                "mesh: '{mesh}' is neither a file nor a mesh of {} (flag --mesh)",
                ctx.scenes_dir.join("meshes").display()
            );
        }
        named
    };
    GraspObject::from_mesh_file(&path).map_err(|e| anyhow!("{e} (flag --mesh)"))
}

fn list(ctx: &Ctx, a: &ListArgs) -> Result<()> {
    let params = a.params.params()?;
    let robot = ctx.robot(&a.robot)?;
    let hand = Hand::new(
        robot,
        &a.hand,
        params.fingers.as_deref(),
        &workspace_params(&params),
    )
    .map_err(|e| anyhow!("{e} (flag --{})", e.field()))?;
    let object = mesh_object(ctx, &a.mesh)?;
    if let Some(file) = &a.load {
        let l = load_grasp_list(file, &hand, &object, &params).map_err(|e| anyhow!("{e}"))?;
        return print_list(ctx, &l, false, a.top);
    }
    let cache = GraspListCache::new(Some(a.cache.clone()));
    let hidden = ctx.json || !std::io::stderr().is_terminal();
    let bar = if hidden {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template("grasp frames [{bar:30}] {pos}/{len} {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    let (l, built) = if a.rebuild {
        let l = build_grasp_list(&hand, &object, &params, &progress, &|| false)
            .map_err(|e| anyhow!("{e}"))?;
        let dir = &a.cache;
        if std::fs::create_dir_all(dir).is_ok() {
            let _ = save_grasp_list(&l, &dir.join(list_file_name(&hand, &object, &params)));
        }
        (std::sync::Arc::new(l), true)
    } else {
        cache
            .get_or_build(&hand, &object, &params, &progress, &|| false)
            .map_err(|e| anyhow!("{e}"))?
    };
    bar.finish_and_clear();
    if let Some(out) = &a.out {
        save_grasp_list(&l, out).map_err(|e| anyhow!("{e}"))?;
    }
    print_list(ctx, &l, built, a.top)
}

fn print_list(ctx: &Ctx, l: &GraspList, built: bool, top: usize) -> Result<()> {
    let best: Vec<&SingleGrasp> = l.grasps.iter().take(top).collect();
    let v = json!({
        "robot": l.robot, "hand": l.hand, "object": l.object, "built": built,
        "fingers": l.fingers, "params": l.params, "stats": l.stats,
        "hand_hash": l.hand_hash, "object_hash": l.object_hash, "params_hash": l.params_hash,
        "grasps": l.grasps.len(), "best": best,
    });
    ctx.print(&v, || {
        let s = &l.stats;
        let mut t = format!(
            "{} {} × {}: {} grasps ({} {:.2} s; {} frames, palm free {}, thumb contact {}, ≥3 contacts {}, force closure {}; {} surface points, spheres per finger {:?})\n",
            l.robot,
            l.hand,
            l.object,
            l.grasps.len(),
            if built { "built in" } else { "cached, built in" },
            s.seconds,
            s.frames,
            s.palm_free,
            s.thumb_contacts,
            s.candidates,
            s.force_closure,
            s.surface_points,
            s.spheres
        );
        for (i, g) in best.iter().enumerate() {
            let fingers: Vec<&str> = g.contacts.iter().map(|c| c.finger.as_str()).collect();
            t += &format!(
                "  #{i}: quality {:.3} (fc {:.3}, centroid {:.3}, ellipsoid {:.3}, curvature {:.3}), ε {:.4}, contacts {}\n",
                g.quality,
                g.scores.force_closure,
                g.scores.centroid,
                g.scores.ellipsoid,
                g.scores.curvature,
                g.epsilon,
                fingers.join(",")
            );
        }
        t
    });
    Ok(())
}

#[derive(Args, Debug)]
#[command(group(ArgGroup::new("input").required(true).args(["scene", "contacts"])))]
pub struct QualityArgs {
    /// Scene (name or path to a .json) whose object's grasps are scored; needs --object.
    #[arg(long, requires = "object", conflicts_with = "contacts")]
    pub scene: Option<String>,
    /// Object of the scene. Its grasps' stored contacts are scored about its centre of mass
    /// (uniform density) with λ = 1 / its radius unless --lambda is given.
    #[arg(long, requires = "scene")]
    pub object: Option<String>,
    /// Only this grasp of the object.
    #[arg(long, requires = "object")]
    pub grasp: Option<String>,
    /// JSON file {"contacts": [{"point": [x, y, z], "normal": [x, y, z]}, …], "centre": [x, y, z]}:
    /// inward normals (the finger force direction), centre = the object's centre of mass, one
    /// frame. λ defaults to 1 / the largest contact distance from the centre.
    #[arg(long)]
    pub contacts: Option<PathBuf>,
    /// Centre of mass x,y,z (replaces the file's or the object's).
    #[arg(long, allow_hyphen_values = true)]
    pub centre: Option<String>,
    /// Coulomb friction coefficient μ (JSON field mu).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub mu: f64,
    /// Edges of the linearised friction cone, 3..=32 (JSON field cone_edges).
    #[arg(long, default_value_t = 8)]
    pub edges: usize,
    /// Torque scale λ in 1/m (JSON field lambda).
    #[arg(long, allow_negative_numbers = true)]
    pub lambda: Option<f64>,
    /// Soft-finger torsional friction γ in m: adds the wrenches [0; ±λγn] per contact (JSON
    /// field soft_finger).
    #[arg(long, allow_negative_numbers = true)]
    pub soft: Option<f64>,
}

pub fn run(ctx: &Ctx, cmd: &GraspCmd) -> Result<()> {
    match cmd {
        GraspCmd::Quality(a) => quality(ctx, a),
        GraspCmd::List(a) => list(ctx, a),
    }
}

/// The contacts file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactsFile {
    contacts: Vec<ContactPoint>,
    #[serde(default)]
    centre: Option<[f64; 3]>,
}

/// The flag of a settings field, for messages.
fn flag_of(field: &str) -> Option<&'static str> {
    match field {
        "mu" => Some("--mu"),
        "cone_edges" => Some("--edges"),
        "lambda" => Some("--lambda"),
        "soft_finger" => Some("--soft"),
        "centre" => Some("--centre"),
        _ => None,
    }
}

/// A library error as a message naming the field (and its flag).
fn grasp_error(e: &GraspError) -> anyhow::Error {
    match flag_of(e.field()) {
        Some(flag) => anyhow!("{e} (flag {flag})"),
        None => anyhow!("{e}"),
    }
}

fn parse_centre(text: &str) -> Result<Vector3<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow!("centre: '{text}' is not x,y,z: {e} (flag --centre)"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vector3::new(x, y, z)),
        [_, _, _] => bail!("centre: '{text}' must be finite (flag --centre)"),
        _ => bail!(
            "centre: '{text}' has {} values, x,y,z expected (flag --centre)",
            v.len()
        ),
    }
}

fn kind_name(k: GraspType) -> &'static str {
    match k {
        GraspType::Power => "power",
        GraspType::Precision => "precision",
        GraspType::Pinch => "pinch",
    }
}

fn quality_json(q: &GraspQuality) -> Value {
    json!({"force_closure": q.force_closure, "rank": q.rank, "epsilon": q.epsilon,
        "wrenches": q.wrenches, "facets": q.facets, "lambda": q.lambda})
}

fn contacts_text(s: &WrenchSpaceSettings) -> String {
    match s.soft_finger {
        Some(g) => format!("soft-finger contacts (γ = {g})"),
        None => "point contacts".into(),
    }
}

fn quality(ctx: &Ctx, a: &QualityArgs) -> Result<()> {
    let settings = WrenchSpaceSettings {
        mu: a.mu,
        cone_edges: a.edges,
        lambda: a.lambda,
        soft_finger: a.soft,
    };
    settings.validate().map_err(|e| grasp_error(&e))?;
    let centre = a.centre.as_deref().map(parse_centre).transpose()?;
    match (&a.contacts, &a.scene, &a.object) {
        (Some(file), _, _) => score_file(ctx, file, centre, &settings),
        (None, Some(scene), Some(object)) => {
            score_scene(ctx, scene, object, a.grasp.as_deref(), centre, &settings)
        }
        // clap enforces --contacts or --scene with --object.
        _ => bail!("give --contacts FILE, or --scene S with --object O"),
    }
}

fn score_file(
    ctx: &Ctx,
    file: &Path,
    centre: Option<Vector3<f64>>,
    settings: &WrenchSpaceSettings,
) -> Result<()> {
    let text =
        std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
    let mut de = serde_json::Deserializer::from_str(&text);
    let parsed: ContactsFile = serde_path_to_error::deserialize(&mut de)
        .map_err(|e| anyhow!("{}: {}: {}", file.display(), e.path(), e.inner()))?;
    let centre = centre.or(parsed.centre.map(Vector3::from)).ok_or_else(|| {
        anyhow!(
            "centre: missing; give the object's centre of mass as \"centre\": [x, y, z] in {} \
                 or --centre x,y,z",
            file.display()
        )
    })?;
    let contacts: Vec<Contact> = parsed.contacts.iter().map(Contact::from).collect();
    let q = grasp_quality(&contacts, &centre, settings)
        .map_err(|e| grasp_error(&e).context(file.display().to_string()))?;
    let mut v = quality_json(&q);
    v["contacts"] = json!(contacts.len());
    v["centre"] = json!([centre.x, centre.y, centre.z]);
    v["mu"] = json!(settings.mu);
    v["cone_edges"] = json!(settings.cone_edges);
    v["soft_finger"] = json!(settings.soft_finger);
    ctx.print(&v, || {
        format!(
            "{} contacts, centre [{}, {}, {}], μ = {}, {} cone edges, λ = {:.6}, {}\n\
             force closure: {}, rank {}, ε = {:.6} ({} wrenches, {} hull facets)",
            contacts.len(),
            centre.x,
            centre.y,
            centre.z,
            settings.mu,
            settings.cone_edges,
            q.lambda,
            contacts_text(settings),
            if q.force_closure { "yes" } else { "no" },
            q.rank,
            q.epsilon,
            q.wrenches,
            q.facets
        )
    });
    Ok(())
}

fn score_scene(
    ctx: &Ctx,
    scene_name: &str,
    object_name: &str,
    grasp: Option<&str>,
    centre: Option<Vector3<f64>>,
    settings: &WrenchSpaceSettings,
) -> Result<()> {
    let scene = ctx.scene(scene_name)?;
    let object = scene.object(object_name).ok_or_else(|| {
        let names: Vec<&str> = scene.objects.iter().map(|o| o.body.name.as_str()).collect();
        anyhow!(
            "--object: scene '{}' has no object '{object_name}' (objects: {})",
            scene.name,
            names.join(", ")
        )
    })?;
    let grasps: Vec<_> = match grasp {
        Some(n) => vec![object.grasps.iter().find(|g| g.name == n).ok_or_else(|| {
            let names: Vec<&str> = object.grasps.iter().map(|g| g.name.as_str()).collect();
            anyhow!(
                "--grasp: object '{object_name}' has no grasp '{n}' (grasps: {})",
                names.join(", ")
            )
        })?],
        None => object.grasps.iter().collect(),
    };
    let scores = score_object_grasps(object, grasps.iter().copied(), centre, settings)
        .map_err(|e| grasp_error(&e))?;
    let c = scores.centre;
    let rows: Vec<Value> = grasps
        .iter()
        .zip(&scores.grasps)
        .map(|(g, q)| {
            let mut v = quality_json(q);
            v["name"] = json!(g.name);
            v["end_effector"] = json!(g.end_effector);
            v["type"] = json!(kind_name(g.kind));
            v["contacts"] = json!(g.contacts.len());
            v["scene_quality"] = json!(g.quality);
            v
        })
        .collect();
    let closing = scores.grasps.iter().filter(|q| q.force_closure).count();
    let v = json!({
        "scene": scene.name, "object": object_name, "centre": [c.x, c.y, c.z],
        "radius": scores.radius, "lambda": scores.settings.lambda, "mu": settings.mu,
        "cone_edges": settings.cone_edges, "soft_finger": settings.soft_finger,
        "force_closure_grasps": closing, "grasps": rows,
    });
    ctx.print(&v, || {
        let lambda = match scores.settings.lambda {
            Some(l) => format!("{l:.4}"),
            None => "1 / largest contact distance".into(),
        };
        let mut s = format!(
            "{}/{object_name}: centre [{:.4}, {:.4}, {:.4}] (object frame), radius {:.4} m, \
             λ = {lambda}, μ = {}, {} cone edges, {}\n",
            scene.name,
            c.x,
            c.y,
            c.z,
            scores.radius,
            settings.mu,
            settings.cone_edges,
            contacts_text(settings)
        );
        s += &format!(
            "{:<16} {:<10} {:>8} {:>5} {:>14} {:>10}\n",
            "grasp", "type", "contacts", "rank", "force closure", "ε"
        );
        for (g, q) in grasps.iter().zip(&scores.grasps) {
            s += &format!(
                "{:<16} {:<10} {:>8} {:>5} {:>14} {:>10.6}\n",
                g.name,
                kind_name(g.kind),
                g.contacts.len(),
                q.rank,
                if q.force_closure { "yes" } else { "no" },
                q.epsilon
            );
        }
        s += &format!("force closure: {closing} of {} grasps", grasps.len());
        s
    });
    Ok(())
}
