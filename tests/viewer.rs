//! The 3-D viewer (`/viewer`, issue 25 item 3) in a real browser: a kitchen-task plan opened
//! headless in Chromium loads without console errors, its canvas shows the robot, and a picture
//! later in the plan differs from the first.
//!
//! Needs Chromium (`chromium`, or `MANYHANDS_CHROMIUM`) and a binary built with the viewer's
//! bundle (npm at build time). Without them the test says SKIPPED, unless
//! `MANYHANDS_REQUIRE_BROWSER=1` (set by `.ci/run`, which installs Chromium), where it fails.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::json;

fn require() -> bool {
    std::env::var("MANYHANDS_REQUIRE_BROWSER").is_ok_and(|v| v == "1")
}

fn skip(why: &str) {
    assert!(!require(), "MANYHANDS_REQUIRE_BROWSER=1 but {why}");
    eprintln!("SKIPPED (viewer test): {why}");
}

fn chromium() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("MANYHANDS_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    for dir in std::env::split_paths(&path) {
        for name in ["chromium", "chromium-browser", "google-chrome"] {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

/// Runs headless Chromium on `url` with `extra` (e.g. `--dump-dom`); its stdout.
fn browse(bin: &Path, profile: &Path, url: &str, extra: &[String]) -> String {
    let out = Command::new(bin)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-dev-shm-usage",
            "--enable-unsafe-swiftshader",
            "--use-angle=swiftshader",
            "--hide-scrollbars",
            "--window-size=900,600",
            // Virtual time runs until the page is idle (fetches done, frames drawn), up to 20 s.
            "--virtual-time-budget=20000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(extra)
        .arg(url)
        .output()
        .expect("run chromium");
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// RGB pixels (row-major) and width of a PNG file.
fn read_png(path: &Path) -> (Vec<[u8; 3]>, usize) {
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(path).expect("screenshot file"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("png size")];
    let info = reader.next_frame(&mut buf).expect("png frame");
    let channels = info.color_type.samples();
    assert!(channels >= 3, "screenshot is {:?}", info.color_type);
    let px = buf[..info.buffer_size()]
        .chunks(channels)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (px, info.width as usize)
}

/// Text content of the element with `id` in a dumped DOM (`None` if absent).
fn element_text<'a>(dom: &'a str, id: &str) -> Option<&'a str> {
    let start = dom.find(&format!("id=\"{id}\""))?;
    let open_end = start + dom[start..].find('>')? + 1;
    let close = open_end + dom[open_end..].find("</")?;
    Some(&dom[open_end..close])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kitchen_plan_in_a_headless_browser() {
    let Some(bin) = chromium() else {
        return skip("no chromium on PATH (MANYHANDS_CHROMIUM names one)");
    };
    if !manyhands::server::viewer::built() {
        return skip("this build has no viewer bundle (npm was missing when it was compiled)");
    }
    let h = common::server::start("viewer").await;

    // What the page is built from: the page, its script, a robot's URDF.
    for (path, ty) in [
        ("/viewer", "text/html"),
        ("/viewer/viewer.js", "text/javascript"),
        ("/v1/robots/armar/urdf", "application/xml"),
    ] {
        let r = h
            .http
            .get(format!("{}{path}", h.base))
            .send()
            .await
            .expect("GET");
        assert_eq!(r.status(), 200, "{path}");
        let ct = r.headers()["content-type"]
            .to_str()
            .unwrap_or("")
            .to_string();
        assert!(ct.starts_with(ty), "{path}: content-type {ct}");
    }
    let r = h
        .http
        .get(format!("{}/v1/robots/no_such_robot/urdf", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), 404);

    let (status, job) = h
        .post(
            "/v1/plans?wait=120",
            &json!({"kind": "kitchen_task", "scene": "kitchen", "seed": 1}),
        )
        .await;
    assert!(status.is_success(), "{status}: {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let id = job["id"].as_str().expect("job id").to_string();

    let dir = std::env::temp_dir().join(format!("manyhands-viewer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let base = h.base.clone();
    let shots = tokio::task::spawn_blocking(move || {
        let profile = dir.join("profile");
        let url = |t: &str| format!("{base}/viewer?plan={id}&t={t}");
        let dom = browse(&bin, &profile, &url("0"), &["--dump-dom".into()]);
        let mut shots = Vec::new();
        // The start, and late in the plan (a time past its end shows the end).
        for (k, t) in ["0", "1e6"].iter().enumerate() {
            let file = dir.join(format!("shot{k}.png"));
            browse(
                &bin,
                &profile,
                &url(t),
                &[format!("--screenshot={}", file.display())],
            );
            shots.push(read_png(&file));
        }
        (dom, shots)
    })
    .await
    .expect("browser task");
    let (dom, shots) = shots;

    assert!(
        dom.contains("<title>manyhands viewer: ready</title>"),
        "the page did not get ready: status {:?}, errors {:?}",
        element_text(&dom, "status"),
        element_text(&dom, "errors")
    );
    assert_eq!(
        element_text(&dom, "errors").map(str::trim),
        Some(""),
        "console errors on the page"
    );
    let status = element_text(&dom, "status").unwrap_or("");
    assert!(
        status.contains("kitchen_task in kitchen"),
        "status {status:?}"
    );

    // The 3-D canvas is the window above the control bar (about 60 px).
    let (a, w) = &shots[0];
    let (b, _) = &shots[1];
    assert_eq!(a.len(), b.len());
    let rows = a.len() / w;
    let canvas = w * (rows - 80);
    // The robot is drawn in the first palette colour (blue, shaded): pixels clearly blue.
    let blue = |p: &[u8; 3]| p[2] as i32 > p[0] as i32 + 40 && p[2] as i32 > p[1] as i32 + 15;
    for (k, px) in [a, b].iter().enumerate() {
        let n = px[..canvas].iter().filter(|p| blue(p)).count();
        eprintln!("screenshot {k}: {n} of {canvas} canvas pixels show the robot");
        assert!(
            n * 200 > canvas,
            "screenshot {k}: only {n} of {canvas} canvas pixels show the robot"
        );
        let background = px[..canvas]
            .iter()
            .filter(|p| p.iter().all(|&c| c >= 0xec))
            .count();
        assert!(background < canvas, "screenshot {k} is blank");
    }
    let changed = a[..canvas]
        .iter()
        .zip(&b[..canvas])
        .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > 30))
        .count();
    eprintln!("{changed} of {canvas} canvas pixels changed between the two screenshots");
    assert!(
        changed * 500 > canvas,
        "the picture late in the plan barely differs from the start ({changed} of {canvas} pixels)"
    );

    // A multi-robot plan: both robots on one clock and the phase-space panel shown.
    let (status, job) = h
        .post(
            "/v1/plans?wait=120",
            &json!({"kind": "multi_robot", "scene": "kitchen_two", "object": "table",
                    "seed": 2, "s_min": 0.1, "deterministic": true}),
        )
        .await;
    assert!(status.is_success(), "{status}: {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let id = job["id"].as_str().expect("job id").to_string();
    let bin = chromium().expect("chromium");
    let base = h.base.clone();
    let dom = tokio::task::spawn_blocking(move || {
        let profile =
            std::env::temp_dir().join(format!("manyhands-viewer-mr-{}", std::process::id()));
        browse(
            &bin,
            &profile,
            &format!("{base}/viewer?plan={id}&t=1"),
            &["--dump-dom".into()],
        )
    })
    .await
    .expect("browser task");
    assert!(
        dom.contains("<title>manyhands viewer: ready</title>"),
        "multi-robot page: status {:?}, errors {:?}",
        element_text(&dom, "status"),
        element_text(&dom, "errors")
    );
    assert_eq!(element_text(&dom, "errors").map(str::trim), Some(""));
    assert!(
        !dom.contains("<canvas id=\"phase\" hidden"),
        "the phase-space panel is hidden for a multi-robot plan"
    );
    h.server.shutdown().await.expect("shutdown");
}
