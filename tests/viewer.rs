//! The 3-D viewer (`/viewer`) in a real browser: a kitchen-task plan opened headless in
//! Chromium loads without console errors, its canvas shows the robot, and a picture later in the
//! plan differs from the first; the pick-and-place statuette in the hand at mid-carry; the page
//! without WebGL; and the four-Panda `schedule` job with the Panda's visual meshes, its phase
//! panel and the collision-geometry view.
//!
//! Needs Chromium (`chromium`, or `MANYHANDS_CHROMIUM`) and a binary built with the viewer's
//! bundle (npm at build time). Without them the test says SKIPPED, unless
//! `MANYHANDS_REQUIRE_BROWSER=1` (set by `.ci/run`, which installs Chromium), where it fails.
//! The four-Panda test also READS THE MOTIONBENCHMAKER DATA (the benchmark Panda, its visual
//! meshes included: `manyhands data mbm`, or `../shared/benchmarks/mbm`); without it it says
//! SKIPPED, unless `MANYHANDS_REQUIRE_MBM` is set.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::json;

fn require() -> bool {
    std::env::var("MANYHANDS_REQUIRE_BROWSER").is_ok_and(|v| v == "1")
}

fn skip(why: &str) {
    assert!(!require(), "MANYHANDS_REQUIRE_BROWSER=1 but {why}");
    manyhands::skips::report(&format!("viewer test: {why}"));
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
            // (A generous time limit: the viewer tests run side by side with browsers.)
            &json!({"kind": "kitchen_task", "scene": "kitchen", "seed": 1, "time_limit": 60}),
        )
        .await;
    assert!(status.is_success(), "{status}: {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let id = job["id"].as_str().expect("job id").to_string();

    let dir = common::tmp::TestDir::new("viewer");
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
                    "seed": 2, "s_min": 0.1, "deterministic": true, "time_limit": 60}),
        )
        .await;
    assert!(status.is_success(), "{status}: {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let id = job["id"].as_str().expect("job id").to_string();
    let bin = chromium().expect("chromium");
    let base = h.base.clone();
    let mr = common::tmp::TestDir::new("viewer-mr");
    let profile = mr.to_path_buf();
    let dom = tokio::task::spawn_blocking(move || {
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

    // A robot whose visual mesh cannot be loaded (its uploaded mesh is missing): its other
    // visual is drawn, that link is drawn with its collision geometry, and the page says so.
    let urdf = std::fs::read_to_string(common::root().join("tests/robots/arm6.urdf"))
        .expect("arm6")
        .replacen(
            "<link name=\"pedestal\">",
            "<link name=\"pedestal\"><visual><origin xyz=\"0 0 -0.15\"/>\
             <geometry><box size=\"0.2 0.2 0.3\"/></geometry></visual>",
            1,
        )
        .replacen(
            "<link name=\"base\">",
            "<link name=\"base\"><visual><geometry><mesh filename=\"meshes/absent.stl\"/>\
             </geometry></visual>",
            1,
        );
    let scene = json!({"name": "visual_fallback", "robots": [{"name": "arm", "model": "arm6v"}],
        "obstacles": [], "objects": []});
    for (path, body) in [
        ("/v1/robots/arm6v", json!({"urdf": urdf})),
        ("/v1/scenes/visual_fallback", scene),
    ] {
        let r = h
            .http
            .put(format!("{}{path}", h.base))
            .json(&body)
            .send()
            .await
            .expect("PUT");
        assert!(r.status().is_success(), "{path}: {}", r.status());
    }
    let bin = chromium().expect("chromium");
    let base = h.base.clone();
    let fb = common::tmp::TestDir::new("viewer-fallback");
    let profile = fb.to_path_buf();
    let dom = tokio::task::spawn_blocking(move || {
        browse(
            &bin,
            &profile,
            &format!("{base}/viewer?scene=visual_fallback"),
            &["--dump-dom".into()],
        )
    })
    .await
    .expect("browser task");
    assert_ready(&dom, "visual fallback");
    let p = probe(&dom);
    assert_eq!(p["visuals"], json!({"drawn": 1, "failed": 1}), "{p}");
    let status = element_text(&dom, "status").unwrap_or("");
    assert!(
        status.contains(
            "1 visual geometries not drawn, their links drawn with their collision geometry"
        ) && status.contains("absent.stl"),
        "{status}"
    );
    h.server.shutdown().await.expect("shutdown");
}

/// The `#probe` JSON of a dumped page: where objects and hands are on the canvas.
fn probe(dom: &str) -> serde_json::Value {
    let text = element_text(dom, "probe").unwrap_or("");
    serde_json::from_str(text).unwrap_or_else(|e| panic!("probe {text:?}: {e}"))
}

/// The dumped DOM and a screenshot of `url`, in a fresh browser profile under `dir`.
fn dom_and_shot(
    bin: &Path,
    dir: &Path,
    url: &str,
    extra: &[String],
) -> (String, (Vec<[u8; 3]>, usize)) {
    std::fs::create_dir_all(dir).expect("shot dir");
    let profile = dir.join("profile");
    let mut args = extra.to_vec();
    args.push("--dump-dom".into());
    let dom = browse(bin, &profile, url, &args);
    let file = dir.join("shot.png");
    let mut args = extra.to_vec();
    args.push(format!("--screenshot={}", file.display()));
    browse(bin, &profile, url, &args);
    (dom, read_png(&file))
}

fn assert_ready(dom: &str, what: &str) {
    assert!(
        dom.contains("<title>manyhands viewer: ready</title>"),
        "{what}: the page did not get ready: status {:?}, errors {:?}",
        element_text(dom, "status"),
        element_text(dom, "errors")
    );
    assert_eq!(
        element_text(dom, "errors").map(str::trim),
        Some(""),
        "{what}: console errors on the page"
    );
}

/// Pixels of the scene's object colour (orange, shaded): red well over green over blue.
fn orange(p: &[u8; 3]) -> bool {
    let [r, g, b] = p.map(i32::from);
    r > g + 35 && g > b + 35 && r > 120
}

/// Pixels within `radius` of `at` (x, y) in an image `w` wide that pass `pick`.
fn count_near(
    px: &[[u8; 3]],
    w: usize,
    at: (f64, f64),
    radius: f64,
    pick: impl Fn(&[u8; 3]) -> bool,
) -> usize {
    px.iter()
        .enumerate()
        .filter(|(i, p)| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            (x - at.0).hypot(y - at.1) <= radius && pick(p)
        })
        .count()
}

fn point(v: &serde_json::Value) -> (f64, f64) {
    (
        v[0].as_f64().expect("probe x"),
        v[1].as_f64().expect("probe y"),
    )
}

/// Height of the 3-D canvas on a screenshot: the rows above the control bar's top border (a
/// row of #ccccdd).
fn canvas_rows(px: &[[u8; 3]], w: usize) -> usize {
    let rows = px.len() / w;
    (0..rows)
        .find(|&y| {
            let row = &px[y * w..(y + 1) * w];
            let border = row
                .iter()
                .filter(|p| {
                    p[0].abs_diff(0xcc) < 4 && p[1].abs_diff(0xcc) < 4 && p[2].abs_diff(0xdd) < 4
                })
                .count();
            border * 10 > w * 9
        })
        .unwrap_or(rows)
}

/// A `#probe` point of a page dumped at another viewport height (Chromium's `--dump-dom` window
/// is shorter than its `--screenshot` one) on a screenshot whose canvas is `w` × `h`: the
/// camera keeps its vertical field of view, so offsets from the centre scale with the height.
fn on_shot(p: &serde_json::Value, at: (f64, f64), w: usize, h: usize) -> (f64, f64) {
    let (wd, hd) = (
        p["canvas"][0].as_f64().expect("probe width"),
        p["canvas"][1].as_f64().expect("probe height"),
    );
    let k = h as f64 / hd;
    (
        w as f64 / 2.0 + (at.0 - wd / 2.0) * k,
        h as f64 / 2.0 + (at.1 - hd / 2.0) * k,
    )
}

/// The pick-and-place plan: the statuette (a mesh object) is drawn on the desk at the start and
/// in the right hand half-way through its carry (between the pick and the hand-over), checked by
/// its colour around the hand's place on the screenshot.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pick_and_place_shows_the_statuette_in_the_hand() {
    let Some(bin) = chromium() else {
        return skip("no chromium on PATH (MANYHANDS_CHROMIUM names one)");
    };
    if !manyhands::server::viewer::built() {
        return skip("this build has no viewer bundle (npm was missing when it was compiled)");
    }
    let h = common::server::start("viewer-pp").await;
    // The scene's mesh as the viewer reads it: OBJ text of the loaded statuette.
    let r = h
        .http
        .get(format!(
            "{}/v1/scenes/pick_place/meshes/objects/0/0",
            h.base
        ))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), 200);
    let obj = r.text().await.expect("text");
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 1312);
    for bad in ["obstacles/0/0", "objects/0/9", "objects/x/0", "walls/0/0"] {
        let r = h
            .http
            .get(format!("{}/v1/scenes/pick_place/meshes/{bad}", h.base))
            .send()
            .await
            .expect("GET");
        assert_eq!(r.status(), 404, "{bad}");
    }

    let (status, job) = h
        .post(
            "/v1/plans?wait=120",
            &json!({"kind": "pick_place", "scene": "pick_place", "robot": "justin",
                    "object": "statuette", "pick_hand": "right_hand", "place_hand": "left_hand",
                    "seed": 1, "time_limit": 60}),
        )
        .await;
    assert!(status.is_success(), "{status}: {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let id = job["id"].as_str().expect("job id").to_string();
    let r = &job["result"];
    let events = r["trajectory"]["events"]
        .as_array()
        .or(r["events"].as_array())
        .expect("events");
    let time = |e: &serde_json::Value| {
        e["time_from_start"]
            .as_f64()
            .or(e["time"].as_f64())
            .expect("event time")
    };
    let (t_pick, t_next) = (time(&events[0]), time(&events[1]));
    assert!(t_next > t_pick, "{events:?}");
    let mid = 0.5 * (t_pick + t_next);

    let dir = common::tmp::TestDir::new("viewer-pp");
    let base = h.base.clone();
    let dir2 = dir.to_path_buf();
    let (start, carry) = tokio::task::spawn_blocking(move || {
        let url = |t: f64| format!("{base}/viewer?plan={id}&t={t}");
        (
            dom_and_shot(&bin, &dir2.join("start"), &url(0.0), &[]),
            dom_and_shot(&bin, &dir2.join("carry"), &url(mid), &[]),
        )
    })
    .await
    .expect("browser task");
    for (what, (dom, _)) in [("start", &start), ("mid-carry", &carry)] {
        assert_ready(dom, what);
        let status = element_text(dom, "status").unwrap_or("");
        assert!(!status.contains("not drawn"), "{what}: {status}");
    }
    let (dom, (px, w)) = &carry;
    let p = probe(dom);
    eprintln!(
        "probe at mid-carry: {p}; screenshot {} x {}",
        w,
        px.len() / w
    );
    let h_canvas = canvas_rows(px, *w);
    let hand = on_shot(&p, point(&p["hands"]["justin/right_hand"]), *w, h_canvas);
    let object = on_shot(&p, point(&p["objects"]["statuette"]), *w, h_canvas);
    let total = px.iter().filter(|q| orange(q)).count();
    let near = count_near(px, *w, object, 60.0, orange);
    eprintln!(
        "mid-carry (t = {mid:.2} s): {total} statuette pixels, {near} around its place {object:?}; hand at {hand:?}"
    );
    assert!(
        total > 150,
        "the statuette is not visible at mid-carry ({total} pixels)"
    );
    assert!(
        near * 10 > total * 8,
        "the statuette's pixels are not where it is ({near} of {total})"
    );
    // In the hand: the object is drawn next to the hand's link.
    assert!(
        (object.0 - hand.0).hypot(object.1 - hand.1) < 80.0,
        "statuette at {object:?}, right hand at {hand:?}"
    );
    let (sdom, (spx, sw)) = &start;
    let sp = probe(sdom);
    let s_object = on_shot(
        &sp,
        point(&sp["objects"]["statuette"]),
        *sw,
        canvas_rows(spx, *sw),
    );
    let s_near = count_near(spx, *sw, s_object, 60.0, orange);
    assert!(
        s_near > 150,
        "the statuette is not drawn on the desk at the start ({s_near})"
    );
    assert!(
        (s_object.0 - object.0).hypot(s_object.1 - object.1) > 20.0,
        "the statuette did not move: {s_object:?} → {object:?}"
    );
    h.server.shutdown().await.expect("shutdown");
}

/// Without WebGL the page says so (and does not stay at "loading…").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_webgl_the_page_says_so() {
    let Some(bin) = chromium() else {
        return skip("no chromium on PATH (MANYHANDS_CHROMIUM names one)");
    };
    if !manyhands::server::viewer::built() {
        return skip("this build has no viewer bundle (npm was missing when it was compiled)");
    }
    let h = common::server::start("viewer-nogl").await;
    let base = h.base.clone();
    let dir = common::tmp::TestDir::new("viewer-nogl");
    let dir2 = dir.to_path_buf();
    let dom = tokio::task::spawn_blocking(move || {
        browse(
            &bin,
            &dir2.join("profile"),
            &format!("{base}/viewer?scene=kitchen"),
            &[
                "--disable-3d-apis".into(),
                "--disable-webgl".into(),
                "--dump-dom".into(),
            ],
        )
    })
    .await
    .expect("browser task");
    assert!(
        dom.contains("<title>manyhands viewer: no WebGL</title>"),
        "status {:?}",
        element_text(&dom, "status")
    );
    let status = element_text(&dom, "status").unwrap_or("");
    assert!(status.contains("WebGL is not available"), "{status}");
    h.server.shutdown().await.expect("shutdown");
}

/// A robots folder holding the shipped robots and the benchmark Panda as `panda`, its URDF's
/// visual meshes (`meshes/`) beside it, as links to the files.
fn robots_with_panda(dir: &Path, data: &Path) -> PathBuf {
    let robots = dir.join("robots");
    std::fs::create_dir_all(&robots).expect("robots dir");
    for e in std::fs::read_dir(common::root().join("robots")).expect("shipped robots") {
        let e = e.expect("entry");
        let src = e.path().canonicalize().expect("shipped robot file");
        std::os::unix::fs::symlink(src, robots.join(e.file_name())).expect("link");
    }
    let f = manyhands::benchmark::mbm_data::robot_files(data, "panda");
    let from = f.urdf.parent().expect("panda folder");
    for (src, dst) in [
        (f.urdf.clone(), "panda.urdf"),
        (f.srdf.clone(), "panda.srdf"),
        (from.join("meshes"), "meshes"),
    ] {
        let src = src.canonicalize().expect("benchmark Panda file");
        std::os::unix::fs::symlink(&src, robots.join(dst)).expect("link");
    }
    robots
}

/// The four-Panda cell's `schedule` job — READS THE MOTIONBENCHMAKER DATA (`manyhands data
/// mbm`, or `../shared/benchmarks/mbm`; skipped without it, required by
/// `MANYHANDS_REQUIRE_MBM`): the server loads the benchmark Panda as a built-in robot with its
/// URDF's visual meshes beside it. The page draws the four arms with their visual meshes (every
/// one loaded, in the arm's colour around each hand) and the phase-space panel (one pair of
/// robots chosen from the six), checked by the path's green in the panel's corner; with
/// `geometry=collision` it draws the arms' collision spheres instead (a different picture).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn panda_four_schedule_shows_visual_meshes_and_its_phase_panel() {
    let Some(bin) = chromium() else {
        return skip("no chromium on PATH (MANYHANDS_CHROMIUM names one)");
    };
    if !manyhands::server::viewer::built() {
        return skip("this build has no viewer bundle (npm was missing when it was compiled)");
    }
    let Some(data) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    let meshes = manyhands::benchmark::mbm_data::robot_files(&data, "panda")
        .urdf
        .with_file_name("meshes");
    if !meshes.is_dir() {
        let why = format!(
            "the MotionBenchMaker data has no Panda visual meshes ({} is missing; \
             `manyhands data mbm` leaves them out, ../shared/benchmarks/mbm has them)",
            meshes.display()
        );
        assert!(
            !manyhands::benchmark::mbm_data::data_required(),
            "MANYHANDS_REQUIRE_MBM is set but {why}"
        );
        return manyhands::skips::report(&format!("viewer test: {why}"));
    }
    let dir = common::tmp::TestDir::new("viewer-panda");
    let robots = robots_with_panda(&dir, &data);
    let h = common::server::start_with_robots("viewer-panda", &robots).await;
    let r = h
        .http
        .put(format!("{}/v1/scenes/panda_four", h.base))
        .json(&serde_json::to_value(manyhands::model::panda_four("panda")).expect("json"))
        .send()
        .await
        .expect("PUT");
    assert!(r.status().is_success(), "{}", r.status());

    // The Panda's visual geometry: eleven meshes, all on the server, served as OBJ text.
    let visuals: serde_json::Value = h
        .http
        .get(format!("{}/v1/robots/panda/visuals", h.base))
        .send()
        .await
        .expect("GET")
        .json()
        .await
        .expect("json");
    let list = visuals["visuals"].as_array().expect("visuals");
    assert_eq!(list.len(), 11, "{visuals}");
    assert!(
        list.iter()
            .all(|v| v["shape"]["type"] == "mesh" && v.get("problem").is_none()),
        "{visuals}"
    );
    let r = h
        .http
        .get(format!("{}/v1/robots/panda/visuals/panda_link1/0", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), 200);
    let obj = r.text().await.expect("text");
    let faces = obj.lines().filter(|l| l.starts_with("f ")).count();
    let verts = obj.lines().filter(|l| l.starts_with("v ")).count();
    assert_eq!(faces, 12516, "the file's triangles");
    assert!(verts < faces, "{verts} vertices for {faces} triangles");

    let scene = serde_json::to_value(manyhands::model::panda_four("panda")).expect("json");
    let mut trajectories = Vec::new();
    for r in scene["robots"].as_array().expect("robots") {
        let name = r["name"].as_str().expect("name");
        let req = json!({"kind": "joint_space", "scene": "panda_four", "seed": 2,
            "robots": [{"name": name, "goal": r["configs"]["goal"]}]});
        let (s, v) = h.post("/v1/plans?wait=60", &req).await;
        assert!(s.is_success() && v["state"] == "succeeded", "{s} {v}");
        trajectories.push(json!({"robot": name, "joints": v["result"]["joints"],
            "path": v["result"]["path"]}));
    }
    let (s, job) = h
        .post(
            "/v1/plans?wait=60",
            &json!({"kind": "schedule", "scene": "panda_four", "trajectories": trajectories}),
        )
        .await;
    assert!(s.is_success() && job["state"] == "succeeded", "{s} {job}");
    let id = job["id"].as_str().expect("id").to_string();
    let duration = job["result"]["duration"].as_f64().expect("duration");

    let base = h.base.clone();
    let dir2 = dir.to_path_buf();
    let ((dom, (px, w)), (cpx, _)) = tokio::task::spawn_blocking(move || {
        let url = format!("{base}/viewer?plan={id}&t={}", 0.5 * duration);
        let visual = dom_and_shot(&bin, &dir2.join("visual"), &url, &[]);
        let cdir = dir2.join("collision");
        std::fs::create_dir_all(&cdir).expect("dir");
        let file = cdir.join("shot.png");
        browse(
            &bin,
            &cdir.join("profile"),
            &format!("{url}&geometry=collision"),
            &[format!("--screenshot={}", file.display())],
        );
        (visual, read_png(&file))
    })
    .await
    .expect("browser task");
    assert_ready(&dom, "panda_four schedule");
    let status = element_text(&dom, "status").unwrap_or("");
    assert!(!status.contains("not drawn"), "{status}");
    let p = probe(&dom);
    eprintln!("probe: {p}");
    assert_eq!(p["geometry"], "visual", "{p}");
    assert_eq!(
        p["visuals"]["drawn"], 44,
        "four arms of eleven visual meshes: {p}"
    );
    assert_eq!(p["visuals"]["failed"], 0, "{p}");
    let toggle = dom
        .find("id=\"geometry-box\"")
        .map(|i| &dom[i..i + dom[i..].find('>').unwrap_or(0)])
        .unwrap_or("");
    assert!(
        !toggle.is_empty() && !toggle.contains(" hidden"),
        "no geometry toggle for robots with visual geometry: {toggle:?}"
    );
    assert!(
        !dom.contains("<canvas id=\"phase\" hidden"),
        "the phase-space panel is hidden for a schedule job"
    );
    assert!(
        !dom.contains(
            "<select id=\"phase-pair\" title=\"robot pair of the phase-space panel\" hidden"
        ),
        "no robot-pair choice for four robots"
    );
    // The panel (220 px square under the pair choice) in the top right corner.
    let in_panel = |i: usize| i % w + 250 >= w && i / w < 280;
    let path_green = |p: &[u8; 3]| {
        let [r, g, b] = p.map(i32::from);
        (r - 0x1a).abs() < 30 && (g - 0x9a).abs() < 30 && (b - 0x3a).abs() < 30 && g > r + 80
    };
    let green = px
        .iter()
        .enumerate()
        .filter(|(i, p)| in_panel(*i) && path_green(p))
        .count();
    let red = px
        .iter()
        .enumerate()
        .filter(|(i, p)| in_panel(*i) && p[0] > 180 && p[1] < 70 && p[2] < 70)
        .count();
    eprintln!("phase panel: {green} path pixels, {red} marker pixels");
    assert!(green > 150, "no phase path in the panel ({green} pixels)");
    assert!(
        red > 10,
        "no current-phase marker in the panel ({red} pixels)"
    );
    // Each arm is drawn in its palette colour (blue, green, purple, red: the four scene
    // robots) around its hand: the hand's visual mesh and the wrist's.
    let h_canvas = canvas_rows(&px, w);
    let palette: [fn(&[u8; 3]) -> bool; 4] = [
        |p| p[2] as i32 > p[0] as i32 + 40 && p[2] as i32 > p[1] as i32 + 15,
        |p| p[1] as i32 > p[0] as i32 + 30 && p[1] as i32 > p[2] as i32 + 20,
        |p| p[0] as i32 > p[1] as i32 + 30 && p[2] as i32 > p[1] as i32 + 30,
        |p| p[0] as i32 > p[1] as i32 + 50 && p[0] as i32 > p[2] as i32 + 50,
    ];
    let names: Vec<String> = scene["robots"]
        .as_array()
        .expect("robots")
        .iter()
        .map(|r| r["name"].as_str().expect("name").to_string())
        .collect();
    for (k, name) in names.iter().enumerate() {
        let at = on_shot(&p, point(&p["hands"][format!("{name}/hand")]), w, h_canvas);
        let n = count_near(&px[..w * h_canvas], w, at, 40.0, palette[k]);
        eprintln!("{name}: {n} pixels of its colour around its hand at {at:?}");
        assert!(
            n > 100,
            "{name}: its hand is not drawn at {at:?} ({n} pixels)"
        );
    }
    // The collision geometry instead: the same arms, drawn differently.
    let canvas = w * h_canvas;
    let arm = |q: &[u8; 3]| palette.iter().any(|f| f(q));
    let (va, ca) = (
        px[..canvas].iter().filter(|q| arm(q)).count(),
        cpx[..canvas].iter().filter(|q| arm(q)).count(),
    );
    let changed = px[..canvas]
        .iter()
        .zip(&cpx[..canvas])
        .enumerate()
        .filter(|(i, (a, b))| {
            !in_panel(*i) && a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 40)
        })
        .count();
    eprintln!("arm pixels: {va} visual, {ca} collision; {changed} pixels changed");
    assert!(
        ca * 2 > va,
        "the collision view barely draws the arms ({ca} vs {va})"
    );
    assert!(
        changed * 10 > va,
        "the collision geometry looks like the visual meshes ({changed} of {va} pixels changed)"
    );
    h.server.shutdown().await.expect("shutdown");
}
