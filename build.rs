//! Builds the 3-D plan viewer (`viewer/`: three.js + urdf-loader, bundled by esbuild) with npm
//! into `OUT_DIR`; `src/server/viewer.rs` embeds the bundle, and the daemon serves it at
//! `/viewer`. The bundle is never committed.
//!
//! The sources are copied to `OUT_DIR/viewer` and built there (`npm ci`, `npm run build`), so
//! the source tree stays clean. Without npm, or when the build fails (no registry), the binary is
//! built anyway: `viewer.js` is then empty and `/viewer` answers with a page that says why and how
//! to fix it (install Node.js ≥ 18 with npm, rebuild). `MANYHANDS_NPM` names another npm binary;
//! `MANYHANDS_REQUIRE_VIEWER=1` (the Dockerfile's build stage) makes a failed viewer build an error.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

fn copy_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    fs::create_dir_all(to)?;
    for entry in fs::read_dir(from)? {
        let entry = entry?;
        let target = to.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            copy_dir(&entry.path(), &target)?;
        } else {
            fs::copy(entry.path(), target)?;
        }
    }
    Ok(())
}

fn run(npm: &str, dir: &Path, args: &[&str]) -> Result<(), String> {
    let out = Command::new(npm)
        .args(args)
        .current_dir(dir)
        .output()
        .map_err(|e| {
            format!("could not run `{npm}` ({e}); install Node.js with npm and rebuild")
        })?;
    if out.status.success() {
        Ok(())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = err.lines().rev().take(6).collect();
        Err(format!(
            "`{npm} {}` failed ({}): {}",
            args.join(" "),
            out.status,
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        ))
    }
}

fn build(src: &Path, work: &Path) -> Result<String, String> {
    let npm = std::env::var("MANYHANDS_NPM").unwrap_or_else(|_| "npm".into());
    let io = |e: std::io::Error| format!("copying the viewer sources: {e}");
    fs::create_dir_all(work).map_err(io)?;
    let lock = fs::read(src.join("package-lock.json")).map_err(io)?;
    // `npm ci` only when the lock file changed since the last build in this OUT_DIR.
    let stamp = work.join("node_modules/.manyhands-lock");
    let fresh = fs::read(&stamp).map(|s| s == lock).unwrap_or(false);
    for f in ["package.json", "package-lock.json", "index.html"] {
        fs::copy(src.join(f), work.join(f)).map_err(io)?;
    }
    let _ = fs::remove_dir_all(work.join("src"));
    copy_dir(&src.join("src"), &work.join("src")).map_err(io)?;
    if !fresh {
        run(
            &npm,
            work,
            &["ci", "--no-audit", "--no-fund", "--loglevel=error"],
        )?;
        fs::write(&stamp, &lock).map_err(io)?;
    }
    run(&npm, work, &["run", "--silent", "build"])?;
    fs::read_to_string(work.join("dist/viewer.js")).map_err(|e| format!("reading the bundle: {e}"))
}

fn main() {
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    for f in ["package.json", "package-lock.json", "index.html", "src"] {
        println!("cargo:rerun-if-changed=viewer/{f}");
    }
    println!("cargo:rerun-if-env-changed=MANYHANDS_NPM");
    println!("cargo:rerun-if-env-changed=MANYHANDS_REQUIRE_VIEWER");
    let (js, why) = match build(Path::new("viewer"), &out.join("viewer")) {
        Ok(js) if !js.is_empty() => (js, String::new()),
        Ok(_) => (String::new(), "the bundle came out empty".to_string()),
        Err(why) => {
            println!("cargo:warning=the 3-D viewer (/viewer) was not built: {why}");
            (String::new(), why)
        }
    };
    if !why.is_empty() && std::env::var("MANYHANDS_REQUIRE_VIEWER").is_ok_and(|v| v == "1") {
        panic!("MANYHANDS_REQUIRE_VIEWER=1 but the 3-D viewer was not built: {why}");
    }
    fs::write(out.join("viewer.js"), js).expect("writing OUT_DIR/viewer.js");
    fs::write(out.join("viewer_status.txt"), why).expect("writing OUT_DIR/viewer_status.txt");
}
