//! The robots and scenes the server knows: built-in ones loaded at start (read-only) and
//! uploaded ones, validated on upload and persisted under `DATA_DIR/robots` and
//! `DATA_DIR/scenes`.

use crate::reachability::GridCache;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, RwLock};

use crate::collision::CollisionWorld;
use crate::kinematics::{Chain, SrsArm, SrsError};
use crate::model::{load_robot_dir, load_scene_dir_lenient, ModelError, RobotLibrary, SceneJson};
use crate::{Robot, Scene};

use super::api::Source;
use super::error::{ApiError, ApiResult};

pub struct RobotEntry {
    pub robot: Arc<Robot>,
    pub source: Source,
    /// Chains and analytic arm solvers of the robot's chain groups, built on first use (at most
    /// one per SRDF group).
    arms: Mutex<BTreeMap<String, Arc<ArmSolver>>>,
}

/// A chain group and its analytic S-R-S solver (or why it has none).
pub struct ArmSolver {
    pub chain: Chain,
    pub srs: Result<SrsArm, SrsError>,
}

impl RobotEntry {
    pub fn new(robot: Arc<Robot>, source: Source) -> RobotEntry {
        RobotEntry {
            robot,
            source,
            arms: Mutex::new(BTreeMap::new()),
        }
    }

    /// The chain and analytic solver of chain group `group`; `None` when `group` is not a
    /// chain group of the robot.
    pub fn arm(&self, group: &str) -> Option<Arc<ArmSolver>> {
        let mut arms = self.arms.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(a) = arms.get(group) {
            return Some(a.clone());
        }
        let chain = Chain::from_group(&self.robot, group)?;
        let srs = SrsArm::new(&self.robot, &chain);
        let a = Arc::new(ArmSolver { chain, srs });
        arms.insert(group.to_string(), a.clone());
        Some(a)
    }
}

pub struct SceneEntry {
    pub scene: Arc<Scene>,
    pub source: Source,
    world: OnceLock<Arc<CollisionWorld>>,
}

impl SceneEntry {
    fn new(scene: Scene, source: Source) -> SceneEntry {
        SceneEntry {
            scene: Arc::new(scene),
            source,
            world: OnceLock::new(),
        }
    }

    /// The scene's collision world, built on first use.
    pub fn world(&self) -> Arc<CollisionWorld> {
        self.world
            .get_or_init(|| Arc::new(CollisionWorld::from_scene(&self.scene)))
            .clone()
    }
}

/// Robots and scenes by name.
pub struct Catalog {
    robots: RwLock<BTreeMap<String, Arc<RobotEntry>>>,
    scenes: RwLock<BTreeMap<String, Arc<SceneEntry>>>,
    robots_dir: PathBuf,
    scenes_dir: PathBuf,
    /// Serialises uploads and deletions (validation + files + maps).
    write: std::sync::Mutex<()>,
    grids: Arc<GridCache>,
    /// Single-grasp lists (003 §IV-A) under `<data-dir>/grasps`.
    grasp_lists: Arc<crate::grasp::GraspListCache>,
    grasp_dir: PathBuf,
    /// The built-in scenes' `meshes/` folder (objects of `kind: grasp_list` by name).
    meshes_dir: PathBuf,
    /// Uploaded meshes, `<data-dir>/scenes/meshes` (an uploaded scene's `meshes/NAME`).
    upload_meshes_dir: PathBuf,
    /// The shared store behind the caches (grids, grasp lists, roadmaps), with a shared store.
    tier: std::sync::OnceLock<Arc<dyn crate::cache_tier::CacheTier>>,
}

/// A name usable as a file stem: 1..=64 of `[A-Za-z0-9_.-]`, not starting with a dot.
pub fn check_name(name: &str, what: &str) -> ApiResult<()> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'));
    if ok {
        Ok(())
    } else {
        Err(ApiError::invalid(
            "name",
            format!("{what} name '{name}' must be 1-64 characters of A-Z a-z 0-9 _ - . (not starting with '.')"),
        ))
    }
}

/// An uploaded file may only name meshes by relative paths without `..` (no reading of
/// arbitrary server files).
fn check_mesh_path(path: &str) -> Result<(), String> {
    let p = path.strip_prefix("file://").unwrap_or(path);
    if p.starts_with("package://") {
        return Err(format!("'{path}': package:// URIs are not resolved; upload meshes relative to the data directory"));
    }
    let pp = Path::new(p);
    if pp.is_absolute()
        || pp
            .components()
            .any(|c| matches!(c, std::path::Component::ParentDir))
    {
        return Err(format!(
            "'{path}': mesh paths must be relative and stay inside the data directory"
        ));
    }
    Ok(())
}

fn lock_err<T>(p: std::sync::PoisonError<T>) -> T {
    p.into_inner()
}

fn write_atomic(path: &Path, text: &str) -> ApiResult<()> {
    let tmp = path.with_extension("tmp-upload");
    std::fs::write(&tmp, text)
        .and_then(|_| std::fs::rename(&tmp, path))
        .map_err(|e| ApiError::internal(format!("writing {}: {e}", path.display())))
}

fn remove_file(path: &Path) -> ApiResult<()> {
    match std::fs::remove_file(path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(ApiError::internal(format!(
            "removing {}: {e}",
            path.display()
        ))),
    }
}

/// Most `<joint>` elements of an uploaded URDF.
pub const MAX_UPLOAD_JOINTS: usize = 512;
/// Most `<link>` elements of an uploaded URDF.
pub const MAX_UPLOAD_LINKS: usize = 512;

/// Largest joint-limits text of an upload (a few hundred bytes a joint).
const MAX_JOINT_LIMITS_BYTES: usize = 1 << 20;

/// Bounds an upload's size in joints and links before the model is built (422 naming `urdf`
/// and the limit). Malformed XML is left to the URDF parser, which names the error.
fn check_urdf_size(urdf: &str) -> ApiResult<()> {
    let Ok(doc) = roxmltree::Document::parse(urdf) else {
        return Ok(());
    };
    let count = |tag: &str| {
        doc.root_element()
            .children()
            .filter(|n| n.has_tag_name(tag))
            .count()
    };
    for (tag, max) in [("joint", MAX_UPLOAD_JOINTS), ("link", MAX_UPLOAD_LINKS)] {
        let n = count(tag);
        if n > max {
            return Err(ApiError::invalid(
                "urdf",
                format!("{n} <{tag}> elements; an uploaded robot may have at most {max}"),
            ));
        }
    }
    Ok(())
}

impl Catalog {
    /// Loads built-in robots and scenes from `robots_dir` / `scenes_dir` (a robot that does not
    /// load is fatal; a scene file that does not load is left out and logged, every one) and the
    /// uploaded ones under `data_dir` (a broken upload is skipped with a warning).
    pub fn load(
        robots_dir: &Path,
        scenes_dir: &Path,
        data_dir: &Path,
    ) -> Result<Catalog, ModelError> {
        let up_robots = data_dir.join("robots");
        let up_scenes = data_dir.join("scenes");
        let up_meshes = up_scenes.join("meshes");
        for d in [&up_robots, &up_scenes, &up_meshes] {
            std::fs::create_dir_all(d).map_err(|e| ModelError::Io {
                file: d.display().to_string(),
                reason: e.to_string(),
            })?;
        }
        let mut robots = BTreeMap::new();
        if robots_dir.is_dir() {
            for (name, robot) in load_robot_dir(robots_dir)? {
                robots.insert(name, Arc::new(RobotEntry::new(robot, Source::Builtin)));
            }
        }
        if let Ok(rd) = std::fs::read_dir(&up_robots) {
            let mut files: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
            files.sort();
            for p in files
                .iter()
                .filter(|p| p.extension().and_then(|e| e.to_str()) == Some("urdf"))
            {
                let Some(name) = p.file_stem().and_then(|s| s.to_str()).map(str::to_string) else {
                    continue;
                };
                if robots.contains_key(&name) {
                    tracing::warn!(robot = %name, "uploaded robot shadows a built-in one; skipped");
                    continue;
                }
                let srdf = p.with_extension("srdf");
                match Robot::from_files(p, srdf.is_file().then_some(srdf.as_path())) {
                    Ok(mut r) => {
                        // Named as uploaded, whatever the URDF's <robot name>.
                        r.name = name.clone();
                        robots.insert(
                            name,
                            Arc::new(RobotEntry::new(Arc::new(r), Source::Uploaded)),
                        );
                    }
                    Err(e) => {
                        tracing::warn!(file = %p.display(), error = %e, "skipping uploaded robot")
                    }
                }
            }
        }
        let lib: RobotLibrary = robots
            .iter()
            .map(|(k, v)| (k.clone(), v.robot.clone()))
            .collect();
        let mut scenes = BTreeMap::new();
        if scenes_dir.is_dir() {
            // A scene file that does not load is left out (each one named in the log); the
            // others are served.
            let (good, bad) = load_scene_dir_lenient(scenes_dir, &lib)?;
            for (name, s) in good {
                scenes.insert(name, Arc::new(SceneEntry::new(s, Source::Builtin)));
            }
            for (_, e) in &bad {
                tracing::error!(error = %e, "scene not loaded");
            }
            if !bad.is_empty() {
                let files: Vec<String> = bad.iter().map(|(f, _)| f.display().to_string()).collect();
                tracing::error!(
                    count = bad.len(),
                    files = %files.join(", "),
                    "scene files not loaded (the others are served)"
                );
            }
        }
        if let Ok(rd) = std::fs::read_dir(&up_scenes) {
            let mut files: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
            files.sort();
            for p in files
                .iter()
                .filter(|p| p.extension().and_then(|e| e.to_str()) == Some("json"))
            {
                let Some(name) = p.file_stem().and_then(|s| s.to_str()).map(str::to_string) else {
                    continue;
                };
                if scenes.contains_key(&name) {
                    tracing::warn!(scene = %name, "uploaded scene shadows a built-in one; skipped");
                    continue;
                }
                match Scene::from_file(p, &lib) {
                    Ok(s) => {
                        scenes.insert(name, Arc::new(SceneEntry::new(s, Source::Uploaded)));
                    }
                    Err(e) => {
                        tracing::warn!(file = %p.display(), error = %e, "skipping uploaded scene")
                    }
                }
            }
        }
        Ok(Catalog {
            robots: RwLock::new(robots),
            scenes: RwLock::new(scenes),
            robots_dir: up_robots,
            scenes_dir: up_scenes,
            write: std::sync::Mutex::new(()),
            grids: Arc::new(GridCache::new(Some(data_dir.join("reach")))),
            grasp_lists: Arc::new(crate::grasp::GraspListCache::new(Some(
                data_dir.join("grasps"),
            ))),
            grasp_dir: data_dir.join("grasps"),
            meshes_dir: scenes_dir.join("meshes"),
            upload_meshes_dir: up_meshes,
            tier: std::sync::OnceLock::new(),
        })
    }

    /// Single-grasp lists built by `kind: grasp_list`, kept under `<data-dir>/grasps`.
    pub fn grasp_lists(&self) -> Arc<crate::grasp::GraspListCache> {
        self.grasp_lists.clone()
    }

    /// The folder of the grasp-list files.
    pub fn grasp_dir(&self) -> &Path {
        &self.grasp_dir
    }

    /// The built-in meshes folder (`<scenes>/meshes`).
    pub fn meshes_dir(&self) -> &Path {
        &self.meshes_dir
    }

    /// Reachability grids built on demand (Bimanual IK-RRT), kept under `<data-dir>/reach`.
    pub fn grids(&self) -> Arc<GridCache> {
        self.grids.clone()
    }

    /// Puts `tier` behind the grid, grasp-list and roadmap caches (once).
    pub fn set_cache_tier(&self, tier: Arc<dyn crate::cache_tier::CacheTier>) {
        self.grids.set_tier(tier.clone());
        self.grasp_lists.set_tier(tier.clone());
        let _ = self.tier.set(tier);
    }

    /// The tier behind the caches, if any.
    pub fn cache_tier(&self) -> Option<Arc<dyn crate::cache_tier::CacheTier>> {
        self.tier.get().cloned()
    }

    pub fn robots(&self) -> Vec<(String, Arc<RobotEntry>)> {
        self.robots
            .read()
            .unwrap_or_else(lock_err)
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    }

    pub fn scenes(&self) -> Vec<(String, Arc<SceneEntry>)> {
        self.scenes
            .read()
            .unwrap_or_else(lock_err)
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    }

    pub fn counts(&self) -> (usize, usize) {
        (
            self.robots.read().unwrap_or_else(lock_err).len(),
            self.scenes.read().unwrap_or_else(lock_err).len(),
        )
    }

    /// A robot by name, or 404 naming `field`.
    pub fn robot(&self, name: &str, field: &str) -> ApiResult<Arc<RobotEntry>> {
        let found = self
            .robots
            .read()
            .unwrap_or_else(lock_err)
            .get(name)
            .cloned();
        found.ok_or_else(|| {
            ApiError::not_found(
                field,
                format!(
                    "unknown robot '{name}' (known: {})",
                    self.names(&self.robots)
                ),
            )
        })
    }

    /// A scene by name, or 404 naming `field`.
    pub fn scene(&self, name: &str, field: &str) -> ApiResult<Arc<SceneEntry>> {
        let found = self
            .scenes
            .read()
            .unwrap_or_else(lock_err)
            .get(name)
            .cloned();
        found.ok_or_else(|| {
            ApiError::not_found(
                field,
                format!(
                    "unknown scene '{name}' (known: {})",
                    self.names(&self.scenes)
                ),
            )
        })
    }

    /// The names of a map, comma-separated (for "unknown …" messages).
    fn names<T>(&self, map: &RwLock<BTreeMap<String, T>>) -> String {
        let m = map.read().unwrap_or_else(lock_err);
        if m.is_empty() {
            return "none".into();
        }
        m.keys().cloned().collect::<Vec<_>>().join(", ")
    }

    fn library(&self) -> RobotLibrary {
        self.robots
            .read()
            .unwrap_or_else(lock_err)
            .iter()
            .map(|(k, v)| (k.clone(), v.robot.clone()))
            .collect()
    }

    /// Validates and stores an uploaded robot (CPU work: call it off the async runtime).
    /// Returns true when it was created (false: replaced).
    /// Adds or replaces an uploaded robot: URDF, optional SRDF and optional joint limits
    /// (MoveIt's `joint_limits.yaml` text), kept under the data folder as
    /// `NAME.urdf`, `NAME.srdf` and `NAME.joint_limits.yaml`.
    pub fn put_robot(
        &self,
        name: &str,
        urdf: &str,
        srdf: Option<&str>,
        joint_limits: Option<&str>,
    ) -> ApiResult<bool> {
        check_name(name, "robot")?;
        check_urdf_size(urdf)?;
        check_urdf_meshes(urdf)?;
        let mut robot = Robot::from_strings(urdf, srdf, &self.robots_dir).map_err(|e| {
            let prefix = match &e {
                ModelError::Invalid { file, .. }
                | ModelError::Syntax { file, .. }
                | ModelError::Io { file, .. }
                    if file.ends_with(".srdf") =>
                {
                    "srdf"
                }
                _ => "urdf",
            };
            ApiError::from_model(&e, prefix)
        })?;
        if let Some(text) = joint_limits {
            if text.len() > MAX_JOINT_LIMITS_BYTES {
                return Err(ApiError::invalid(
                    "joint_limits",
                    format!("more than {MAX_JOINT_LIMITS_BYTES} bytes"),
                ));
            }
            robot
                .apply_joint_limits(text, "joint_limits.yaml")
                .map_err(|e| ApiError::from_model(&e, "joint_limits"))?;
        }
        // Errors and answers name the robot as uploaded, not by the URDF's <robot name>.
        robot.name = name.to_string();
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let existing = self
            .robots
            .read()
            .unwrap_or_else(lock_err)
            .get(name)
            .map(|e| e.source);
        if existing == Some(Source::Builtin) {
            return Err(ApiError::conflict(format!(
                "robot '{name}' is built in and read-only"
            )));
        }
        // Scenes using the model must still validate with the new one.
        let mut lib = self.library();
        let robot = Arc::new(robot);
        lib.insert(name.to_string(), robot.clone());
        let mut rescoped = Vec::new();
        for (sname, entry) in self.scenes() {
            if entry.scene.json.robots.iter().any(|r| r.model == name) {
                let s = Scene::from_json(entry.scene.json.clone(), &sname, &self.scenes_dir, &lib).map_err(|e| {
                    ApiError::conflict(format!("scene '{sname}' uses robot '{name}' and does not validate with the new model: {e}"))
                })?;
                rescoped.push((sname, SceneEntry::new(s, entry.source)));
            }
        }
        write_atomic(&self.robots_dir.join(format!("{name}.urdf")), urdf)?;
        let srdf_path = self.robots_dir.join(format!("{name}.srdf"));
        match srdf {
            Some(s) => write_atomic(&srdf_path, s)?,
            None => remove_file(&srdf_path)?,
        }
        let limits_path = self.robots_dir.join(format!("{name}.joint_limits.yaml"));
        match joint_limits {
            Some(s) => write_atomic(&limits_path, s)?,
            None => remove_file(&limits_path)?,
        }
        self.robots.write().unwrap_or_else(lock_err).insert(
            name.to_string(),
            Arc::new(RobotEntry::new(robot, Source::Uploaded)),
        );
        let mut scenes = self.scenes.write().unwrap_or_else(lock_err);
        for (sname, e) in rescoped {
            scenes.insert(sname, Arc::new(e));
        }
        Ok(existing.is_none())
    }

    pub fn delete_robot(&self, name: &str) -> ApiResult<()> {
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let entry = self.robot(name, "name")?;
        if entry.source == Source::Builtin {
            return Err(ApiError::conflict(format!(
                "robot '{name}' is built in and read-only"
            )));
        }
        if let Some((s, _)) = self
            .scenes()
            .into_iter()
            .find(|(_, e)| e.scene.json.robots.iter().any(|r| r.model == name))
        {
            return Err(ApiError::conflict(format!(
                "robot '{name}' is used by scene '{s}'; delete the scene first"
            )));
        }
        remove_file(&self.robots_dir.join(format!("{name}.urdf")))?;
        remove_file(&self.robots_dir.join(format!("{name}.srdf")))?;
        remove_file(&self.robots_dir.join(format!("{name}.joint_limits.yaml")))?;
        self.robots.write().unwrap_or_else(lock_err).remove(name);
        Ok(())
    }

    /// Validates and stores an uploaded scene. Returns true when it was created.
    pub fn put_scene(&self, name: &str, json: SceneJson) -> ApiResult<bool> {
        check_name(name, "scene")?;
        if json.name != name {
            return Err(ApiError::invalid(
                "name",
                format!(
                    "'{}' differs from the scene name '{name}' in the URL",
                    json.name
                ),
            ));
        }
        for (list, bodies) in [("obstacles", &json.obstacles), ("objects", &json.objects)] {
            for (i, b) in bodies.iter().enumerate() {
                for (j, g) in b.shapes.iter().enumerate() {
                    if let Some(p) = &g.path {
                        check_mesh_path(p).map_err(|m| {
                            ApiError::invalid(format!("{list}[{i}].shapes[{j}].path"), m)
                        })?;
                    }
                }
            }
        }
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let existing = self
            .scenes
            .read()
            .unwrap_or_else(lock_err)
            .get(name)
            .map(|e| e.source);
        if existing == Some(Source::Builtin) {
            return Err(ApiError::conflict(format!(
                "scene '{name}' is built in and read-only"
            )));
        }
        let lib = self.library();
        for (i, r) in json.robots.iter().enumerate() {
            if !lib.contains_key(&r.model) {
                return Err(ApiError::not_found(
                    format!("robots[{i}].model"),
                    format!("unknown robot '{}'", r.model),
                ));
            }
        }
        for (list, bodies) in [("obstacles", &json.obstacles), ("objects", &json.objects)] {
            for (i, b) in bodies.iter().enumerate() {
                for (j, g) in b.shapes.iter().enumerate() {
                    let Some(p) = &g.path else { continue };
                    if !self.scenes_dir.join(p).is_file() {
                        let hint = match mesh_upload_name(p) {
                            Some(m) => format!("upload it first with PUT /v1/meshes/{m}"),
                            None => "an uploaded scene names an uploaded mesh as 'meshes/NAME' \
                                     (PUT /v1/meshes/NAME)"
                                .to_string(),
                        };
                        return Err(ApiError::invalid(
                            format!("{list}[{i}].shapes[{j}].path"),
                            format!("no mesh '{p}' on the server; {hint}"),
                        ));
                    }
                }
            }
        }
        let text =
            serde_json::to_string_pretty(&json).map_err(|e| ApiError::internal(e.to_string()))?;
        let scene = Scene::from_json(json, name, &self.scenes_dir, &lib)
            .map_err(|e| ApiError::from_model(&e, ""))?;
        write_atomic(&self.scenes_dir.join(format!("{name}.json")), &text)?;
        self.scenes.write().unwrap_or_else(lock_err).insert(
            name.to_string(),
            Arc::new(SceneEntry::new(scene, Source::Uploaded)),
        );
        Ok(existing.is_none())
    }

    pub fn delete_scene(&self, name: &str) -> ApiResult<()> {
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let entry = self.scene(name, "name")?;
        if entry.source == Source::Builtin {
            return Err(ApiError::conflict(format!(
                "scene '{name}' is built in and read-only"
            )));
        }
        remove_file(&self.scenes_dir.join(format!("{name}.json")))?;
        self.scenes.write().unwrap_or_else(lock_err).remove(name);
        Ok(())
    }
}

/// Mesh file names of an uploaded URDF must be relative paths inside the data directory.
fn check_urdf_meshes(urdf: &str) -> ApiResult<()> {
    let doc = match roxmltree::Document::parse(urdf) {
        Ok(d) => d,
        // The model parser reports the syntax error with its position.
        Err(_) => return Ok(()),
    };
    for n in doc.descendants().filter(|n| n.has_tag_name("mesh")) {
        if let Some(f) = n.attribute("filename") {
            let link = n
                .ancestors()
                .find(|a| a.has_tag_name("link"))
                .and_then(|a| a.attribute("name"))
                .unwrap_or("?");
            check_mesh_path(f)
                .map_err(|m| ApiError::invalid(format!("urdf.link[{link}].mesh.filename"), m))?;
        }
    }
    Ok(())
}

/// Largest uploaded mesh file (bytes).
pub const MAX_MESH_BYTES: usize = 16 << 20;
/// Most triangles of an uploaded mesh.
pub const MAX_MESH_TRIANGLES: usize = 200_000;

/// An uploaded mesh as `GET /v1/meshes` lists it.
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct MeshSummary {
    /// File name; an uploaded scene names it as `meshes/NAME` in a shape's `path`.
    pub name: String,
    pub bytes: u64,
    /// Vertices and triangles as read (present in upload answers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vertices: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triangles: Option<usize>,
    /// Whether it bounds a solid (closed, consistently oriented); else it is checked as its
    /// convex hull (present in upload answers).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solid: Option<bool>,
}

/// The upload name of a scene shape path `meshes/NAME` (`./` parts ignored), else `None`.
pub(super) fn mesh_upload_name(path: &str) -> Option<String> {
    let parts: Vec<&str> = Path::new(path)
        .components()
        .filter(|c| !matches!(c, std::path::Component::CurDir))
        .map(|c| c.as_os_str().to_str())
        .collect::<Option<_>>()?;
    match parts.as_slice() {
        ["meshes", name] => Some((*name).to_string()),
        _ => None,
    }
}

/// A mesh upload name: a file name ([`check_name`]) ending in `.stl`, `.obj` or `.dae`.
pub fn check_mesh_name(name: &str) -> ApiResult<()> {
    check_name(name, "mesh")?;
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("stl" | "obj" | "dae")) {
        return Err(ApiError::invalid(
            "name",
            format!("mesh name '{name}' must end in .stl, .obj or .dae (the format)"),
        ));
    }
    Ok(())
}

impl Catalog {
    fn scenes_using_mesh(&self, name: &str) -> Vec<(String, Arc<SceneEntry>)> {
        self.scenes()
            .into_iter()
            .filter(|(_, e)| {
                e.source == Source::Uploaded
                    && e.scene
                        .json
                        .obstacles
                        .iter()
                        .chain(&e.scene.json.objects)
                        .flat_map(|b| &b.shapes)
                        .filter_map(|g| g.path.as_deref())
                        .any(|p| mesh_upload_name(p).as_deref() == Some(name))
            })
            .collect()
    }

    /// Validates and stores an uploaded mesh (STL, OBJ or COLLADA; CPU work: call it off the
    /// async runtime): at most [`MAX_MESH_BYTES`] and [`MAX_MESH_TRIANGLES`], read without
    /// following references to other files. Uploaded scenes using it must still validate.
    /// Returns whether it was created (false: replaced) and its summary.
    pub fn put_mesh(&self, name: &str, bytes: &[u8]) -> ApiResult<(bool, MeshSummary)> {
        check_mesh_name(name)?;
        if bytes.len() > MAX_MESH_BYTES {
            return Err(ApiError::invalid(
                "body",
                format!(
                    "{} bytes; a mesh may have at most {MAX_MESH_BYTES}",
                    bytes.len()
                ),
            ));
        }
        let mesh = crate::geometry::Mesh::parse(bytes, name, [1.0; 3])
            .map_err(|m| ApiError::invalid("body", m))?;
        if mesh.triangles.is_empty() || mesh.triangles.len() > MAX_MESH_TRIANGLES {
            return Err(ApiError::invalid(
                "body",
                format!(
                    "mesh '{name}' has {} triangles; 1 to {MAX_MESH_TRIANGLES} are accepted",
                    mesh.triangles.len()
                ),
            ));
        }
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let path = self.upload_meshes_dir.join(name);
        let old = std::fs::read(&path).ok();
        let tmp = self.upload_meshes_dir.join(format!(".{name}.tmp-upload"));
        std::fs::write(&tmp, bytes)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .map_err(|e| ApiError::internal(format!("writing {}: {e}", path.display())))?;
        // Scenes using the mesh are rebuilt with the new one (or the old one is put back).
        let lib = self.library();
        let mut rescoped = Vec::new();
        for (sname, entry) in self.scenes_using_mesh(name) {
            match Scene::from_json(entry.scene.json.clone(), &sname, &self.scenes_dir, &lib) {
                Ok(s) => rescoped.push((sname, SceneEntry::new(s, entry.source))),
                Err(e) => {
                    let _ = match &old {
                        Some(b) => std::fs::write(&path, b),
                        None => std::fs::remove_file(&path),
                    };
                    return Err(ApiError::conflict(format!(
                        "scene '{sname}' uses mesh '{name}' and does not validate with the new one: {e}"
                    )));
                }
            }
        }
        let mut scenes = self.scenes.write().unwrap_or_else(lock_err);
        for (sname, e) in rescoped {
            scenes.insert(sname, Arc::new(e));
        }
        Ok((
            old.is_none(),
            MeshSummary {
                name: name.to_string(),
                bytes: bytes.len() as u64,
                vertices: Some(mesh.vertices.len()),
                triangles: Some(mesh.triangles.len()),
                solid: Some(mesh.solid.is_ok()),
            },
        ))
    }

    /// The uploaded meshes, by name.
    pub fn meshes(&self) -> Vec<MeshSummary> {
        let mut out: Vec<MeshSummary> = std::fs::read_dir(&self.upload_meshes_dir)
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .filter_map(|e| {
                        let name = e.file_name().to_str()?.to_string();
                        check_mesh_name(&name).ok()?;
                        let meta = e.metadata().ok().filter(|m| m.is_file())?;
                        Some(MeshSummary {
                            name,
                            bytes: meta.len(),
                            vertices: None,
                            triangles: None,
                            solid: None,
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        out
    }

    /// The bytes of an uploaded mesh (404 naming `name`).
    pub fn mesh_bytes(&self, name: &str) -> ApiResult<Vec<u8>> {
        check_mesh_name(name)?;
        std::fs::read(self.upload_meshes_dir.join(name))
            .map_err(|_| ApiError::not_found("name", format!("unknown mesh '{name}'")))
    }

    /// Deletes an uploaded mesh (409 while an uploaded scene uses it).
    pub fn delete_mesh(&self, name: &str) -> ApiResult<()> {
        check_mesh_name(name)?;
        let _w = self.write.lock().unwrap_or_else(lock_err);
        let path = self.upload_meshes_dir.join(name);
        if !path.is_file() {
            return Err(ApiError::not_found(
                "name",
                format!("unknown mesh '{name}'"),
            ));
        }
        if let Some((s, _)) = self.scenes_using_mesh(name).into_iter().next() {
            return Err(ApiError::conflict(format!(
                "mesh '{name}' is used by scene '{s}'; delete the scene first"
            )));
        }
        remove_file(&path)
    }
}
