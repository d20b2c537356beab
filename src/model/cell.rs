//! Multi-arm work cells: copies of one arm model around a square table, facing its centre, each
//! with a named `start` and `goal` configuration (issue 23's `panda_four`, the fixed-goal
//! setting beside paper 002 §VI's humanoids: each arm is planned alone, then the phase-space
//! planner of 002 §V schedules them so they can move at the same time).
//!
//! The cell is scene JSON over a robot *model name*; the model itself is whatever the robot
//! library holds under that name (for `panda_four`: the MotionBenchMaker's spherized Panda,
//! loaded as an outside robot from the fetched data, `manyhands data mbm`).

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

use crate::geometry::PoseJson;

use super::{BodyJson, GeometryJson, RobotPlacementJson, SceneJson};

/// Parameters of [`arm_cell`].
#[derive(Debug, Clone, PartialEq)]
pub struct ArmCell {
    pub name: String,
    pub description: String,
    /// Model name of every arm (a robot of the library the scene is resolved against).
    pub model: String,
    /// Number of arms (1..=4), on the corners of the table, counter-clockwise from +x +y.
    pub arms: usize,
    /// Edge length of the square table top (m).
    pub table_side: f64,
    /// Height of the table top above the floor (m).
    pub table_height: f64,
    /// Thickness of the table top (m).
    pub table_thickness: f64,
    /// How far each base stands in from its corner along both edges (m).
    pub inset: f64,
    /// Height of each base frame above the table top (m): the riser the arm is bolted to, which
    /// must clear the collision geometry of the arm's root link below its frame.
    pub mount_height: f64,
    /// The `start` configuration of every arm (joint name → value; other joints 0).
    pub start: BTreeMap<String, f64>,
    /// The `goal` configuration of every arm.
    pub goal: BTreeMap<String, f64>,
}

/// Scene JSON of the cell: a table `table`, arms `{model}_{i}` with configurations `start`
/// (the scene's start) and `goal`. Arm `i` stands at the corner at angle 45° + i·90° and faces
/// the table's centre, so the same joint values give a four-fold symmetric cell.
pub fn arm_cell(c: &ArmCell) -> SceneJson {
    let half = 0.5 * c.table_side;
    let top = c.table_height;
    let table = BodyJson {
        name: "table".into(),
        pose: PoseJson {
            position: Some([0.0, 0.0, top - 0.5 * c.table_thickness]),
            rpy: None,
            quat_xyzw: None,
        },
        shapes: vec![GeometryJson {
            kind: "box".into(),
            half_extents: Some([half, half, 0.5 * c.table_thickness]),
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
    let corner = (half - c.inset).max(0.0) * std::f64::consts::SQRT_2;
    let robots = (0..c.arms)
        .map(|i| {
            let angle = FRAC_PI_4 + i as f64 * FRAC_PI_2;
            let yaw = angle + PI;
            let yaw = if yaw > PI { yaw - 2.0 * PI } else { yaw };
            let mut configs = BTreeMap::new();
            configs.insert("start".to_string(), c.start.clone());
            configs.insert("goal".to_string(), c.goal.clone());
            RobotPlacementJson {
                name: format!("{}_{i}", c.model),
                model: c.model.clone(),
                base_pose: PoseJson {
                    position: Some([
                        round_mm(corner * angle.cos()),
                        round_mm(corner * angle.sin()),
                        round_mm(top + c.mount_height),
                    ]),
                    rpy: Some([0.0, 0.0, yaw]),
                    quat_xyzw: None,
                },
                configs,
                start: Some("start".into()),
            }
        })
        .collect();
    SceneJson {
        name: c.name.clone(),
        description: c.description.clone(),
        obstacles: vec![table],
        objects: Vec::new(),
        robots,
    }
}

fn round_mm(x: f64) -> f64 {
    let r = (x * 1e6).round() / 1e6;
    if r == 0.0 {
        0.0
    } else {
        r
    }
}

/// The `panda_four` cell of issue 23 (5c): four Panda arms (joints `panda_joint1…7`) on the
/// corners of a 1.2 m square table 0.75 m high, 0.1 m in from each corner, on 4 cm risers (the
/// spherized Panda's base sphere reaches 3 cm below its frame). Every arm swings from reaching
/// over the table on its left (`start`) to reaching low on its right (`goal`). Each motion is
/// free on its own and the four are free one after the other in the order 0, 1, 2, 3, but the
/// straight-line motions cross: executed together, the arms meet above the table's centre. So
/// neither "all at once" nor a fixed order without waiting is a good schedule; the phase-space
/// planner finds one where they overlap in time.
pub fn panda_four(model: &str) -> SceneJson {
    let joints = |v: [f64; 7]| -> BTreeMap<String, f64> {
        v.iter()
            .enumerate()
            .map(|(k, &x)| (format!("panda_joint{}", k + 1), x))
            .collect()
    };
    arm_cell(&ArmCell {
        name: "panda_four".into(),
        description: format!(
            "Four '{model}' arms on the corners of a 1.2 m square table facing \
             its centre; each swings from `start` (reaching over the table on its left) to \
             `goal` (low on its right). The straight-line motions cross above the centre: plan \
             each arm alone (kind joint_space), then schedule them (kind schedule)."
        ),
        model: model.into(),
        arms: 4,
        table_side: 1.2,
        table_height: 0.75,
        table_thickness: 0.05,
        inset: 0.1,
        mount_height: 0.04,
        start: joints([0.48, 0.42, 0.0, -0.74, 0.0, 2.68, 0.785]),
        goal: joints([-0.48, 0.72, 0.0, -1.18, 0.0, 0.61, 0.785]),
    })
}
