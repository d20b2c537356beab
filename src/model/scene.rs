//! `Scene`: fixed obstacles, movable objects with grasp sets, and robots placed by model name.
//! JSON schema: `api/scene.md` and `api/scene.schema.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::robot::{Robot, RobotLibrary};
use super::ModelError;
use crate::geometry::{Geometry, Mesh, Pose, PoseJson, Shape};

/// JSON form of a shape placed in a body (`{"type": "box", "half_extents": […], "pose": …}`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometryJson {
    #[serde(rename = "type")]
    pub kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub half_extents: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseJson>,
}

/// JSON form of an obstacle or object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyJson {
    pub name: String,
    #[serde(default)]
    pub pose: PoseJson,
    pub shapes: Vec<GeometryJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grasps: Vec<GraspJson>,
    /// Objects only: where a pick-and-place task puts the object (paper 003's final pose q_o^f).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<PoseJson>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactPoint {
    /// Contact point in the object frame.
    pub point: [f64; 3],
    /// Unit normal into the object (direction of the finger force).
    pub normal: [f64; 3],
}

/// Kind of grasp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GraspType {
    Power,
    Precision,
    Pinch,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraspJson {
    pub name: String,
    pub end_effector: String,
    pub tcp: PoseJson,
    #[serde(default)]
    pub pregrasp_offset: [f64; 3],
    #[serde(rename = "type")]
    pub kind: GraspType,
    #[serde(default)]
    pub contacts: Vec<ContactPoint>,
    #[serde(default)]
    pub quality: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotPlacementJson {
    pub name: String,
    pub model: String,
    #[serde(default)]
    pub base_pose: PoseJson,
    #[serde(default)]
    pub configs: BTreeMap<String, BTreeMap<String, f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<String>,
}

/// The scene file as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneJson {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub obstacles: Vec<BodyJson>,
    #[serde(default)]
    pub objects: Vec<BodyJson>,
    #[serde(default)]
    pub robots: Vec<RobotPlacementJson>,
}

/// A rigid body of the scene (obstacle or object).
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    pub name: String,
    /// Pose in the world frame.
    pub pose: Pose,
    pub shapes: Vec<Geometry>,
}

/// A grasp: where the hand's TCP goes relative to the object.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    pub name: String,
    pub end_effector: String,
    /// TCP pose in the object frame.
    pub tcp: Pose,
    /// Translation of the pre-grasp TCP pose in the TCP frame.
    pub pregrasp_offset: Vector3<f64>,
    pub kind: GraspType,
    pub contacts: Vec<ContactPoint>,
    pub quality: f64,
}

/// A movable object with its grasp set.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    pub body: Body,
    pub mass: Option<f64>,
    pub grasps: Vec<Grasp>,
    /// Where a pick-and-place task puts the object (003's q_o^f), if the scene says.
    pub goal: Option<Pose>,
}

/// A robot model placed in the scene.
#[derive(Debug, Clone)]
pub struct RobotPlacement {
    /// Instance name (unique in the scene).
    pub name: String,
    pub robot: Arc<Robot>,
    /// Pose of the robot's root link in the world.
    pub base_pose: Pose,
    /// Named full configurations (partial maps in the file, completed from the model's `home`
    /// group state or zero).
    pub configs: BTreeMap<String, Vec<f64>>,
    pub start: Option<String>,
}

impl RobotPlacement {
    /// The start configuration: the named `start`, else `home`, else zero.
    pub fn start_config(&self) -> Vec<f64> {
        self.start
            .as_ref()
            .and_then(|s| self.configs.get(s).cloned())
            .or_else(|| self.robot.named_config("home"))
            .unwrap_or_else(|| self.robot.zero_config())
    }
}

/// A resolved scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub obstacles: Vec<Body>,
    pub objects: Vec<Object>,
    pub robots: Vec<RobotPlacement>,
    /// The file it came from, for writing it back.
    pub json: SceneJson,
}

impl Scene {
    /// Reads and resolves a scene file; models are looked up in `robots`; mesh paths are relative
    /// to the file.
    pub fn from_file(path: &Path, robots: &RobotLibrary) -> Result<Scene, ModelError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ModelError::Io {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::from_str(&text, &file, &base, robots)
    }

    /// Parses scene JSON text (`file` names it in errors).
    pub fn from_str(
        text: &str,
        file: &str,
        base_dir: &Path,
        robots: &RobotLibrary,
    ) -> Result<Scene, ModelError> {
        let json: SceneJson = serde_json::from_str(text).map_err(|e| ModelError::Syntax {
            file: file.to_string(),
            reason: e.to_string(),
        })?;
        Scene::from_json(json, file, base_dir, robots)
    }

    /// Validates and resolves parsed scene JSON. Errors name the field path
    /// (e.g. `robots[0].configs.start.right_elbow`).
    pub fn from_json(
        json: SceneJson,
        file: &str,
        base_dir: &Path,
        robots: &RobotLibrary,
    ) -> Result<Scene, ModelError> {
        let err = |el: String, reason: String| ModelError::invalid(file, el, reason);
        let mut names: BTreeMap<&str, &str> = BTreeMap::new();
        let mut obstacles = Vec::new();
        for (i, b) in json.obstacles.iter().enumerate() {
            let el = format!("obstacles[{i}]");
            if !b.grasps.is_empty() {
                return Err(err(
                    format!("{el}.grasps"),
                    "obstacles are fixed and have no grasps; make it an object".into(),
                ));
            }
            if b.goal.is_some() {
                return Err(err(
                    format!("{el}.goal"),
                    "obstacles are fixed and have no goal pose; make it an object".into(),
                ));
            }
            if let Some(prev) = names.insert(&b.name, "obstacle") {
                return Err(err(
                    format!("{el}.name"),
                    format!("'{}' is already the name of an {prev}", b.name),
                ));
            }
            obstacles.push(body(b, &el, file, base_dir)?);
        }
        let mut objects = Vec::new();
        for (i, b) in json.objects.iter().enumerate() {
            let el = format!("objects[{i}]");
            if let Some(prev) = names.insert(&b.name, "object") {
                return Err(err(
                    format!("{el}.name"),
                    format!("'{}' is already the name of an {prev}", b.name),
                ));
            }
            let body = body(b, &el, file, base_dir)?;
            if let Some(m) = b.mass {
                if !(m.is_finite() && m > 0.0) {
                    return Err(err(
                        format!("{el}.mass"),
                        format!("must be finite and > 0, got {m}"),
                    ));
                }
            }
            let mut grasps = Vec::new();
            for (k, g) in b.grasps.iter().enumerate() {
                let gel = format!("{el}.grasps[{k}]");
                let tcp = g.tcp.to_pose().map_err(|r| err(format!("{gel}.tcp"), r))?;
                if g.pregrasp_offset.iter().any(|v| !v.is_finite()) {
                    return Err(err(
                        format!("{gel}.pregrasp_offset"),
                        "values must be finite".into(),
                    ));
                }
                if !(g.quality.is_finite() && (0.0..=1.0).contains(&g.quality)) {
                    return Err(err(
                        format!("{gel}.quality"),
                        format!("must be in [0, 1], got {}", g.quality),
                    ));
                }
                for (c, cp) in g.contacts.iter().enumerate() {
                    let n = Vector3::from(cp.normal).norm();
                    if cp
                        .point
                        .iter()
                        .chain(cp.normal.iter())
                        .any(|v| !v.is_finite())
                        || (n - 1.0).abs() > 1e-3
                    {
                        return Err(err(
                            format!("{gel}.contacts[{c}]"),
                            "point must be finite and normal a unit vector".into(),
                        ));
                    }
                }
                grasps.push(Grasp {
                    name: g.name.clone(),
                    end_effector: g.end_effector.clone(),
                    tcp,
                    pregrasp_offset: Vector3::from(g.pregrasp_offset),
                    kind: g.kind,
                    contacts: g.contacts.clone(),
                    quality: g.quality,
                });
            }
            let goal = match &b.goal {
                Some(g) => Some(g.to_pose().map_err(|r| err(format!("{el}.goal"), r))?),
                None => None,
            };
            objects.push(Object {
                body,
                mass: b.mass,
                grasps,
                goal,
            });
        }
        let mut placements = Vec::new();
        for (i, r) in json.robots.iter().enumerate() {
            let el = format!("robots[{i}]");
            if placements.iter().any(|p: &RobotPlacement| p.name == r.name) {
                return Err(err(
                    format!("{el}.name"),
                    format!("duplicate robot name '{}'", r.name),
                ));
            }
            let robot = robots.get(&r.model).cloned().ok_or_else(|| {
                err(
                    format!("{el}.model"),
                    format!("unknown robot model '{}'", r.model),
                )
            })?;
            let base_pose = r
                .base_pose
                .to_pose()
                .map_err(|e| err(format!("{el}.base_pose"), e))?;
            let home = robot
                .named_config("home")
                .unwrap_or_else(|| robot.zero_config());
            let mut configs = BTreeMap::new();
            for (cname, values) in &r.configs {
                let q = robot.config_from_map(&home, values).map_err(|e| {
                    let (joint, reason) = e.split_once(": ").unwrap_or(("", e.as_str()));
                    let field = if joint.is_empty() {
                        format!("{el}.configs.{cname}")
                    } else {
                        format!("{el}.configs.{cname}.{joint}")
                    };
                    err(field, reason.to_string())
                })?;
                configs.insert(cname.clone(), q);
            }
            if let Some(s) = &r.start {
                if !configs.contains_key(s) && robot.named_config(s).is_none() {
                    return Err(err(
                        format!("{el}.start"),
                        format!(
                            "no configuration named '{s}' in configs or the model's group states"
                        ),
                    ));
                }
                if !configs.contains_key(s) {
                    if let Some(q) = robot.named_config(s) {
                        configs.insert(s.clone(), q);
                    }
                }
            }
            placements.push(RobotPlacement {
                name: r.name.clone(),
                robot,
                base_pose,
                configs,
                start: r.start.clone(),
            });
        }
        Ok(Scene {
            name: json.name.clone(),
            description: json.description.clone(),
            obstacles,
            objects,
            robots: placements,
            json,
        })
    }

    pub fn robot(&self, name: &str) -> Option<&RobotPlacement> {
        self.robots.iter().find(|r| r.name == name)
    }

    pub fn object(&self, name: &str) -> Option<&Object> {
        self.objects.iter().find(|o| o.body.name == name)
    }
}

fn body(b: &BodyJson, el: &str, file: &str, base_dir: &Path) -> Result<Body, ModelError> {
    let err = |f: String, reason: String| ModelError::invalid(file, f, reason);
    let pose = b.pose.to_pose().map_err(|r| err(format!("{el}.pose"), r))?;
    if b.shapes.is_empty() {
        return Err(err(
            format!("{el}.shapes"),
            "a body needs at least one shape".into(),
        ));
    }
    let mut shapes = Vec::new();
    for (k, g) in b.shapes.iter().enumerate() {
        let gel = format!("{el}.shapes[{k}]");
        shapes.push(geometry(g, &gel, base_dir).map_err(|(f, r)| err(f, r))?);
    }
    Ok(Body {
        name: b.name.clone(),
        pose,
        shapes,
    })
}

/// Resolves one JSON shape; the error is `(field path, reason)`.
pub(crate) fn geometry(
    g: &GeometryJson,
    el: &str,
    base_dir: &Path,
) -> Result<Geometry, (String, String)> {
    let origin = match &g.pose {
        Some(p) => p.to_pose().map_err(|r| (format!("{el}.pose"), r))?,
        None => Pose::identity(),
    };
    let need = |v: Option<f64>, f: &str| {
        v.ok_or_else(|| {
            (
                format!("{el}.{f}"),
                format!("required for type '{}'", g.kind),
            )
        })
    };
    let forbid = |present: bool, f: &str| {
        if present {
            Err((
                format!("{el}.{f}"),
                format!("not a parameter of type '{}'", g.kind),
            ))
        } else {
            Ok(())
        }
    };
    let shape = match g.kind.as_str() {
        "box" => {
            forbid(g.radius.is_some(), "radius")?;
            forbid(g.length.is_some(), "length")?;
            forbid(g.path.is_some(), "path")?;
            let h = g.half_extents.ok_or_else(|| {
                (
                    format!("{el}.half_extents"),
                    "required for type 'box'".to_string(),
                )
            })?;
            Shape::Box {
                half_extents: Vector3::from(h),
            }
        }
        "cylinder" | "capsule" => {
            forbid(g.half_extents.is_some(), "half_extents")?;
            forbid(g.path.is_some(), "path")?;
            let radius = need(g.radius, "radius")?;
            let half_length = need(g.length, "length")? * 0.5;
            if g.kind == "cylinder" {
                Shape::Cylinder {
                    radius,
                    half_length,
                }
            } else {
                Shape::Capsule {
                    radius,
                    half_length,
                }
            }
        }
        "sphere" => {
            forbid(g.half_extents.is_some(), "half_extents")?;
            forbid(g.length.is_some(), "length")?;
            forbid(g.path.is_some(), "path")?;
            Shape::Sphere {
                radius: need(g.radius, "radius")?,
            }
        }
        "mesh" => {
            let p = g
                .path
                .as_ref()
                .ok_or_else(|| (format!("{el}.path"), "required for type 'mesh'".to_string()))?;
            let full: PathBuf = base_dir.join(p);
            let scale = g.scale.unwrap_or([1.0; 3]);
            if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
                return Err((
                    format!("{el}.scale"),
                    "values must be finite and > 0".into(),
                ));
            }
            Shape::Mesh(Arc::new(
                Mesh::load(&full, scale).map_err(|r| (format!("{el}.path"), r))?,
            ))
        }
        other => {
            return Err((
                format!("{el}.type"),
                format!("unknown shape type '{other}' (box, cylinder, sphere, capsule, mesh)"),
            ))
        }
    };
    shape.validate().map_err(|r| {
        let (f, rest) = r
            .split_once(": ")
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .unwrap_or(("".into(), r.clone()));
        (format!("{el}.{f}"), rest)
    })?;
    Ok(Geometry { origin, shape })
}
