//! Multi-arm benchmark cells and crossing tasks.
//!
//! **Cells.** The three public cells of VAMP-MR (Huang, Gao & Li, "VAMP-MR: Vector-Accelerated
//! Motion Planning and Execution for Multi-Robot-Arms", WoMAPF at AAAI 2026, Table 1 and its
//! environment descriptions), built at run time over the MotionBenchMaker Panda that
//! `manyhands data mbm` installs (59-sphere collision model, end effector frame
//! `panda_grasptarget`), so nothing shipped in `robots/` or `scenes/` depends on fetched data:
//!
//! - [`VampMrCell::PandaTwoRod`]: two Pandas facing each other 0.8 m apart on a segmented
//!   table (top 0.1 m high), each holding a 0.5 m rod (radius 1.5 cm) across its gripper;
//! - [`VampMrCell::PandaFour`]: four Pandas on the corners of a 2 × 2 m segmented table, bases
//!   at (±0.36, ±0.36) yawed towards the centre;
//! - [`VampMrCell::PandaFourBins`]: the same table among five open bins (0.5 m cubes, 2 cm
//!   walls) in a plus shape, bases at (±0.4, ±0.4), each hand holding a 0.3 m rod (radius 1 cm).
//!
//! The published table segments, bin walls, base poses and rod attachments are taken as given,
//! with two changes for the spherized Panda, whose base sphere reaches 3 cm below its frame:
//! every base stands on a 4 cm riser (not modelled as a body: it is under the base link), and
//! in the bins cell the bases stand 1 cm further out in x and y so that the arms' spheres clear
//! the bins' walls at the start configuration. A held rod is part of the arm model (a fixed
//! link on the end-effector frame, its cylinder covered by spheres, see [`RodSpec`]), so the
//! sphere checker handles the cell; the rod may touch the hand and fingers holding it (SRDF
//! `disable_collisions`), nothing else.
//!
//! [`vamp_mr`] gives the resolved [`Scene`], its JSON and the arm models' URDF/SRDF text (to
//! upload with `PUT /v1/robots/NAME`, or write next to the scene as `manyhands scene vamp-mr
//! --out DIR` does).
//!
//! **Crossing tasks.** [`crossing_task`] draws, from a seed, one start and one goal
//! configuration per arm of a cell such that all starts together and all goals together are
//! collision-free (scene, self and between arms) while the arms' straight joint-space motions,
//! executed together on one clock, collide between arms (VAMP-MR's and mr-shortcut's random
//! multi-arm tasks, filtered to the ones where the arms are in each other's way: with the paths
//! fixed as straight lines, simultaneous execution fails).

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use thiserror::Error;

use crate::collision::{AutoChecker, CollisionChecker, CollisionWorld};
use crate::geometry::PoseJson;
use crate::model::{
    BodyJson, GeometryJson, ModelError, RobotLibrary, RobotPlacementJson, Scene, SceneJson,
};
use crate::Robot;

/// The public VAMP-MR cells (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VampMrCell {
    PandaTwoRod,
    PandaFour,
    PandaFourBins,
}

impl VampMrCell {
    /// All three, in the order of VAMP-MR's Table 1.
    pub const ALL: [VampMrCell; 3] = [
        VampMrCell::PandaTwoRod,
        VampMrCell::PandaFour,
        VampMrCell::PandaFourBins,
    ];

    /// The cell's (and its scene's) name: `vamp_mr_panda_two_rod`, `vamp_mr_panda_four`,
    /// `vamp_mr_panda_four_bins`.
    pub fn name(self) -> &'static str {
        match self {
            VampMrCell::PandaTwoRod => "vamp_mr_panda_two_rod",
            VampMrCell::PandaFour => "vamp_mr_panda_four",
            VampMrCell::PandaFourBins => "vamp_mr_panda_four_bins",
        }
    }

    /// The cell of a name: [`Self::name`], or VAMP-MR's own (`panda_two_rod`, `panda_four`,
    /// `panda_four_bins`).
    pub fn from_name(name: &str) -> Option<VampMrCell> {
        let bare = name.strip_prefix("vamp_mr_").unwrap_or(name);
        match bare {
            "panda_two_rod" => Some(VampMrCell::PandaTwoRod),
            "panda_four" => Some(VampMrCell::PandaFour),
            "panda_four_bins" => Some(VampMrCell::PandaFourBins),
            _ => None,
        }
    }

    /// VAMP-MR's published collision-check times on their machine (Table 1, µs; average over
    /// 10 000 random samples): (single state, motion segment).
    pub fn published_check_us(self) -> (f64, f64) {
        match self {
            VampMrCell::PandaTwoRod => (8.60, 36.03),
            VampMrCell::PandaFour => (15.01, 32.61),
            VampMrCell::PandaFourBins => (13.70, 14.23),
        }
    }

    /// The cell's geometry and arm placement.
    pub fn spec(self) -> CellSpec {
        // The published table segments: (centre x, centre y, size x, size y), 0.1 m thick, top
        // at 0.1 m.
        let two_table = [
            (0.0, 0.0, 0.6, 2.0),
            (0.75, 0.0, 0.5, 2.0),
            (-0.75, 0.0, 0.5, 2.0),
            (0.4, 0.55, 0.2, 0.9),
            (0.4, -0.55, 0.2, 0.9),
            (-0.4, 0.55, 0.2, 0.9),
            (-0.4, -0.55, 0.2, 0.9),
        ];
        let four_table = [
            (0.0, 0.0, 2.0, 0.5),
            (0.0, 0.0, 0.5, 2.0),
            (0.77, 0.0, 0.46, 2.0),
            (-0.77, 0.0, 0.46, 2.0),
            (0.0, 0.77, 2.0, 0.46),
            (0.0, -0.77, 2.0, 0.46),
        ];
        let slab = |s: &[(f64, f64, f64, f64)]| -> Vec<BoxSpec> {
            s.iter()
                .map(|&(x, y, lx, ly)| BoxSpec {
                    centre: [x, y, 0.05],
                    size: [lx, ly, 0.1],
                })
                .collect()
        };
        let four_yaws = [2.28, 0.66, -0.66, -2.28];
        let corners = |d: f64| -> Vec<([f64; 2], f64)> {
            [(d, -d), (-d, -d), (-d, d), (d, d)]
                .iter()
                .zip(four_yaws)
                .map(|(&(x, y), yaw)| ([x, y], yaw))
                .collect()
        };
        let riser = 0.04;
        match self {
            VampMrCell::PandaTwoRod => CellSpec {
                name: self.name().into(),
                description: "VAMP-MR's two-Panda rod cell: two MotionBenchMaker Pandas facing \
                    each other 0.8 m apart on a segmented table (top 0.1 m high, bases on 4 cm \
                    risers), each holding a 0.5 m rod (radius 1.5 cm) across its gripper."
                    .into(),
                table_top: 0.1,
                table: slab(&two_table),
                bins: Vec::new(),
                bin_wall: 0.02,
                bases: vec![([0.4, 0.0], PI), ([-0.4, 0.0], 0.0)],
                riser,
                rod: Some(RodSpec {
                    length: 0.5,
                    radius: 0.015,
                    offset: -0.005,
                }),
            },
            VampMrCell::PandaFour => CellSpec {
                name: self.name().into(),
                description: "VAMP-MR's four-Panda cell: four MotionBenchMaker Pandas on the \
                    corners of a 2 x 2 m segmented table (top 0.1 m high, bases on 4 cm risers) \
                    yawed towards its centre."
                    .into(),
                table_top: 0.1,
                table: slab(&four_table),
                bins: Vec::new(),
                bin_wall: 0.02,
                bases: corners(0.36),
                riser,
                rod: None,
            },
            VampMrCell::PandaFourBins => CellSpec {
                name: self.name().into(),
                description: "VAMP-MR's four-Panda bins cell: four MotionBenchMaker Pandas on \
                    the corners of a 2 x 2 m segmented table (top 0.1 m high, bases on 4 cm \
                    risers, 1 cm further out than published) among five open 0.5 m bins in a \
                    plus shape, each hand holding a 0.3 m rod (radius 1 cm)."
                    .into(),
                table_top: 0.1,
                table: slab(&four_table),
                bins: vec![[0.0, 0.0], [0.5, 0.0], [-0.5, 0.0], [0.0, 0.5], [0.0, -0.5]]
                    .into_iter()
                    .map(|[x, y]| BinSpec {
                        centre: [x, y, 0.0],
                        size: [0.5, 0.5, 0.5],
                    })
                    .collect(),
                bin_wall: 0.02,
                bases: corners(0.41),
                riser,
                rod: Some(RodSpec {
                    length: 0.3,
                    radius: 0.01,
                    offset: -0.005,
                }),
            },
        }
    }
}

/// An axis-aligned box obstacle.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxSpec {
    pub centre: [f64; 3],
    /// Full edge lengths (m).
    pub size: [f64; 3],
}

/// An open box (bin): a bottom plate at `centre` and four walls of its height standing on it,
/// the walls centred on the edges of the `size[0]` × `size[1]` footprint (VAMP-MR's hollow box).
#[derive(Debug, Clone, PartialEq)]
pub struct BinSpec {
    pub centre: [f64; 3],
    pub size: [f64; 3],
}

/// A rod held across the gripper: a cylinder along the x axis of the end-effector frame,
/// centred `offset` m along its z axis.
///
/// It is modelled as `n = ⌈length / (2·radius)⌉` spheres on the axis, centres `length / n`
/// apart from `length / 2n` inside either end, each of radius `√(radius² + (length / 2n)²)`:
/// sphere k contains the slab of the cylinder within `length / 2n` of its centre, so the
/// spheres together contain the cylinder (a conservative superset, as VAMP's own sphere
/// attachments).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodSpec {
    pub length: f64,
    pub radius: f64,
    pub offset: f64,
}

impl RodSpec {
    /// The covering spheres: (x along the rod, radius).
    pub fn spheres(&self) -> Vec<(f64, f64)> {
        let n = (self.length / (2.0 * self.radius)).ceil().max(1.0) as usize;
        let half_step = self.length / (2.0 * n as f64);
        let r = (self.radius * self.radius + half_step * half_step).sqrt();
        (0..n)
            .map(|k| (-0.5 * self.length + half_step * (2 * k + 1) as f64, r))
            .collect()
    }
}

/// The geometry and placement of a multi-arm cell (see [`VampMrCell::spec`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CellSpec {
    pub name: String,
    pub description: String,
    /// Height of the table top (m).
    pub table_top: f64,
    pub table: Vec<BoxSpec>,
    pub bins: Vec<BinSpec>,
    /// Wall and bottom thickness of the bins (m).
    pub bin_wall: f64,
    /// Per arm: base position (x, y) and yaw about z; the base stands at `table_top + riser`.
    pub bases: Vec<([f64; 2], f64)>,
    /// Height of the riser under every base (m).
    pub riser: f64,
    /// The rod every hand holds, if any.
    pub rod: Option<RodSpec>,
}

/// An arm model of a cell, as text (upload with `PUT /v1/robots/NAME`).
#[derive(Debug, Clone, PartialEq)]
pub struct CellModel {
    pub name: String,
    pub urdf: String,
    pub srdf: String,
}

/// A built cell: the resolved scene, its JSON and the models it uses.
#[derive(Debug, Clone)]
pub struct MultiArmCell {
    pub scene: Scene,
    pub json: SceneJson,
    pub models: Vec<CellModel>,
}

/// Why a cell or a task could not be built.
#[derive(Debug, Error)]
pub enum CellError {
    #[error("unknown cell '{0}' (panda_two_rod, panda_four, panda_four_bins)")]
    UnknownCell(String),
    #[error("{file}: cannot read: {reason}")]
    Io { file: String, reason: String },
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error("the model has no link '{0}' to hold the rod")]
    NoLink(String),
    #[error("no start configuration of cell '{cell}' is free (the first collides: {a} with {b})")]
    StartCollides { cell: String, a: String, b: String },
    #[error("no crossing task found in {draws} draws (seed {seed})")]
    NoTask { seed: u64, draws: usize },
}

/// The link a held rod is fixed to: the MotionBenchMaker Panda's grasp frame (between the
/// fingertips, z out of the palm, fingers closing along y).
pub const ROD_PARENT_LINK: &str = "panda_grasptarget";

/// The rod's link in a rod-holding model.
pub const ROD_LINK: &str = "held_rod";

/// The Panda's SRDF `ready` configuration (joints `panda_joint1…7`).
pub const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

/// The arms' `start` in a cell: the first of these configurations (every arm the same) that
/// is collision-free there — `ready`; `ready` turned a quarter turn about the base (the arms
/// reach sideways); nearly upright with the hand pointing forward (SRDF `extended` with the
/// elbow bent 0.1 rad).
pub const START_CANDIDATES: [[f64; 7]; 3] = [
    READY,
    [FRAC_PI_2, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
    [0.0, 0.0, 0.0, -0.1, 0.0, 1.571, 0.785],
];

/// The URDF and SRDF text of `panda` (the MotionBenchMaker files) holding `rod` (see
/// [`RodSpec`]), as model `name`.
pub fn rod_model(
    name: &str,
    urdf: &str,
    srdf: &str,
    rod: &RodSpec,
) -> Result<CellModel, CellError> {
    if !urdf.contains(&format!("name=\"{ROD_PARENT_LINK}\"")) {
        return Err(CellError::NoLink(ROD_PARENT_LINK.into()));
    }
    let mut link = format!("\t<link name=\"{ROD_LINK}\">\n");
    for (x, r) in rod.spheres() {
        let _ = write!(
            link,
            "\t\t<collision>\n\t\t\t<geometry>\n\t\t\t\t<sphere radius=\"{r:.6}\"></sphere>\n\
             \t\t\t</geometry>\n\t\t\t<origin xyz=\"{x:.6} 0.0 0.0\" rpy=\"0 0 0\"></origin>\n\
             \t\t</collision>\n"
        );
    }
    link.push_str("\t</link>\n");
    let _ = write!(
        link,
        "\t<joint name=\"{ROD_LINK}_joint\" type=\"fixed\">\n\t\t<parent link=\"{ROD_PARENT_LINK}\"></parent>\n\
         \t\t<child link=\"{ROD_LINK}\"></child>\n\t\t<origin xyz=\"0 0 {:.6}\" rpy=\"0 0 0\"></origin>\n\
         \t</joint>\n",
        rod.offset
    );
    let urdf = insert_before_last(urdf, "</robot>", &link)
        .ok_or_else(|| CellError::NoLink("</robot>".into()))?;
    let mut extra = String::new();
    for l in [
        "panda_hand",
        "panda_leftfinger",
        "panda_rightfinger",
        ROD_PARENT_LINK,
    ] {
        let _ = writeln!(
            extra,
            "  <disable_collisions link1=\"{ROD_LINK}\" link2=\"{l}\" reason=\"Adjacent\"/>"
        );
    }
    let srdf = insert_before_last(srdf, "</robot>", &extra)
        .ok_or_else(|| CellError::NoLink("</robot> in the SRDF".into()))?;
    Ok(CellModel {
        name: name.into(),
        urdf,
        srdf,
    })
}

fn insert_before_last(text: &str, tag: &str, what: &str) -> Option<String> {
    let at = text.rfind(tag)?;
    let mut s = String::with_capacity(text.len() + what.len());
    s.push_str(&text[..at]);
    s.push_str(what);
    s.push_str(&text[at..]);
    Some(s)
}

fn box_body(name: String, centre: [f64; 3], size: [f64; 3]) -> BodyJson {
    BodyJson {
        name,
        pose: PoseJson {
            position: Some(centre),
            rpy: None,
            quat_xyzw: None,
        },
        shapes: vec![GeometryJson {
            kind: "box".into(),
            half_extents: Some([0.5 * size[0], 0.5 * size[1], 0.5 * size[2]]),
            radius: None,
            length: None,
            path: None,
            scale: None,
            pose: None,
        }],
        mass: None,
        grasps: Vec::new(),
        goal: None,
    }
}

/// Scene JSON of `spec` over arm model `model` (joints `panda_joint1…7`): obstacles `table_K`,
/// `bin_K_{bottom,front,back,left,right}`, arms `arm_K` with configuration `start` (the scene's
/// start) = `start` for every arm.
pub fn cell_json(spec: &CellSpec, model: &str, start: &[f64; 7]) -> SceneJson {
    let mut obstacles: Vec<BodyJson> = spec
        .table
        .iter()
        .enumerate()
        .map(|(k, b)| box_body(format!("table_{k}"), b.centre, b.size))
        .collect();
    let t = spec.bin_wall;
    for (k, b) in spec.bins.iter().enumerate() {
        let [cx, cy, cz] = b.centre;
        let [lx, ly, h] = b.size;
        let side_z = cz + 0.5 * t + 0.5 * h;
        for (part, c, s) in [
            ("bottom", [cx, cy, cz], [lx, ly, t]),
            ("front", [cx, cy + 0.5 * ly, side_z], [lx, t, h]),
            ("back", [cx, cy - 0.5 * ly, side_z], [lx, t, h]),
            ("left", [cx - 0.5 * lx, cy, side_z], [t, ly, h]),
            ("right", [cx + 0.5 * lx, cy, side_z], [t, ly, h]),
        ] {
            obstacles.push(box_body(format!("bin_{k}_{part}"), c, s));
        }
    }
    let start: BTreeMap<String, f64> = start
        .iter()
        .enumerate()
        .map(|(k, &v)| (format!("panda_joint{}", k + 1), v))
        .collect();
    let robots = spec
        .bases
        .iter()
        .enumerate()
        .map(|(k, &([x, y], yaw))| {
            let mut configs = BTreeMap::new();
            configs.insert("start".to_string(), start.clone());
            RobotPlacementJson {
                name: format!("arm_{k}"),
                model: model.into(),
                base_pose: PoseJson {
                    position: Some([x, y, spec.table_top + spec.riser]),
                    rpy: Some([0.0, 0.0, yaw]),
                    quat_xyzw: None,
                },
                configs,
                start: Some("start".into()),
            }
        })
        .collect();
    SceneJson {
        name: spec.name.clone(),
        description: spec.description.clone(),
        obstacles,
        objects: Vec::new(),
        robots,
    }
}

/// Builds `cell` over the MotionBenchMaker Panda of data folder `mbm_dir`
/// ([`crate::benchmark::mbm_data::locate`]): the arm model is `panda`, or `panda_rod` holding the cell's
/// rod. Every arm starts at the first of [`START_CANDIDATES`] that is collision-free in the
/// cell (scene, self and between the arms).
pub fn vamp_mr(cell: VampMrCell, mbm_dir: &Path) -> Result<MultiArmCell, CellError> {
    let f = crate::benchmark::mbm_data::robot_files(mbm_dir, "panda");
    let read = |p: &Path| {
        std::fs::read_to_string(p).map_err(|e| CellError::Io {
            file: p.display().to_string(),
            reason: e.to_string(),
        })
    };
    let (urdf, srdf) = (read(&f.urdf)?, read(&f.srdf)?);
    let spec = cell.spec();
    let model = match &spec.rod {
        Some(rod) => rod_model("panda_rod", &urdf, &srdf, rod)?,
        None => CellModel {
            name: "panda".into(),
            urdf,
            srdf,
        },
    };
    let base = f.urdf.parent().unwrap_or(Path::new("."));
    let robot = Robot::from_strings(&model.urdf, Some(&model.srdf), base)?;
    let mut lib = RobotLibrary::new();
    lib.insert(model.name.clone(), Arc::new(robot));
    let mut first_contact = None;
    for start in &START_CANDIDATES {
        let json = cell_json(&spec, &model.name, start);
        let scene = Scene::from_json(json.clone(), &spec.name, Path::new("."), &lib)?;
        let world = CollisionWorld::from_scene(&scene);
        let mut checker = AutoChecker::new(&world, 0.0);
        match checker.first_contact(&CollisionWorld::start_config(&scene)) {
            None => {
                return Ok(MultiArmCell {
                    scene,
                    json,
                    models: vec![model],
                })
            }
            Some(c) => {
                first_contact.get_or_insert(c);
            }
        }
    }
    let (a, b) = first_contact.map(|c| (c.a, c.b)).unwrap_or_default();
    Err(CellError::StartCollides {
        cell: spec.name,
        a,
        b,
    })
}

/// [`vamp_mr`] by name ([`VampMrCell::from_name`]).
pub fn vamp_mr_by_name(name: &str, mbm_dir: &Path) -> Result<MultiArmCell, CellError> {
    let cell = VampMrCell::from_name(name).ok_or_else(|| CellError::UnknownCell(name.into()))?;
    vamp_mr(cell, mbm_dir)
}

/// Settings of [`crossing_task`].
#[derive(Debug, Clone, PartialEq)]
pub struct CrossingSettings {
    /// Most configurations drawn (over all arms and attempts) before giving up.
    pub max_draws: usize,
    /// Largest joint step (rad) between the instants at which the straight motions are
    /// checked against each other when looking for their conflict.
    pub resolution: f64,
    /// Least number of arm pairs whose straight motions must collide.
    pub min_conflicts: usize,
    /// Every arm's straight motion must also be free alone (scene and self), so that the only
    /// obstacle of the task is the other arms.
    pub free_alone: bool,
}

impl Default for CrossingSettings {
    fn default() -> Self {
        CrossingSettings {
            max_draws: 200_000,
            resolution: 0.02,
            min_conflicts: 1,
            free_alone: false,
        }
    }
}

/// A task of [`crossing_task`]: per arm (scene order) a start and a goal configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossingTask {
    pub seed: u64,
    pub starts: Vec<Vec<f64>>,
    pub goals: Vec<Vec<f64>>,
    /// The arm pairs (i < j) whose straight motions, run together, collide.
    pub conflicts: Vec<(usize, usize)>,
    /// Configurations drawn to find it.
    pub draws: usize,
}

impl CrossingTask {
    /// The world configuration with every arm at its start.
    pub fn start_config(&self) -> Vec<f64> {
        self.starts.concat()
    }

    /// The world configuration with every arm at its goal.
    pub fn goal_config(&self) -> Vec<f64> {
        self.goals.concat()
    }
}

/// Checkers of a scene's arms: each alone (scene and self) and each pair (between them only).
struct TaskCheckers {
    alone: Vec<AutoChecker>,
    /// (i, j, checker of the pair between themselves), i < j.
    pairs: Vec<(usize, usize, AutoChecker)>,
}

impl TaskCheckers {
    fn new(world: &CollisionWorld) -> TaskCheckers {
        let n = world.robots.len();
        let alone = (0..n)
            .filter_map(|r| world.subset(&[r]))
            .map(|w| AutoChecker::new(&w, 0.0))
            .collect();
        let mut pairs = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                if let Some(w) = world.subset(&[i, j]) {
                    pairs.push((i, j, AutoChecker::new(&w.between_robots(), 0.0)));
                }
            }
        }
        TaskCheckers { alone, pairs }
    }

    fn pair_free(c: &mut AutoChecker, a: &[f64], b: &[f64], buf: &mut Vec<f64>) -> bool {
        buf.clear();
        buf.extend_from_slice(a);
        buf.extend_from_slice(b);
        c.is_free(buf)
    }
}

/// Draws configurations for every arm, one arm after the other, each free alone and free
/// against the arms drawn before it.
fn draw_all(
    world: &CollisionWorld,
    ck: &mut TaskCheckers,
    rng: &mut ChaCha8Rng,
    draws: &mut usize,
    max: usize,
) -> Option<Vec<Vec<f64>>> {
    let n = world.robots.len();
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut buf = Vec::new();
    for r in 0..n {
        let robot = &world.robots[r].robot;
        let vars: Vec<usize> = (0..robot.dof()).collect();
        let mut q = robot.zero_config();
        loop {
            if *draws >= max {
                return None;
            }
            *draws += 1;
            robot.sample_vars(&vars, &mut q, rng);
            if !ck.alone[r].is_free(&q) {
                continue;
            }
            let against_earlier = ck
                .pairs
                .iter_mut()
                .filter(|(_, j, _)| *j == r)
                .all(|(i, _, c)| TaskCheckers::pair_free(c, &out[*i], &q, &mut buf));
            if against_earlier {
                break;
            }
        }
        out.push(q);
    }
    Some(out)
}

fn lerp_into(a: &[f64], b: &[f64], t: f64, out: &mut Vec<f64>) {
    out.clear();
    out.extend(a.iter().zip(b).map(|(x, y)| x + (y - x) * t));
}

/// A seeded crossing task in `scene` (see the module documentation): starts and goals drawn
/// uniformly within the joint limits (rejection sampling, arm after arm), kept when at least
/// `min_conflicts` arm pairs collide somewhere along the straight motions run together (both
/// arms at the same fraction of their motions, checked every `resolution` rad of the larger
/// joint step of the two). Same scene, seed and settings → same task.
pub fn crossing_task(
    scene: &Scene,
    seed: u64,
    s: &CrossingSettings,
) -> Result<CrossingTask, CellError> {
    let world = CollisionWorld::from_scene(scene);
    let mut ck = TaskCheckers::new(&world);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draws = 0;
    let resolution = if s.resolution.is_finite() && s.resolution > 0.0 {
        s.resolution
    } else {
        CrossingSettings::default().resolution
    };
    let (mut qa, mut qb, mut buf) = (Vec::new(), Vec::new(), Vec::new());
    loop {
        let none = || CellError::NoTask {
            seed,
            draws: s.max_draws,
        };
        let starts =
            draw_all(&world, &mut ck, &mut rng, &mut draws, s.max_draws).ok_or_else(none)?;
        let goals =
            draw_all(&world, &mut ck, &mut rng, &mut draws, s.max_draws).ok_or_else(none)?;
        if s.free_alone {
            let all_free = (0..starts.len()).all(|r| {
                let step = max_step(&starts[r], &goals[r]);
                let n = (step / resolution).ceil().max(1.0) as usize;
                (1..n).all(|k| {
                    lerp_into(&starts[r], &goals[r], k as f64 / n as f64, &mut qa);
                    ck.alone[r].is_free(&qa)
                })
            });
            if !all_free {
                continue;
            }
        }
        let mut conflicts = Vec::new();
        for (i, j, c) in ck.pairs.iter_mut() {
            let (i, j) = (*i, *j);
            let step = max_step(&starts[i], &goals[i]).max(max_step(&starts[j], &goals[j]));
            let n = (step / resolution).ceil().max(1.0) as usize;
            let hit = (1..n).any(|k| {
                let t = k as f64 / n as f64;
                lerp_into(&starts[i], &goals[i], t, &mut qa);
                lerp_into(&starts[j], &goals[j], t, &mut qb);
                !TaskCheckers::pair_free(c, &qa, &qb, &mut buf)
            });
            if hit {
                conflicts.push((i, j));
            }
        }
        if conflicts.len() >= s.min_conflicts.max(1) {
            return Ok(CrossingTask {
                seed,
                starts,
                goals,
                conflicts,
                draws,
            });
        }
    }
}

fn max_step(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (y - x).abs())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rod's spheres contain the cylinder: every point of its surface grid is inside one.
    #[test]
    fn rod_spheres_cover_the_cylinder() {
        for rod in [
            RodSpec {
                length: 0.5,
                radius: 0.015,
                offset: 0.0,
            },
            RodSpec {
                length: 0.3,
                radius: 0.01,
                offset: 0.0,
            },
        ] {
            let spheres = rod.spheres();
            assert!(spheres.len() >= 10, "{}", spheres.len());
            for i in 0..=200 {
                let x = -0.5 * rod.length + rod.length * i as f64 / 200.0;
                for k in 0..16 {
                    let a = k as f64 * PI / 8.0;
                    let (y, z) = (rod.radius * a.cos(), rod.radius * a.sin());
                    let inside = spheres
                        .iter()
                        .any(|&(c, r)| ((x - c).powi(2) + y * y + z * z).sqrt() <= r + 1e-12);
                    assert!(inside, "({x}, {y}, {z}) outside");
                }
            }
            // And not much more: the spheres stay within the rod's ends plus a radius.
            let (first, last) = (spheres[0], spheres[spheres.len() - 1]);
            assert!(first.0 - first.1 >= -0.5 * rod.length - rod.radius);
            assert!(last.0 + last.1 <= 0.5 * rod.length + rod.radius);
        }
    }

    #[test]
    fn cell_names_round_trip() {
        for c in VampMrCell::ALL {
            assert_eq!(VampMrCell::from_name(c.name()), Some(c));
            let bare = c.name().strip_prefix("vamp_mr_").unwrap_or("");
            assert_eq!(VampMrCell::from_name(bare), Some(c));
        }
        assert_eq!(VampMrCell::from_name("panda_six"), None);
    }

    /// The bins cell: five bins of five plates each, four arms on risers above the table top.
    #[test]
    fn bins_cell_json_has_the_published_layout() {
        let spec = VampMrCell::PandaFourBins.spec();
        let j = cell_json(&spec, "panda_rod", &READY);
        assert_eq!(j.obstacles.len(), 6 + 5 * 5);
        assert_eq!(j.robots.len(), 4);
        for r in &j.robots {
            let p = r.base_pose.position.unwrap_or_default();
            assert!((p[2] - 0.14).abs() < 1e-12, "{p:?}");
            assert!((p[0].abs() - 0.41).abs() < 1e-12 && (p[1].abs() - 0.41).abs() < 1e-12);
        }
    }
}
