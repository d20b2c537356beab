//! The `manyhands` command on real inputs: robot show, fk, ik, check, scene random-boxes, plan.

mod common;

use std::process::Command;

use serde_json::Value;

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run manyhands");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn json(args: &[&str]) -> Value {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "{args:?}: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{args:?}: {e}: {out}"))
}

#[test]
fn robot_show_lists_dof_joints_groups_and_shapes() {
    let v = json(&["robot", "show", "armar", "--json"]);
    assert_eq!(v["dof"], 20);
    let groups: Vec<&str> = v["groups"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g["name"].as_str().unwrap())
        .collect();
    for g in [
        "left_arm",
        "right_arm",
        "hip",
        "base",
        "both_arms",
        "torso_left_arm",
        "torso_right_arm",
        "whole_body",
    ] {
        assert!(groups.contains(&g), "{g}");
    }
    let elbow = v["joints"]
        .as_array()
        .unwrap()
        .iter()
        .find(|j| j["name"] == "right_elbow")
        .unwrap();
    assert!(
        elbow["limits"]["lower"].as_f64().unwrap() < elbow["limits"]["upper"].as_f64().unwrap()
    );
    assert!(v["links"]
        .as_array()
        .unwrap()
        .iter()
        .any(|l| !l["collision"].as_array().unwrap().is_empty()));
    let (code, out, _) = run(&["robot", "show", "justin"]);
    assert_eq!(code, 0);
    assert!(out.contains("43 DoF"), "{out}");
    // An outside robot by path, its SRDF found beside it.
    let v = json(&["robot", "show", "tests/robots/twin_arms.urdf", "--json"]);
    assert_eq!(v["dof"], 14);
    assert!(v["groups"]
        .as_array()
        .unwrap()
        .iter()
        .any(|g| g["name"] == "both_arms"));
}

#[test]
fn fk_then_ik_returns_the_pose() {
    let fk = json(&[
        "fk",
        "armar",
        "--config",
        "right_shoulder_1=-1.0,right_elbow=-1.2,right_wrist_1=0.4",
        "--link",
        "right_tcp",
        "--json",
    ]);
    let p = &fk["links"][0]["pose"];
    let vals: Vec<String> = p["position"]
        .as_array()
        .unwrap()
        .iter()
        .chain(p["rpy"].as_array().unwrap())
        .map(|x| x.to_string())
        .collect();
    let pose = vals.join(",");
    for extra in [vec![], vec!["--numeric"]] {
        let mut args = vec!["ik", "armar", "--group", "right_arm", "--json"];
        let pose_arg = format!("--pose={pose}");
        args.push(&pose_arg);
        args.extend(extra.iter().copied());
        let ik = json(&args);
        let sols = ik["solutions"].as_array().unwrap();
        assert!(!sols.is_empty(), "{ik}");
        // Check the first solution by FK.
        let names = ik["joints"].as_array().unwrap();
        let cfg: Vec<String> = names
            .iter()
            .zip(sols[0].as_array().unwrap())
            .map(|(n, v)| format!("{}={}", n.as_str().unwrap(), v))
            .collect();
        let back = json(&[
            "fk",
            "armar",
            "--config",
            &cfg.join(","),
            "--link",
            "right_tcp",
            "--json",
        ]);
        let a = &back["links"][0]["pose"]["position"];
        for k in 0..3 {
            assert!(
                (a[k].as_f64().unwrap() - p["position"][k].as_f64().unwrap()).abs() < 1e-9,
                "{a} vs {}",
                p["position"]
            );
        }
    }
}

#[test]
fn ik_of_an_unreachable_pose_fails_cleanly() {
    let (code, _, err) = run(&["ik", "armar", "--group", "right_arm", "--pose=3,0,1,0,0,0"]);
    assert_eq!(code, 2);
    assert!(err.contains("no IK solution"), "{err}");
    let (code, _, err) = run(&["ik", "armar", "--group", "nope", "--pose=0,0,1,0,0,0"]);
    assert_eq!(code, 2);
    assert!(err.contains("--group"), "{err}");
}

#[test]
fn check_names_the_colliding_pair() {
    let v = json(&["check", "kitchen", "--json"]);
    assert_eq!(v["collision"], false);
    let v = json(&["check", "kitchen", "--config", "base_x=0.5", "--json"]);
    assert_eq!(v["collision"], true);
    let pair = v["pair"].as_array().unwrap();
    assert!(pair.iter().any(|p| p == "obstacle:counter"), "{v}");
    assert_eq!(v["fast_checker"]["collision"], true);
    let (code, _, err) = run(&["check", "kitchen", "--config", "right_elbow=4.2"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("right_elbow") && err.contains("outside limit"),
        "{err}"
    );
}

#[test]
fn random_boxes_scene_is_written_and_loads() {
    let path = common::tmp::run_root().join(format!("manyhands-boxes-{}.json", std::process::id()));
    let p = path.to_str().unwrap();
    let (code, _, err) = run(&[
        "scene",
        "random-boxes",
        "--base",
        "empty",
        "--boxes",
        "12",
        "--seed",
        "4",
        "--out",
        p,
    ]);
    assert_eq!(code, 0, "{err}");
    let v = json(&["check", p, "--json"]);
    assert_eq!(v["collision"], false);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.matches("box_").count() >= 12);
    let _ = std::fs::remove_file(&path);
}

/// `bench mbm --ompl-log` writes OMPL's benchmark log: the preamble, one planner, one line per
/// run with as many "; "-terminated fields as declared properties, solved runs marked correct;
/// `--out` writes every run with its returned path.
#[test]
fn bench_mbm_writes_an_ompl_benchmark_log() {
    let Some(data) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    let dir = common::tmp::run_root().join(format!("manyhands-ompl-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let log = dir.join("mbm.log");
    let urdf = data.join("panda/panda_spherized.urdf");
    let problems = data.join("panda/problems.json");
    let out_file = dir.join("mbm.json");
    let (code, out, err) = run(&[
        "bench",
        "mbm",
        "--robot",
        urdf.to_str().expect("utf-8 path"),
        "--problems",
        problems.to_str().expect("utf-8 path"),
        "--sets",
        "table_pick,box",
        "--limit",
        "2",
        "--ompl-log",
        log.to_str().expect("utf-8 path"),
        "--out",
        out_file.to_str().expect("utf-8 path"),
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out_file).expect("--out written"))
            .expect("JSON");
    let runs = report["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 4);
    for r in runs {
        let path = r["path"].as_array().expect("path");
        assert_eq!(r["solved"], true, "{r}");
        assert!(path.len() >= 2, "{r}");
        assert_eq!(path.len() as u64, r["vertices"].as_u64().expect("vertices"));
        assert!(path
            .iter()
            .all(|q| q.as_array().is_some_and(|q| q.len() == 7)));
    }
    let text = std::fs::read_to_string(&log).expect("log written");
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("manyhands version "));
    assert_eq!(lines[1], "Experiment mbm_panda");
    assert!(lines.contains(&"1 planners"));
    assert!(lines.contains(&"4 runs per planner"));
    let n_props = lines
        .iter()
        .find_map(|l| l.strip_suffix(" properties for each run"))
        .and_then(|n| n.parse::<usize>().ok())
        .expect("property count");
    let runs_at = lines
        .iter()
        .position(|l| *l == "4 runs")
        .expect("run count line");
    let props = &lines[runs_at - n_props..runs_at];
    assert_eq!(props[0], "problem set ENUM");
    let solved_col = props
        .iter()
        .position(|p| *p == "solved BOOLEAN")
        .expect("solved");
    let correct_col = props
        .iter()
        .position(|p| *p == "correct solution BOOLEAN")
        .expect("correct");
    for l in &lines[runs_at + 1..runs_at + 5] {
        let f: Vec<&str> = l.split("; ").collect();
        assert_eq!(f.len(), n_props + 1, "{l}");
        assert_eq!(f[n_props], "", "{l}");
        assert_eq!(f[solved_col], "1", "{l}");
        assert_eq!(f[correct_col], "1", "{l}");
        assert!(
            f[3].parse::<f64>().is_ok_and(|t| t > 0.0 && t < 10.0),
            "{l}"
        );
    }
    assert_eq!(lines[runs_at + 5], ".");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `bench mbm --suite generality`: every robot of benchmarks/generality/ (and the Panda with the
/// MotionBenchMaker data) planned certified and without the certificate on the same problems:
/// all solved, the certified paths all exactly valid, the work counts reported.
#[test]
fn bench_mbm_suite_plans_every_robot_certified_and_uncertified() {
    let v = json(&[
        "bench",
        "mbm",
        "--suite",
        "generality",
        "--limit",
        "1",
        "--json",
    ]);
    let robots = v["robots"].as_array().expect("robots");
    let names: Vec<&str> = robots.iter().filter_map(|r| r["robot"].as_str()).collect();
    for want in ["armar_arms", "fetchlike", "ur5like", "xarm7like"] {
        assert!(names.contains(&want), "{want} missing: {names:?}");
    }
    for r in robots {
        let n = r["problems"].as_u64().expect("problems");
        assert!(
            n >= 4,
            "{r}: one problem per set of box, cage, shelf, table at least"
        );
        assert_eq!(r["solved"].as_u64(), Some(n), "{r}");
        assert_eq!(r["invalid"].as_u64(), Some(0), "{r}");
        assert_eq!(
            r["uncertified_solved"]
                .as_u64()
                .map(|u| u + r["uncertified_invalid"].as_u64().unwrap_or(0)),
            Some(n),
            "{r}"
        );
        let per_iteration = r["checks_per_iteration"]
            .as_f64()
            .expect("checks/iteration");
        assert!(per_iteration > 0.0 && per_iteration.is_finite(), "{r}");
        assert!(
            r["refinements_per_check"]
                .as_f64()
                .is_some_and(|x| x >= 0.0),
            "{r}"
        );
        assert!(r["median_us"].as_f64().is_some_and(|t| t > 0.0), "{r}");
    }
    // The switch is the benchmark's alone: a robot not made of spheres is refused.
    let (code, _, err) = run(&[
        "bench",
        "mbm",
        "--robot",
        "tests/robots/arm6.urdf",
        "--problems",
        "benchmarks/generality/ur5like/problems.json",
        "--uncertified",
        "--certify",
        "0",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("--uncertified"), "{err}");
}

/// `bench mbm` re-checks every returned path exactly once the set's timed plans are done: the
/// same search without the certificate returns paths through obstacles, and the re-check (run
/// after the plans, against each run's own problem) counts them as invalid; the certified paths
/// of several trials per problem all pass it.
#[test]
fn bench_mbm_rechecks_every_path_after_the_timed_plans() {
    let base = [
        "bench",
        "mbm",
        "--robot",
        "benchmarks/generality/ur5like/ur5like_spherized.urdf",
        "--problems",
        "benchmarks/generality/ur5like/problems.json",
        "--no-simplify",
        "--limit",
        "3",
        "--json",
    ];
    let totals = |v: &serde_json::Value| {
        let o = &v["overall"];
        (
            o["solved"].as_u64().expect("solved"),
            o["invalid"].as_u64().expect("invalid"),
            o["runs"].as_u64().expect("runs"),
        )
    };
    let uncertified = json(&[&base[..], &["--uncertified"]].concat());
    let (solved, invalid, runs) = totals(&uncertified);
    assert_eq!(runs, 12, "{uncertified}");
    assert_eq!(solved + invalid, runs, "{uncertified}");
    assert!(
        invalid >= 1,
        "no path through an obstacle caught: {uncertified}"
    );
    let certified = json(&[&base[..], &["--trials", "2"]].concat());
    assert_eq!(totals(&certified), (24, 0, 24), "{certified}");
}

#[test]
fn query_runs_the_grasp_ik_endpoints_locally() {
    let dir = common::tmp::run_root().join(format!("manyhands-cli-query-{}", std::process::id()));
    let d = dir.to_string_lossy().to_string();
    // The dual-arm IK with the wok held: same body as POST /v1/ik/dual-arm, same answer shape.
    let body = r#"{"scene":"kitchen","robot":"armar","object":"wok","held":"wok_l_02","seed":3,
        "region":{"min":[0.3,-0.3,1.0],"max":[0.6,0.2,1.4]}}"#;
    let v = json(&["--json", "query", "ik-dual-arm", body, "--data-dir", &d]);
    assert_eq!(v["found"], true, "{v}");
    assert_eq!(v["left_grasp"], "wok_l_02", "{v}");
    assert_eq!(v["solution"].as_array().map(|s| s.len()), Some(17), "{v}");
    // The reachability grids were cached for the next run.
    assert!(dir.join("reach").read_dir().map(|d| d.count()).unwrap_or(0) >= 2);
    let again = json(&["--json", "query", "ik-dual-arm", body, "--data-dir", &d]);
    assert_eq!(
        again["solution"], v["solution"],
        "same body and seed, same answer"
    );
    // Bad values name their field; unknown fields are refused.
    let (code, _, err) = run(&[
        "query",
        "ik-grasp",
        r#"{"scene":"kitchen","robot":"armar","group":"torso_right_arm","object":"wok","psi_samples":0}"#,
        "--data-dir",
        &d,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("psi_samples"), "{err}");
    let (code, _, err) = run(&[
        "query",
        "ik-base-placement",
        r#"{"scene":"kitchen","robbot":1}"#,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("robbot"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `plan reach` and `plan regrasp` with the arm grid (built into a fresh folder on first use)
/// and without it: a plan with its grasp events either way.
#[test]
fn plan_reach_and_regrasp_with_and_without_the_arm_grid() {
    let dir = common::tmp::run_root().join(format!("manyhands-cli-grids-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let grid_dir = dir.to_string_lossy().into_owned();
    for (command, seed, extra) in [
        ("reach", "2", vec!["--grid-dir", &grid_dir]),
        ("reach", "2", vec!["--no-reachability"]),
        ("regrasp", "1", vec!["--grid-dir", &grid_dir]),
    ] {
        let mut args = vec!["plan", command, "--json", "--seed", seed];
        args.extend(extra);
        let v = json(&args);
        let waypoints = v["waypoints"].as_array().expect("waypoints");
        assert!(waypoints.len() >= 2, "{args:?}");
        let events = v["events"].as_array().expect("events");
        assert!(
            events.iter().any(|e| e["kind"] == "grasp"),
            "{args:?}: {events:?}"
        );
    }
    // The grids were built there: the right arm's for reach, the left arm's for the receiver.
    let built = std::fs::read_dir(&dir).expect("grid folder").count();
    assert!(built >= 2, "{built} grids in {grid_dir}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `plan regrasp --planner j-plus-rrt`: J+-RRT grasps the wok with the right hand and dual-arm
/// J+-RRT (000 Alg. 4–5) hands it to the left: grasp, grasp, release.
#[test]
fn plan_regrasp_with_dual_arm_j_plus_rrt() {
    common::assert_j_plus_regrasp_plan(&json(&[
        "plan",
        "regrasp",
        "--json",
        "--seed",
        "3",
        "--planner",
        "j-plus-rrt",
    ]));
}

/// `data mbm` refuses a package whose sha256 is not the published one (and leaves no folder),
/// and `bench mbm --robot panda` without any data folder says how to get one.
#[test]
fn data_mbm_checks_the_package_and_bench_mbm_names_the_fetch() {
    let dir = common::tmp::run_root().join(format!("manyhands-data-mbm-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("tmp dir");
    let fake = dir.join("vamp_planner-0.6.4.tar.gz");
    std::fs::write(&fake, b"not the package").expect("write");
    let dest = dir.join("mbm");
    let (code, _, err) = run(&[
        "data",
        "mbm",
        "--sdist",
        fake.to_str().expect("utf-8"),
        "--dir",
        dest.to_str().expect("utf-8"),
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("sha256"), "{err}");
    assert!(!dest.exists());
    let out = Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args(["bench", "mbm", "--robot", "panda"])
        .current_dir(&dir)
        .env("MANYHANDS_MBM_DIR", dir.join("none"))
        .output()
        .expect("run manyhands");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("manyhands data mbm"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `manyhands schedule BODY` takes the HTTP body of job kind `schedule` as documented, with
/// its `"kind": "schedule"`, refuses another kind naming the field, and reports a schedule
/// that does not exist with its own code and wording.
#[test]
fn schedule_takes_the_http_body_and_names_a_missing_schedule() {
    let ok = serde_json::json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["base_x"], "path": [[0.0], [0.5]]},
        {"robot": "armar_b", "joints": ["base_x"], "path": [[0.0], [0.5]]}]});
    let v = json(&["schedule", &ok.to_string(), "--json"]);
    assert_eq!(v["method"], "simultaneous", "{v}");
    assert!(v["duration"].as_f64().unwrap_or(0.0) > 0.0, "{v}");
    // The same body without its kind is still accepted.
    let mut bare = ok.clone();
    bare.as_object_mut().expect("object").remove("kind");
    let v = json(&["schedule", &bare.to_string(), "--json"]);
    assert_eq!(v["method"], "simultaneous", "{v}");
    let mut other = ok.clone();
    other["kind"] = "joint_space".into();
    let (code, _, err) = run(&["schedule", &other.to_string()]);
    assert_ne!(code, 0);
    assert!(
        err.contains("'kind'") && err.contains("joint_space"),
        "{err}"
    );
    // Ends in the same spot: no schedule, said as such (not a goal error).
    let blocked = serde_json::json!({"kind": "schedule", "scene": "kitchen_two", "trajectories": [
        {"robot": "armar_a", "joints": ["base_x", "base_y"],
         "path": [[0.0, 0.0], [1.0, 0.0], [1.0, 0.7]]},
        {"robot": "armar_b", "joints": ["base_x", "base_y"],
         "path": [[0.0, 0.0], [1.0, 0.0], [1.0, -0.7]]}]});
    let (code, _, err) = run(&["schedule", &blocked.to_string()]);
    assert_ne!(code, 0);
    assert!(
        err.contains("no_schedule: no collision-free schedule") && !err.contains("invalid_goal"),
        "{err}"
    );
}

/// `manyhands plan multi-arm BODY` takes the HTTP body of job kind `multi_arm` (with or without
/// its kind): the `arms_crossing` task is solved by a method other than decoupled, and a bad
/// field is refused naming it.
#[test]
fn plan_multi_arm_takes_the_http_body() {
    let text =
        std::fs::read_to_string(common::root().join("scenes/arms_crossing.json")).expect("scene");
    let scene: Value = serde_json::from_str(&text).expect("json");
    let goal = |k: usize| scene["robots"][k]["configs"]["goal"].clone();
    let body = serde_json::json!({"kind": "multi_arm", "scene": "arms_crossing",
        "robots": [{"name": "armar_a", "group": "right_arm", "goal": goal(0)},
                   {"name": "armar_b", "group": "left_arm", "goal": goal(1)}]});
    let v = json(&["plan", "multi-arm", &body.to_string(), "--json"]);
    assert_ne!(v["method"], "decoupled", "{v}");
    assert!(v["makespan"].as_f64().unwrap_or(0.0) > 0.0, "{v}");
    let mut bad = body.clone();
    bad["robots"][1]["group"] = "tentacle".into();
    let (code, _, err) = run(&["plan", "multi-arm", &bad.to_string()]);
    assert_ne!(code, 0);
    assert!(err.contains("robots[1].group"), "{err}");
}

/// A `.tar.gz` source package holding `resources/panda/` of the data folder `data` (URDF, SRDF,
/// every file of `meshes/`), a one-problem `problems.tar.bz2`, and `extra` entries written with
/// their names as given (unchecked, as a hostile archive could).
fn panda_sdist(data: &std::path::Path, out: &std::path::Path, extra: &[(&str, Vec<u8>)]) {
    use std::io::Write;
    fn raw(b: &mut tar::Builder<impl Write>, name: &str, data: &[u8]) {
        let mut h = tar::Header::new_gnu();
        let gnu = h.as_gnu_mut().expect("gnu header");
        gnu.name[..name.len()].copy_from_slice(name.as_bytes());
        h.set_size(data.len() as u64);
        h.set_mode(0o644);
        h.set_entry_type(tar::EntryType::Regular);
        h.set_cksum();
        b.append(&h, data).expect("tar entry");
    }
    let scene = "world:\n  collision_objects:\n    - id: far_box\n      primitives:\n        - type: box\n          dimensions: [0.1, 0.1, 0.1]\n      primitive_poses:\n        - position: [3.0, 0.0, 0.0]\n          orientation: [0.0, 0.0, 0.0, 1.0]\n";
    let joints = (1..=7).map(|i| format!("panda_joint{i}"));
    let names: Vec<String> = joints.clone().collect();
    let request = format!(
        "start_state:\n  joint_state:\n    name: [{}]\n    position: [0, -0.5, 0, -2.0, 0, 1.5, 0.7]\ngoal_constraints:\n  - joint_constraints:\n{}",
        names.join(", "),
        joints
            .zip([0.1, -0.6, 0.1, -2.1, 0.1, 1.6, 0.8])
            .map(|(j, q)| format!("      - joint_name: {j}\n        position: {q}\n"))
            .collect::<String>()
    );
    let mut problems = tar::Builder::new(Vec::new());
    raw(
        &mut problems,
        "problems/far_panda/scene0001.yaml",
        scene.as_bytes(),
    );
    raw(
        &mut problems,
        "problems/far_panda/request0001.yaml",
        request.as_bytes(),
    );
    let problems = problems.into_inner().expect("tar");
    let mut bz = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
    bz.write_all(&problems).expect("bz2");
    let problems = bz.finish().expect("bz2");
    let gz = flate2::write::GzEncoder::new(
        std::fs::File::create(out).expect("sdist file"),
        flate2::Compression::fast(),
    );
    let mut b = tar::Builder::new(gz);
    let root = "vamp_planner-0.6.4/resources/panda";
    for f in ["panda_spherized.urdf", "panda.srdf"] {
        let bytes = std::fs::read(data.join("panda").join(f)).expect("panda file");
        raw(&mut b, &format!("{root}/{f}"), &bytes);
    }
    raw(&mut b, &format!("{root}/problems.tar.bz2"), &problems);
    let meshes = data.join("panda/meshes");
    for kind in std::fs::read_dir(&meshes).expect("panda meshes") {
        let kind = kind.expect("entry").path();
        for f in std::fs::read_dir(&kind).expect("mesh folder") {
            let f = f.expect("entry").path();
            let rel = f.strip_prefix(&meshes).expect("under meshes");
            let bytes = std::fs::read(&f).expect("mesh file");
            raw(&mut b, &format!("{root}/meshes/{}", rel.display()), &bytes);
        }
    }
    for (name, data) in extra {
        raw(&mut b, name, data);
    }
    b.into_inner()
        .expect("tar")
        .finish()
        .expect("gz")
        .sync_all()
        .expect("sync");
}

/// The installer puts the Panda's visual meshes beside its URDF, so the installed model finds
/// every visual mesh it names; entries that climb out of `meshes/` or are not mesh files are
/// not written, and a mesh file over the size bound fails the install and leaves no folder.
#[test]
fn data_install_puts_the_visual_meshes_beside_the_urdf_with_path_and_size_bounds() {
    use manyhands::benchmark::mbm_data::{unpack_and_convert, Quiet, MAX_MESH_FILE_BYTES};
    use manyhands::model::VisualGeometry;
    let Some(data) = manyhands::benchmark::mbm_data::data_for_test() else {
        return;
    };
    let dir = common::tmp::TestDir::new("data-mbm-meshes");
    let sdist = dir.join("vamp_planner-0.6.4.tar.gz");
    let root = "vamp_planner-0.6.4/resources/panda/meshes";
    panda_sdist(
        &data,
        &sdist,
        &[
            (
                &format!("{root}/../../../escaped.obj"),
                b"v 0 0 0\n".to_vec(),
            ),
            (&format!("{root}/visual/.hidden.obj"), b"v 0 0 0\n".to_vec()),
            (&format!("{root}/visual/run.sh"), b"#!/bin/sh\n".to_vec()),
        ],
    );
    let dest = dir.join("mbm");
    let report = unpack_and_convert(&sdist, &dest, &["panda"], &mut Quiet).expect("install");
    assert_eq!(report.robots, vec![("panda".to_string(), 1, 1)]);
    let urdf = dest.join("panda/panda_spherized.urdf");
    let robot = manyhands::Robot::from_files(&urdf, Some(&dest.join("panda/panda.srdf")))
        .expect("installed Panda loads");
    let mut meshes = 0;
    for link in &robot.links {
        for v in &link.visual {
            if let VisualGeometry::Mesh { filename, path, .. } = &v.geometry {
                let p = path
                    .as_deref()
                    .unwrap_or_else(|| panic!("{}: mesh {filename} not installed", link.name));
                assert!(p.starts_with(dest.join("panda/meshes")), "{}", p.display());
                assert!(p.is_file(), "{}", p.display());
                meshes += 1;
            }
        }
    }
    assert!(meshes >= 8, "{meshes} visual meshes");
    for bad in [
        dir.join("escaped.obj"),
        dest.join("escaped.obj"),
        dest.join("panda/meshes/visual/.hidden.obj"),
        dest.join("panda/meshes/visual/run.sh"),
    ] {
        assert!(!bad.exists(), "{} was written", bad.display());
    }
    assert!(std::fs::read_to_string(dest.join("SOURCE.md"))
        .expect("SOURCE.md")
        .contains("visual meshes"));

    // One mesh file over the bound: the install fails, names it, and leaves nothing behind.
    let big = dir.join("big.tar.gz");
    let huge = vec![b' '; MAX_MESH_FILE_BYTES as usize + 1];
    panda_sdist(&data, &big, &[(&format!("{root}/visual/huge.obj"), huge)]);
    let dest2 = dir.join("mbm2");
    let err = unpack_and_convert(&big, &dest2, &["panda"], &mut Quiet)
        .expect_err("an oversized mesh is refused")
        .to_string();
    assert!(err.contains("huge.obj") && err.contains("limit"), "{err}");
    assert!(!dest2.exists());
}
