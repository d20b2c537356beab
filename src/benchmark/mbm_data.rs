//! Where the MotionBenchMaker data lives, and how to get it.
//!
//! The problem sets and robot models of [`crate::benchmark::mbm`] are not part of this repository. A
//! complete data folder holds, for each of [`ROBOTS`], `NAME/NAME_spherized.urdf`,
//! `NAME/NAME.srdf` and `NAME/problems.json`. [`locate`] looks for one, in this order:
//!
//! 1. `$MANYHANDS_MBM_DIR` ([`MBM_DIR_ENV`]) when it is set (then nowhere else);
//! 2. `../shared/benchmarks/mbm` ([`SHARED_DIR`]) relative to the working directory (the
//!    project's own machines keep the data beside the repository);
//! 3. the cache `mbm/` under [`cache_root`], which `manyhands data mbm` fills.
//!
//! [`install_from_sdist`] fills a folder from the public source of the data: the `resources/`
//! of the `vamp-planner` 0.6.4 source package on PyPI (Apache-2.0). It checks the package's
//! sha256 ([`SDIST_SHA256`]), copies each robot's spherized URDF and SRDF, its visual meshes
//! (`resources/ROBOT/meshes/**`, beside the URDF where it names them, so the viewer draws the
//! robot with them; planners never read them; bounded by [`MAX_MESH_FILE_BYTES`],
//! [`MAX_MESH_FILES`] and [`MAX_MESH_BYTES`], names restricted to plain file names) and converts the robot's `problems.tar.bz2`
//! (MoveIt scene and request YAML files) to the `problems.json` that [`crate::benchmark::mbm::MbmFile`]
//! reads, as VAMP's own `resources/problem_tar_to_pkl_json.py` does; a problem is `valid` when
//! its start and at least one goal are collision-free for the robot's sphere model.
//! [`download_sdist`] gets the package with `python3 -m pip download` (pip is the ordinary
//! client of that index; this crate's HTTP client has no TLS).
//!
//! Tests that need the data call [`data_for_test`]: without data they print one `SKIPPED …`
//! line and return, unless `MANYHANDS_REQUIRE_MBM=1` ([`REQUIRE_ENV`]) turns absence into a
//! failure (CI sets it).

use std::collections::BTreeMap;
use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};
use sha2::{Digest, Sha256};
use thiserror::Error;
use yaml_rust2::{Yaml, YamlLoader};

use crate::benchmark::mbm::{MbmError, MbmFile};
use crate::collision::{AutoChecker, CollisionChecker};
use crate::model::ModelError;
use crate::Robot;

/// Environment variable naming a data folder (used alone when set).
pub const MBM_DIR_ENV: &str = "MANYHANDS_MBM_DIR";
/// Environment variable that makes [`data_for_test`] fail instead of skip (`1`).
pub const REQUIRE_ENV: &str = "MANYHANDS_REQUIRE_MBM";
/// Environment variable overriding the cache root ([`cache_root`]).
pub const CACHE_DIR_ENV: &str = "MANYHANDS_CACHE_DIR";
/// The project machines' copy, relative to the working directory.
pub const SHARED_DIR: &str = "../shared/benchmarks/mbm";
/// The robots of a complete data folder.
pub const ROBOTS: [&str; 2] = ["panda", "baxter"];
/// The source package (pip requirement) and its file.
pub const SDIST_REQUIREMENT: &str = "vamp-planner==0.6.4";
pub const SDIST_FILE: &str = "vamp_planner-0.6.4.tar.gz";
/// sha256 of [`SDIST_FILE`] as published (65 487 904 bytes).
pub const SDIST_SHA256: &str = "d3150c6b67ff941af9ad56480b31d3fb73b12211ea21dc684f7737b059f6daba";

/// VAMP's configuration order (`vamp.ROBOT.joint_names()`) of each robot.
fn joint_names(robot: &str) -> Option<&'static [&'static str]> {
    match robot {
        "panda" => Some(&[
            "panda_joint1",
            "panda_joint2",
            "panda_joint3",
            "panda_joint4",
            "panda_joint5",
            "panda_joint6",
            "panda_joint7",
        ]),
        "baxter" => Some(&[
            "left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2",
            "right_s0", "right_s1", "right_e0", "right_e1", "right_w0", "right_w1", "right_w2",
        ]),
        _ => None,
    }
}

/// The files of one robot in a data folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RobotFiles {
    pub urdf: PathBuf,
    pub srdf: PathBuf,
    pub problems: PathBuf,
}

/// Issue 23's `panda_four` cell ([`crate::model::panda_four`]) over the Panda of data folder
/// `dir`, loaded as an outside robot under the model name `panda`.
pub fn panda_four_scene(dir: &Path) -> Result<crate::model::Scene, ModelError> {
    let f = robot_files(dir, "panda");
    let robot = Robot::from_files(&f.urdf, Some(&f.srdf))?;
    let mut lib = crate::model::RobotLibrary::new();
    lib.insert("panda".into(), Arc::new(robot));
    crate::model::Scene::from_json(
        crate::model::panda_four("panda"),
        "panda_four",
        Path::new("."),
        &lib,
    )
}

/// The files of `robot` in data folder `dir` (whether or not they exist).
pub fn robot_files(dir: &Path, robot: &str) -> RobotFiles {
    let d = dir.join(robot);
    RobotFiles {
        urdf: d.join(format!("{robot}_spherized.urdf")),
        srdf: d.join(format!("{robot}.srdf")),
        problems: d.join("problems.json"),
    }
}

/// The first file a complete data folder needs that `dir` lacks.
pub fn missing_file(dir: &Path) -> Option<PathBuf> {
    ROBOTS.iter().find_map(|r| {
        let f = robot_files(dir, r);
        [f.urdf, f.srdf, f.problems]
            .into_iter()
            .find(|p| !p.is_file())
    })
}

/// The cache root: `$MANYHANDS_CACHE_DIR`, else `$XDG_CACHE_HOME/manyhands`, else
/// `$HOME/.cache/manyhands` (`None` without any of them). The data goes to `mbm/` under it.
pub fn cache_root() -> Option<PathBuf> {
    let var = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    var(CACHE_DIR_ENV)
        .or_else(|| var("XDG_CACHE_HOME").map(|d| d.join("manyhands")))
        .or_else(|| var("HOME").map(|d| d.join(".cache").join("manyhands")))
}

/// The data folder `manyhands data mbm` fills by default: `mbm/` under [`cache_root`].
pub fn cache_dir() -> Option<PathBuf> {
    cache_root().map(|d| d.join("mbm"))
}

/// The complete data folder to use, or why there is none (every place looked at).
pub fn locate() -> Result<PathBuf, String> {
    if let Some(d) = std::env::var_os(MBM_DIR_ENV).filter(|v| !v.is_empty()) {
        let d = PathBuf::from(d);
        return match missing_file(&d) {
            None => Ok(d),
            Some(f) => Err(format!(
                "{MBM_DIR_ENV}={}: no {} (`manyhands data mbm --dir DIR` fetches the data)",
                d.display(),
                f.display()
            )),
        };
    }
    let mut places = vec![PathBuf::from(SHARED_DIR)];
    places.extend(cache_dir());
    for d in &places {
        if missing_file(d).is_none() {
            return Ok(d.clone());
        }
    }
    let looked: Vec<String> = places.iter().map(|d| d.display().to_string()).collect();
    Err(format!(
        "{MBM_DIR_ENV} is not set and neither {} holds the Panda and Baxter sets \
         (run `manyhands data mbm`)",
        looked.join(" nor ")
    ))
}

/// The complete data folder, if there is one ([`locate`]).
pub fn data_dir() -> Option<PathBuf> {
    locate().ok()
}

/// Whether `MANYHANDS_REQUIRE_MBM` asks for the data (any value but empty and `0`).
pub fn data_required() -> bool {
    std::env::var(REQUIRE_ENV).is_ok_and(|v| !v.is_empty() && v != "0")
}

/// The first line of a test that needs the data: the data folder, or — without one — `None`
/// after reporting `SKIPPED (…): TEST` ([`crate::skips::report`]), so that a run can count the
/// tests that did not run. Panics instead when [`data_required`].
pub fn data_for_test() -> Option<PathBuf> {
    match locate() {
        Ok(d) => Some(d),
        Err(why) => {
            assert!(
                !data_required(),
                "{REQUIRE_ENV} is set and the MotionBenchMaker data is missing: {why}"
            );
            crate::skips::report(&format!(
                "no MotionBenchMaker data: set {MBM_DIR_ENV} or run manyhands data mbm"
            ));
            None
        }
    }
}

/// Why the data could not be fetched or converted.
#[derive(Debug, Error)]
pub enum FetchError {
    #[error(
        "cannot run `python3 -m pip` ({0}); pip downloads {SDIST_REQUIREMENT}: install python3 \
         with pip (e.g. apt-get install python3-pip), or get {SDIST_FILE} by other means and \
         pass it with --sdist FILE"
    )]
    NoPip(String),
    #[error(
        "pip could not download {SDIST_REQUIREMENT} (offline, or the Python package index out \
         of reach?); get {SDIST_FILE} by other means and pass it with --sdist FILE. pip said:\n{0}"
    )]
    Download(String),
    #[error("{file}: sha256 {got}, expected {SDIST_SHA256}: not the published {SDIST_FILE}")]
    Checksum { file: String, got: String },
    #[error("{file}: {reason}")]
    Io { file: String, reason: String },
    #[error("{file}: {reason}")]
    Archive { file: String, reason: String },
    #[error("{robot} {member}: {reason}")]
    Convert {
        robot: String,
        member: String,
        reason: String,
    },
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Mbm(#[from] MbmError),
}

fn io_err(file: &Path) -> impl FnOnce(std::io::Error) -> FetchError + '_ {
    move |e| FetchError::Io {
        file: file.display().to_string(),
        reason: e.to_string(),
    }
}

/// Progress of a fetch: stages, each with a total in its units (bytes, files or problems)
/// when known, and advances within the stage.
pub trait FetchProgress {
    fn stage(&mut self, what: &str, total: Option<u64>);
    fn advance(&mut self, n: u64);
    /// A line of status within the stage (e.g. pip's output).
    fn note(&mut self, line: &str);
}

/// No progress report.
pub struct Quiet;

impl FetchProgress for Quiet {
    fn stage(&mut self, _: &str, _: Option<u64>) {}
    fn advance(&mut self, _: u64) {}
    fn note(&mut self, _: &str) {}
}

/// Downloads [`SDIST_FILE`] into `dir` with `python3 -m pip download --no-deps --no-binary
/// vamp-planner` (pip also fetches the package's build backend to read its metadata) and
/// returns its path. pip's output lines go to [`FetchProgress::note`].
pub fn download_sdist(dir: &Path, progress: &mut dyn FetchProgress) -> Result<PathBuf, FetchError> {
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    progress.stage(&format!("pip download {SDIST_REQUIREMENT}"), None);
    let mut child = Command::new("python3")
        .args([
            "-m",
            "pip",
            "download",
            "--no-deps",
            "--no-binary",
            "vamp-planner",
        ])
        .args(["--disable-pip-version-check", "--progress-bar", "off"])
        .arg(SDIST_REQUIREMENT)
        .arg("-d")
        .arg(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| FetchError::NoPip(e.to_string()))?;
    let mut err_text = String::new();
    let stderr = child.stderr.take();
    let err_reader = std::thread::spawn(move || {
        let mut s = String::new();
        if let Some(mut e) = stderr {
            let _ = e.read_to_string(&mut s);
        }
        s
    });
    let mut out_lines = Vec::new();
    if let Some(out) = child.stdout.take() {
        use std::io::BufRead;
        for line in std::io::BufReader::new(out).lines().map_while(Result::ok) {
            progress.note(line.trim());
            out_lines.push(line);
        }
    }
    if let Ok(s) = err_reader.join() {
        err_text = s;
    }
    let status = child.wait().map_err(|e| FetchError::NoPip(e.to_string()))?;
    if !status.success() {
        if err_text.contains("No module named pip") {
            return Err(FetchError::NoPip(err_text.trim().to_string()));
        }
        let tail: Vec<&str> = out_lines
            .iter()
            .map(String::as_str)
            .chain(err_text.lines())
            .filter(|l| !l.trim().is_empty())
            .collect();
        let tail = tail[tail.len().saturating_sub(12)..].join("\n");
        return Err(FetchError::Download(tail));
    }
    let file = dir.join(SDIST_FILE);
    if !file.is_file() {
        return Err(FetchError::Download(format!(
            "pip succeeded but {} is not there",
            file.display()
        )));
    }
    Ok(file)
}

/// Reads through `r`, reporting every chunk's size to `progress`.
struct Counting<'a, R> {
    inner: R,
    progress: &'a mut dyn FetchProgress,
}

impl<R: Read> Read for Counting<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.progress.advance(n as u64);
        Ok(n)
    }
}

/// The sha256 of `file`, lower-case hex.
pub fn sha256_file(file: &Path, progress: &mut dyn FetchProgress) -> Result<String, FetchError> {
    let len = std::fs::metadata(file).map_err(io_err(file))?.len();
    progress.stage("sha256", Some(len));
    let f = std::fs::File::open(file).map_err(io_err(file))?;
    let mut r = Counting { inner: f, progress };
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = r.read(&mut buf).map_err(io_err(file))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// What [`install_from_sdist`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InstallReport {
    pub dir: PathBuf,
    /// Bytes of all files written.
    pub bytes: u64,
    /// Per robot: problems, valid problems.
    pub robots: Vec<(String, usize, usize)>,
}

/// Checks `sdist` against [`SDIST_SHA256`], then unpacks and converts it into `dest` (written
/// beside it first and moved into place at the end; an existing `dest` is replaced).
pub fn install_from_sdist(
    sdist: &Path,
    dest: &Path,
    progress: &mut dyn FetchProgress,
) -> Result<InstallReport, FetchError> {
    let got = sha256_file(sdist, progress)?;
    if got != SDIST_SHA256 {
        return Err(FetchError::Checksum {
            file: sdist.display().to_string(),
            got,
        });
    }
    unpack_and_convert(sdist, dest, &ROBOTS, progress)
}

/// The robot files and problem archives of `robots` in the source package, unpacked into a
/// staging folder beside `dest`, problem archives converted; then moved to `dest`. No
/// checksum check (see [`install_from_sdist`]).
pub fn unpack_and_convert(
    sdist: &Path,
    dest: &Path,
    robots: &[&str],
    progress: &mut dyn FetchProgress,
) -> Result<InstallReport, FetchError> {
    let parent = dest
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    let name = dest.file_name().and_then(|n| n.to_str()).unwrap_or("mbm");
    let staging = parent.join(format!(".{name}.partial-{}", std::process::id()));
    if staging.exists() {
        std::fs::remove_dir_all(&staging).map_err(io_err(&staging))?;
    }
    let result = unpack_into(sdist, &staging, robots, progress);
    let mut report = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e);
        }
    };
    if dest.exists() {
        std::fs::remove_dir_all(dest).map_err(io_err(dest))?;
    }
    std::fs::rename(&staging, dest).map_err(io_err(dest))?;
    report.dir = dest.to_path_buf();
    Ok(report)
}

fn unpack_into(
    sdist: &Path,
    out: &Path,
    robots: &[&str],
    progress: &mut dyn FetchProgress,
) -> Result<InstallReport, FetchError> {
    let archive_err = |reason: String| FetchError::Archive {
        file: sdist.display().to_string(),
        reason,
    };
    let len = std::fs::metadata(sdist).map_err(io_err(sdist))?.len();
    let f = std::fs::File::open(sdist).map_err(io_err(sdist))?;
    progress.stage("unpack", Some(len));
    let mut bytes = 0u64;
    let mut problem_archives: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    // Visual meshes (written below as they come): per robot, files and bytes so far.
    let mut mesh_counts: BTreeMap<String, (usize, u64)> = BTreeMap::new();
    let mut mesh_files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    {
        let gz = flate2::read::GzDecoder::new(Counting { inner: f, progress });
        let mut tar = tar::Archive::new(gz);
        let entries = tar
            .entries()
            .map_err(|e| archive_err(format!("not a .tar.gz: {e}")))?;
        for entry in entries {
            let mut entry = entry.map_err(|e| archive_err(format!("not a .tar.gz: {e}")))?;
            let path = entry
                .path()
                .map_err(|e| archive_err(e.to_string()))?
                .into_owned();
            let parts: Vec<String> = path
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            let target = match parts.as_slice() {
                [_, lic] if lic == "LICENSE.txt" => Some(out.join("LICENSE-vamp-resources.txt")),
                [_, res, robot, meshes, rest @ ..]
                    if res == "resources"
                        && meshes == "meshes"
                        && !rest.is_empty()
                        && robots.contains(&robot.as_str()) =>
                {
                    if entry.header().entry_type().is_file()
                        && path
                            .components()
                            .all(|c| matches!(c, std::path::Component::Normal(_)))
                        && rest.iter().all(|p| safe_mesh_part(p))
                        && rest.last().is_some_and(|f| mesh_file_kind(f))
                    {
                        let n = mesh_counts.entry(robot.clone()).or_insert((0, 0));
                        let data = read_bounded(&mut entry, MAX_MESH_FILE_BYTES)
                            .map_err(|e| archive_err(format!("{}: {e}", path.display())))?
                            .ok_or_else(|| {
                                archive_err(format!(
                                    "{}: over {MAX_MESH_FILE_BYTES} bytes (the limit of one mesh file)",
                                    path.display()
                                ))
                            })?;
                        n.0 += 1;
                        n.1 += data.len() as u64;
                        if n.0 > MAX_MESH_FILES || n.1 > MAX_MESH_BYTES {
                            return Err(archive_err(format!(
                                "resources/{robot}/meshes: over {MAX_MESH_FILES} files or \
                                 {MAX_MESH_BYTES} bytes"
                            )));
                        }
                        let mut t = out.join(robot.as_str()).join("meshes");
                        for part in rest {
                            t.push(part);
                        }
                        mesh_files.push((t, data));
                    }
                    None
                }
                [_, res, robot, file] if res == "resources" && robots.contains(&robot.as_str()) => {
                    if file == "problems.tar.bz2" {
                        let mut data = Vec::new();
                        entry
                            .read_to_end(&mut data)
                            .map_err(|e| archive_err(format!("{}: {e}", path.display())))?;
                        problem_archives.insert(robot.clone(), data);
                        None
                    } else if *file == format!("{robot}_spherized.urdf")
                        || *file == format!("{robot}.srdf")
                    {
                        Some(out.join(robot).join(file))
                    } else {
                        None
                    }
                }
                _ => None,
            };
            for (t, data) in mesh_files.drain(..) {
                let dir = t.parent().unwrap_or(out);
                std::fs::create_dir_all(dir).map_err(io_err(dir))?;
                std::fs::write(&t, &data).map_err(io_err(&t))?;
                bytes += data.len() as u64;
            }
            if let Some(t) = target {
                let dir = t.parent().unwrap_or(out);
                std::fs::create_dir_all(dir).map_err(io_err(dir))?;
                let mut data = Vec::new();
                entry
                    .read_to_end(&mut data)
                    .map_err(|e| archive_err(format!("{}: {e}", path.display())))?;
                std::fs::write(&t, &data).map_err(io_err(&t))?;
                bytes += data.len() as u64;
            }
        }
    }
    let mut report = InstallReport {
        dir: out.to_path_buf(),
        bytes,
        robots: Vec::new(),
    };
    for robot in robots {
        let files = robot_files(out, robot);
        for f in [&files.urdf, &files.srdf] {
            if !f.is_file() {
                return Err(archive_err(format!(
                    "no resources/{robot}/{} in the package",
                    f.file_name().and_then(|n| n.to_str()).unwrap_or("?")
                )));
            }
        }
        let data = problem_archives.get(*robot).ok_or_else(|| {
            archive_err(format!(
                "no resources/{robot}/problems.tar.bz2 in the package"
            ))
        })?;
        let joints = joint_names(robot).ok_or_else(|| FetchError::Convert {
            robot: robot.to_string(),
            member: String::new(),
            reason: "no joint order known for this robot".into(),
        })?;
        let model = Arc::new(Robot::from_files(&files.urdf, Some(&files.srdf))?);
        let json = convert_problems(data, robot, joints, &model, progress)?;
        std::fs::write(&files.problems, &json).map_err(io_err(&files.problems))?;
        bytes += json.len() as u64;
        // The written file must load as the benchmark reads it.
        let file = MbmFile::load(&files.problems)?;
        file.joint_vars(&model)?;
        let all: Vec<_> = file.sets.iter().flat_map(|s| &s.problems).collect();
        let valid = all.iter().filter(|p| p.valid).count();
        report.robots.push((robot.to_string(), all.len(), valid));
    }
    let note = out.join("SOURCE.md");
    let text = format!(
        "# MotionBenchMaker problem sets\n\nWritten by `manyhands data mbm` from `resources/` of \
         {SDIST_FILE} (the `vamp-planner` 0.6.4 source package on PyPI, sha256 {SDIST_SHA256}; \
         Apache-2.0, see LICENSE-vamp-resources.txt). Robots: {}. Each robot's spherized URDF, \
         SRDF and visual meshes (`meshes/`, when the package has them) are copied as they are; \
         `problems.json` is converted \
         from its `problems.tar.bz2` (MoveIt scenes and requests) as VAMP's \
         `resources/problem_tar_to_pkl_json.py` does, `valid` = start and one goal free for \
         the sphere model. The problems are MotionBenchMaker's (Chamzas et al., RA-L 2022).\n",
        robots.join(", ")
    );
    std::fs::write(&note, &text).map_err(io_err(&note))?;
    report.bytes = bytes + text.len() as u64;
    Ok(report)
}

/// Largest visual mesh file [`unpack_and_convert`] installs (the bound of an uploaded mesh).
pub const MAX_MESH_FILE_BYTES: u64 = 16 << 20;
/// Most visual mesh files of one robot [`unpack_and_convert`] installs.
pub const MAX_MESH_FILES: usize = 512;
/// Most bytes of visual mesh files of one robot [`unpack_and_convert`] installs.
pub const MAX_MESH_BYTES: u64 = 128 << 20;

/// A folder or file name under `resources/ROBOT/meshes/` that is installed: ASCII letters,
/// digits, `_`, `-` and `.`, not starting with `.` (no `..`, no hidden files), at most 128 bytes.
fn safe_mesh_part(p: &str) -> bool {
    !p.is_empty()
        && p.len() <= 128
        && !p.starts_with('.')
        && p.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
}

/// A mesh file or a file a mesh refers to: OBJ (with its MTL), STL, COLLADA, and the PNG/JPEG
/// textures a COLLADA or MTL file may name.
fn mesh_file_kind(file: &str) -> bool {
    let ext = file.rsplit_once('.').map(|(_, e)| e.to_ascii_lowercase());
    matches!(
        ext.as_deref(),
        Some("obj" | "mtl" | "stl" | "dae" | "png" | "jpg" | "jpeg")
    )
}

/// All of `r` when it has at most `limit` bytes, `None` when it has more (reading stops there).
fn read_bounded(r: &mut impl Read, limit: u64) -> std::io::Result<Option<Vec<u8>>> {
    let mut data = Vec::new();
    r.take(limit + 1).read_to_end(&mut data)?;
    Ok((data.len() as u64 <= limit).then_some(data))
}

/// One obstacle of a converted problem (VAMP's JSON form).
#[derive(Debug, Clone, Serialize)]
struct ObstacleOut {
    name: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    radius: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    half_extents: Option<[f64; 3]>,
    position: [f64; 3],
    orientation_euler_xyz: [f64; 3],
    orientation_quat_xyzw: [f64; 4],
}

#[derive(Debug, Clone, Default, Serialize)]
struct ProblemOut {
    sphere: Vec<ObstacleOut>,
    cylinder: Vec<ObstacleOut>,
    #[serde(rename = "box")]
    boxes: Vec<ObstacleOut>,
    index: usize,
    problem: String,
    start: Vec<f64>,
    goals: Vec<Vec<f64>>,
    valid: bool,
}

/// Problem sets in order of first appearance in the archive (a JSON map in that order).
struct Sets(Vec<(String, Vec<ProblemOut>)>);

impl Serialize for Sets {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

#[derive(Serialize)]
struct FileOut<'a> {
    robot: &'a str,
    joints: &'a [&'a str],
    problems: Sets,
}

/// A YAML value that does not fit, with the path to it.
struct Bad(String);

impl fmt::Display for Bad {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(&self.0)
    }
}

fn num(y: &Yaml, what: &str) -> Result<f64, Bad> {
    match y {
        Yaml::Real(_) => y.as_f64(),
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
    .filter(|v| v.is_finite())
    .ok_or_else(|| Bad(format!("{what}: not a finite number")))
}

fn nums(y: &Yaml, what: &str) -> Result<Vec<f64>, Bad> {
    y.as_vec()
        .ok_or_else(|| Bad(format!("{what}: not a list")))?
        .iter()
        .enumerate()
        .map(|(i, v)| num(v, &format!("{what}[{i}]")))
        .collect()
}

fn fixed<const N: usize>(y: &Yaml, what: &str) -> Result<[f64; N], Bad> {
    let v = nums(y, what)?;
    v.try_into()
        .map_err(|v: Vec<f64>| Bad(format!("{what}: {} values, expected {N}", v.len())))
}

/// A MoveIt pose `{position: [x, y, z], orientation: [x, y, z, w]}`.
fn yaml_pose(y: &Yaml, what: &str) -> Result<Isometry3<f64>, Bad> {
    let p: [f64; 3] = fixed(&y["position"], &format!("{what}.position"))?;
    let q: [f64; 4] = fixed(&y["orientation"], &format!("{what}.orientation"))?;
    let q = Quaternion::new(q[3], q[0], q[1], q[2]);
    if q.norm() < 1e-9 {
        return Err(Bad(format!("{what}.orientation: not a rotation")));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(p[0], p[1], p[2]),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// The obstacles of a MoveIt scene YAML: `(kind, obstacle)` with kind sphere, cylinder or box.
fn scene_obstacles(doc: &Yaml) -> Result<Vec<(String, ObstacleOut)>, Bad> {
    let objects = doc["world"]["collision_objects"]
        .as_vec()
        .ok_or_else(|| Bad("world.collision_objects: not a list".into()))?;
    let mut out = Vec::with_capacity(objects.len());
    for (k, co) in objects.iter().enumerate() {
        let at = format!("world.collision_objects[{k}]");
        let name = co["id"]
            .as_str()
            .ok_or_else(|| Bad(format!("{at}.id: not a string")))?
            .to_string();
        let base = match &co["pose"] {
            Yaml::BadValue | Yaml::Null => Isometry3::identity(),
            p => yaml_pose(p, &format!("{at}.pose"))?,
        };
        let prim = &co["primitives"][0];
        let pose = base
            * yaml_pose(
                &co["primitive_poses"][0],
                &format!("{at}.primitive_poses[0]"),
            )?;
        let kind = prim["type"]
            .as_str()
            .ok_or_else(|| Bad(format!("{at}.primitives[0].type: not a string")))?
            .to_string();
        let dims = nums(
            &prim["dimensions"],
            &format!("{at}.primitives[0].dimensions"),
        )?;
        let need = |n: usize| {
            if dims.len() < n {
                Err(Bad(format!("{at}: a {kind} needs {n} dimensions")))
            } else {
                Ok(())
            }
        };
        let (mut radius, mut length, mut half_extents) = (None, None, None);
        match kind.as_str() {
            "sphere" => {
                need(1)?;
                radius = Some(dims[0]);
            }
            "cylinder" => {
                need(2)?;
                length = Some(dims[0]);
                radius = Some(dims[1]);
            }
            "box" => {
                need(3)?;
                half_extents = Some([dims[0] / 2.0, dims[1] / 2.0, dims[2] / 2.0]);
            }
            other => return Err(Bad(format!("{at}: primitive type '{other}' not supported"))),
        }
        let t = pose.translation.vector;
        let q = pose.rotation;
        let (roll, pitch, yaw) = q.euler_angles();
        out.push((
            kind,
            ObstacleOut {
                name,
                radius,
                length,
                half_extents,
                position: [t.x, t.y, t.z],
                orientation_euler_xyz: [roll, pitch, yaw],
                orientation_quat_xyzw: [q.i, q.j, q.k, q.w],
            },
        ));
    }
    Ok(out)
}

/// Start and goal of a MoveIt motion-plan request YAML, in the order of `joints`.
fn request_configs(doc: &Yaml, joints: &[&str]) -> Result<(Vec<f64>, Vec<f64>), Bad> {
    let js = &doc["start_state"]["joint_state"];
    let names = js["name"]
        .as_vec()
        .ok_or_else(|| Bad("start_state.joint_state.name: not a list".into()))?;
    let pos = nums(&js["position"], "start_state.joint_state.position")?;
    let start = joints
        .iter()
        .map(|j| {
            names
                .iter()
                .position(|n| n.as_str() == Some(j))
                .and_then(|i| pos.get(i).copied())
                .ok_or_else(|| Bad(format!("start state: no joint {j}")))
        })
        .collect::<Result<Vec<f64>, Bad>>()?;
    let cons = doc["goal_constraints"][0]["joint_constraints"]
        .as_vec()
        .ok_or_else(|| Bad("goal_constraints[0].joint_constraints: not a list".into()))?;
    let goal = joints
        .iter()
        .map(|j| {
            let c = cons
                .iter()
                .find(|c| c["joint_name"].as_str() == Some(j))
                .ok_or_else(|| Bad(format!("goal: no joint constraint on {j}")))?;
            num(&c["position"], &format!("goal {j}"))
        })
        .collect::<Result<Vec<f64>, Bad>>()?;
    Ok((start, goal))
}

/// Converts a `problems.tar.bz2` of MoveIt YAML files (`problems/SET_ROBOT/sceneNNNN.yaml`,
/// `requestNNNN.yaml`) into the text of a `problems.json`: sets in order of their first scene
/// file in the archive (set names without `_ROBOT`), problems by index, `valid` when the start and at least one
/// goal are collision-free for `model` (its sphere model when it has one).
pub fn convert_problems(
    archive: &[u8],
    robot: &str,
    joints: &[&str],
    model: &Arc<Robot>,
    progress: &mut dyn FetchProgress,
) -> Result<String, FetchError> {
    let bad = |member: &str, reason: String| FetchError::Convert {
        robot: robot.to_string(),
        member: member.to_string(),
        reason,
    };
    let mut order: Vec<String> = Vec::new();
    type Parts = (
        Option<Vec<(String, ObstacleOut)>>,
        Option<(Vec<f64>, Vec<f64>)>,
    );
    let mut sets: BTreeMap<String, BTreeMap<usize, Parts>> = BTreeMap::new();
    progress.stage(&format!("convert {robot} problems"), None);
    let mut tar = tar::Archive::new(bzip2::read::BzDecoder::new(archive));
    let entries = tar
        .entries()
        .map_err(|e| bad("problems.tar.bz2", format!("not a .tar.bz2: {e}")))?;
    for entry in entries {
        let mut entry =
            entry.map_err(|e| bad("problems.tar.bz2", format!("not a .tar.bz2: {e}")))?;
        if !entry.header().entry_type().is_file() {
            continue;
        }
        let member = entry
            .path()
            .map_err(|e| bad("problems.tar.bz2", e.to_string()))?
            .display()
            .to_string();
        let parts: Vec<&str> = member.split('/').collect();
        let [_, dir, file] = parts.as_slice() else {
            return Err(bad(&member, "expected problems/SET/FILE.yaml".into()));
        };
        let set = dir.replace(&format!("_{robot}"), "");
        let digits: String = file
            .chars()
            .skip_while(|c| !c.is_ascii_digit())
            .take_while(char::is_ascii_digit)
            .collect();
        let index: usize = digits
            .parse()
            .map_err(|_| bad(&member, "no problem number in the file name".into()))?;
        let mut text = String::new();
        entry
            .read_to_string(&mut text)
            .map_err(|e| bad(&member, e.to_string()))?;
        let docs = YamlLoader::load_from_str(&text).map_err(|e| bad(&member, e.to_string()))?;
        let doc = docs
            .first()
            .ok_or_else(|| bad(&member, "empty YAML".into()))?;
        // VAMP's script orders the sets by their first scene file.
        if file.contains("scene") && !order.contains(&set) {
            order.push(set.clone());
        }
        let slot = sets.entry(set).or_default().entry(index).or_default();
        if file.contains("scene") {
            slot.0 = Some(scene_obstacles(doc).map_err(|e| bad(&member, e.0))?);
        } else if file.contains("request") {
            slot.1 = Some(request_configs(doc, joints).map_err(|e| bad(&member, e.0))?);
        } else {
            return Err(bad(&member, "neither a scene nor a request".into()));
        }
        progress.advance(1);
    }
    for set in sets.keys() {
        if !order.contains(set) {
            order.push(set.clone());
        }
    }
    if order.is_empty() {
        return Err(bad("problems.tar.bz2", "no problems".into()));
    }
    let total: usize = sets.values().map(BTreeMap::len).sum();
    progress.stage(
        &format!("check {robot} starts and goals"),
        Some(total as u64),
    );
    let mut out = Vec::with_capacity(order.len());
    for set in order {
        let mut problems = Vec::new();
        for (index, (scene, request)) in sets.remove(&set).unwrap_or_default() {
            let member = format!("{set}[{index}]");
            let scene = scene.ok_or_else(|| bad(&member, "request without a scene".into()))?;
            let (start, goal) =
                request.ok_or_else(|| bad(&member, "scene without a request".into()))?;
            let mut p = ProblemOut {
                index,
                problem: set.clone(),
                start,
                goals: vec![goal],
                ..ProblemOut::default()
            };
            for (kind, o) in scene {
                match kind.as_str() {
                    "sphere" => p.sphere.push(o),
                    "cylinder" => p.cylinder.push(o),
                    _ => p.boxes.push(o),
                }
            }
            p.valid = problem_valid(&p, joints, model).map_err(|e| bad(&member, e))?;
            problems.push(p);
            progress.advance(1);
        }
        out.push((set, problems));
    }
    let file = FileOut {
        robot,
        joints,
        problems: Sets(out),
    };
    serde_json::to_string(&file).map_err(|e| bad("problems.json", e.to_string()))
}

/// Start and at least one goal collision-free (robot at the identity base among the obstacles).
fn problem_valid(p: &ProblemOut, joints: &[&str], model: &Arc<Robot>) -> Result<bool, String> {
    let text = serde_json::to_string(&FileOut {
        robot: &model.name,
        joints,
        problems: Sets(vec![(p.problem.clone(), vec![p.clone()])]),
    })
    .map_err(|e| e.to_string())?;
    let file = MbmFile::parse(&text, "converted problem").map_err(|e| e.to_string())?;
    let vars = file.joint_vars(model).map_err(|e| e.to_string())?;
    let q = &file.sets[0].problems[0];
    let world = q.world(model.clone());
    let space = q.space(&world, &vars).map_err(|e| e.to_string())?;
    let mut checker = AutoChecker::new(&world, 0.0);
    let mut wq = space.base().to_vec();
    let mut free = |c: &[f64]| {
        space.write_world(c, &mut wq);
        checker.is_free(&wq)
    };
    Ok(free(&q.start) && q.goals.iter().any(|g| free(g)))
}
