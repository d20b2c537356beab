//! `manyhands grasp quality`: force closure, wrench rank and the Ferrari–Canny ε (L1 grasp wrench
//! space, [`manyhands::grasp`]) of a scene object's grasps or of contacts read from a file.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use clap::{ArgGroup, Args, Subcommand};
use nalgebra::Vector3;
use serde::Deserialize;
use serde_json::{json, Value};

use manyhands::grasp::{
    grasp_quality, score_object_grasps, Contact, GraspError, GraspQuality, WrenchSpaceSettings,
};
use manyhands::model::{ContactPoint, GraspType};

use super::commands::Ctx;

#[derive(Subcommand, Debug)]
pub enum GraspCmd {
    /// Force closure, wrench rank and Ferrari–Canny ε of a scene object's grasps (--scene,
    /// --object) or of contacts from a JSON file (--contacts).
    Quality(QualityArgs),
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
