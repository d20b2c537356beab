//! Loading every robot of a folder (`NAME.urdf` + optional `NAME.srdf`) and every scene
//! (`*.json`) of a folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{ModelError, Robot, RobotLibrary, Scene};

/// Loads `dir/*.urdf`, each with the `.srdf` of the same stem when present. The library key is
/// the file stem.
pub fn load_robot_dir(dir: &Path) -> Result<RobotLibrary, ModelError> {
    let mut lib = RobotLibrary::new();
    for p in sorted_files(dir, "urdf")? {
        let stem = stem_of(&p, "robot");
        let srdf = p.with_extension("srdf");
        let robot = Robot::from_files(&p, srdf.is_file().then_some(srdf.as_path()))?;
        lib.insert(stem, Arc::new(robot));
    }
    Ok(lib)
}

/// Loads `dir/*.json` as scenes, keyed by file stem; the first file (in name order) that does
/// not load is the error.
pub fn load_scene_dir(
    dir: &Path,
    robots: &RobotLibrary,
) -> Result<BTreeMap<String, Scene>, ModelError> {
    let (out, bad) = load_scene_dir_lenient(dir, robots)?;
    match bad.into_iter().next() {
        Some((_, e)) => Err(e),
        None => Ok(out),
    }
}

/// Loads `dir/*.json` as scenes, keyed by file stem, skipping the files that do not load: the
/// scenes that loaded, and each file that did not with its error (sorted by file name). Only an
/// unreadable folder is an error.
#[allow(clippy::type_complexity)]
pub fn load_scene_dir_lenient(
    dir: &Path,
    robots: &RobotLibrary,
) -> Result<(BTreeMap<String, Scene>, Vec<(PathBuf, ModelError)>), ModelError> {
    let mut out = BTreeMap::new();
    let mut bad = Vec::new();
    for p in sorted_files(dir, "json")? {
        let stem = stem_of(&p, "scene");
        match Scene::from_file(&p, robots) {
            Ok(s) => {
                out.insert(stem, s);
            }
            Err(e) => bad.push((p, e)),
        }
    }
    Ok((out, bad))
}

/// The file stem of `p` (the library key), `default` when it has none.
fn stem_of(p: &Path, default: &str) -> String {
    p.file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or(default)
        .to_string()
}

fn sorted_files(dir: &Path, ext: &str) -> Result<Vec<PathBuf>, ModelError> {
    let rd = std::fs::read_dir(dir).map_err(|e| ModelError::Io {
        file: dir.display().to_string(),
        reason: e.to_string(),
    })?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().and_then(|e| e.to_str()) == Some(ext))
        .collect();
    v.sort();
    Ok(v)
}

/// The folder holding the shipped `robots/` and `scenes/`: the working directory when it has
/// them, else the source tree the binary was built from.
pub fn data_root() -> PathBuf {
    let cwd = PathBuf::from(".");
    if cwd.join("robots").is_dir() && cwd.join("scenes").is_dir() {
        cwd
    } else {
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
    }
}
