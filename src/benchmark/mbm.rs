//! Loader of the MotionBenchMaker problem sets (Chamzas et al., "MotionBenchMaker: A Tool to
//! Generate and Benchmark Motion Planning Datasets", RA-L 2022) in the JSON form shipped with
//! VAMP (where to find or fetch it: [`crate::benchmark::mbm_data`]): a file lists the robot's joint names in
//! configuration order and, per problem set, problems with obstacles (spheres, boxes,
//! cylinders; positions in the robot's base frame, orientations as quaternions xyzw), a start
//! and a set of goal configurations.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::de::{MapAccess, Visitor};
use serde::{Deserialize, Deserializer};
use thiserror::Error;

use crate::collision::{CollisionWorld, StaticBody, StaticKind};
use crate::geometry::{Geometry, Pose, Shape};
use crate::planning::{JointSpace, PlanError};
use crate::Robot;

/// A problem file that cannot be used.
#[derive(Debug, Error)]
pub enum MbmError {
    #[error("{file}: cannot read: {reason}")]
    Io { file: String, reason: String },
    #[error("{file}: malformed: {reason}")]
    Syntax { file: String, reason: String },
    /// A joint of the file's `joints` list is not a variable of the robot.
    #[error("joint '{joint}' of the problem file is not a variable of robot '{robot}'")]
    UnknownJoint { joint: String, robot: String },
    /// A problem's data does not fit (configuration length, obstacle dimensions).
    #[error("problem {set}[{index}]: {reason}")]
    Problem {
        set: String,
        index: usize,
        reason: String,
    },
    #[error(transparent)]
    Plan(#[from] PlanError),
}

#[derive(Debug, Clone, Deserialize)]
struct SphereJson {
    #[serde(default)]
    name: String,
    radius: f64,
    position: [f64; 3],
}

#[derive(Debug, Clone, Deserialize)]
struct CylinderJson {
    #[serde(default)]
    name: String,
    radius: f64,
    length: f64,
    position: [f64; 3],
    orientation_quat_xyzw: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
struct BoxJson {
    #[serde(default)]
    name: String,
    half_extents: [f64; 3],
    position: [f64; 3],
    orientation_quat_xyzw: [f64; 4],
}

#[derive(Debug, Clone, Deserialize)]
struct ProblemJson {
    #[serde(default)]
    sphere: Vec<SphereJson>,
    #[serde(default)]
    cylinder: Vec<CylinderJson>,
    #[serde(default, rename = "box")]
    boxes: Vec<BoxJson>,
    start: Vec<f64>,
    goals: Vec<Vec<f64>>,
    valid: bool,
    #[serde(default)]
    index: Option<usize>,
}

/// The problem sets in file order (serde_json's map would sort them).
#[derive(Debug, Default)]
struct OrderedSets(Vec<(String, Vec<ProblemJson>)>);

impl<'de> Deserialize<'de> for OrderedSets {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = OrderedSets;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a map of problem sets")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> Result<OrderedSets, A::Error> {
                let mut out = Vec::new();
                while let Some((k, v)) = m.next_entry::<String, Vec<ProblemJson>>()? {
                    out.push((k, v));
                }
                Ok(OrderedSets(out))
            }
        }
        d.deserialize_map(V)
    }
}

#[derive(Debug, Deserialize)]
struct FileJson {
    robot: String,
    joints: Vec<String>,
    problems: OrderedSets,
    /// Written by [`crate::benchmark::mbm_gen`] (not MotionBenchMaker's own problems).
    #[serde(default)]
    generator: Option<serde_json::Value>,
}

/// One obstacle shape of a problem, in the robot's base frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MbmObstacle {
    pub name: String,
    pub pose: Pose,
    pub shape: Shape,
}

/// One problem: obstacles, a start and the goal set (values in the file's joint order).
#[derive(Debug, Clone, PartialEq)]
pub struct MbmProblem {
    pub set: String,
    /// Index in the set as given by the file (1-based there), else the position in the set.
    pub index: usize,
    /// Whether the file marks the problem as valid (only valid ones are planned).
    pub valid: bool,
    pub start: Vec<f64>,
    pub goals: Vec<Vec<f64>>,
    pub obstacles: Vec<MbmObstacle>,
}

/// A problem set of the file.
#[derive(Debug, Clone, PartialEq)]
pub struct MbmSet {
    pub name: String,
    pub problems: Vec<MbmProblem>,
}

/// A whole problem file.
#[derive(Debug, Clone, PartialEq)]
pub struct MbmFile {
    pub robot: String,
    /// Joint names in configuration order.
    pub joints: Vec<String>,
    pub sets: Vec<MbmSet>,
    /// True for problems made by [`crate::benchmark::mbm_gen`] (MotionBenchMaker-like, not the
    /// benchmark's own: no published reference figures apply).
    pub generated: bool,
}

fn quat_pose(p: [f64; 3], xyzw: [f64; 4]) -> Result<Pose, String> {
    let q = Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
    let n = q.norm();
    if !(n.is_finite() && n > 1e-9) || p.iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "pose {p:?} {xyzw:?} is not finite / not a rotation"
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

impl MbmFile {
    /// Reads and validates a `problems.json`.
    pub fn load(path: &Path) -> Result<MbmFile, MbmError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| MbmError::Io {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        MbmFile::parse(&text, &file)
    }

    /// Parses the text of a problem file; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<MbmFile, MbmError> {
        let raw: FileJson = serde_json::from_str(text).map_err(|e| MbmError::Syntax {
            file: file.to_string(),
            reason: e.to_string(),
        })?;
        let n = raw.joints.len();
        let mut sets = Vec::with_capacity(raw.problems.0.len());
        for (set, problems) in raw.problems.0 {
            let mut out = Vec::with_capacity(problems.len());
            for (pos, p) in problems.into_iter().enumerate() {
                let index = p.index.unwrap_or(pos);
                let bad = |reason: String| MbmError::Problem {
                    set: set.clone(),
                    index,
                    reason,
                };
                let config_ok = |q: &[f64]| q.len() == n && q.iter().all(|v| v.is_finite());
                // Invalid problems may carry incomplete data; they are kept but never planned.
                if p.valid {
                    if !config_ok(&p.start) {
                        return Err(bad(format!(
                            "start needs {n} finite values, has {}",
                            p.start.len()
                        )));
                    }
                    if p.goals.is_empty() {
                        return Err(bad("no goal".into()));
                    }
                    if let Some(k) = p.goals.iter().position(|g| !config_ok(g)) {
                        return Err(bad(format!("goal {k} needs {n} finite values")));
                    }
                }
                let mut obstacles = Vec::new();
                for s in &p.sphere {
                    obstacles.push(MbmObstacle {
                        name: s.name.clone(),
                        pose: quat_pose(s.position, [0.0, 0.0, 0.0, 1.0]).map_err(&bad)?,
                        shape: Shape::Sphere { radius: s.radius },
                    });
                }
                for c in &p.cylinder {
                    obstacles.push(MbmObstacle {
                        name: c.name.clone(),
                        pose: quat_pose(c.position, c.orientation_quat_xyzw).map_err(&bad)?,
                        shape: Shape::Cylinder {
                            radius: c.radius,
                            half_length: 0.5 * c.length,
                        },
                    });
                }
                for b in &p.boxes {
                    obstacles.push(MbmObstacle {
                        name: b.name.clone(),
                        pose: quat_pose(b.position, b.orientation_quat_xyzw).map_err(&bad)?,
                        shape: Shape::Box {
                            half_extents: Vector3::from(b.half_extents),
                        },
                    });
                }
                for o in &obstacles {
                    o.shape
                        .validate()
                        .map_err(|e| bad(format!("obstacle '{}': {e}", o.name)))?;
                }
                out.push(MbmProblem {
                    set: set.clone(),
                    index,
                    valid: p.valid,
                    start: p.start,
                    goals: p.goals,
                    obstacles,
                });
            }
            sets.push(MbmSet {
                name: set,
                problems: out,
            });
        }
        Ok(MbmFile {
            robot: raw.robot,
            joints: raw.joints,
            sets,
            generated: raw.generator.is_some(),
        })
    }

    /// The set called `name`.
    pub fn set(&self, name: &str) -> Option<&MbmSet> {
        self.sets.iter().find(|s| s.name == name)
    }

    /// The robot variable of every joint of the file, in the file's order.
    pub fn joint_vars(&self, robot: &Robot) -> Result<Vec<usize>, MbmError> {
        self.joints
            .iter()
            .map(|j| {
                robot.var(j).ok_or_else(|| MbmError::UnknownJoint {
                    joint: j.clone(),
                    robot: robot.name.clone(),
                })
            })
            .collect()
    }
}

impl MbmProblem {
    /// The collision world: `robot` at the identity base, every obstacle a static body. Pairs of
    /// links joined only by fixed joints are not checked (see [`CollisionWorld::is_allowed`]).
    pub fn world(&self, robot: Arc<Robot>) -> CollisionWorld {
        let mut w = CollisionWorld::single(robot, Pose::identity());
        w.statics = self
            .obstacles
            .iter()
            .map(|o| StaticBody {
                name: o.name.clone(),
                kind: StaticKind::Obstacle,
                pose: o.pose,
                shapes: vec![Geometry {
                    origin: Pose::identity(),
                    shape: o.shape.clone(),
                }],
            })
            .collect();
        w
    }

    /// The planning space of the problem: the file's joints (`vars` from
    /// [`MbmFile::joint_vars`]) in file order; every other robot variable held at its zero
    /// configuration (clamped into the limits).
    pub fn space(&self, world: &CollisionWorld, vars: &[usize]) -> Result<JointSpace, MbmError> {
        let base = world
            .robots
            .first()
            .map(|p| p.robot.zero_config())
            .unwrap_or_default();
        Ok(JointSpace::new(world, vars, base)?)
    }
}
