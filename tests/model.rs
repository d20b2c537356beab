//! Robot and scene loading: shipped robots round-trip, error cases name the problem.

use std::path::{Path, PathBuf};

use manyhands::model::{load_robot_dir, load_scene_dir, ModelError, SceneJson};
use manyhands::{Robot, Scene};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str) -> Robot {
    let d = root().join("robots");
    Robot::from_files(
        &d.join(format!("{name}.urdf")),
        Some(&d.join(format!("{name}.srdf"))),
    )
    .unwrap()
}

#[test]
fn armar_has_20_dof_and_its_groups() {
    let r = load("armar");
    assert_eq!(r.dof(), 20);
    for (g, n) in [
        ("left_arm", 7),
        ("right_arm", 7),
        ("hip", 3),
        ("base", 3),
        ("both_arms", 14),
        ("torso_left_arm", 10),
        ("torso_right_arm", 10),
        ("whole_body", 20),
    ] {
        assert_eq!(
            r.group(g).unwrap_or_else(|| panic!("group {g}")).vars.len(),
            n,
            "group {g}"
        );
    }
    assert!(r.group("right_arm").unwrap().chain.is_some());
    assert!(r.end_effector("left_hand").is_some() && r.end_effector("right_hand").is_some());
    assert!(r.named_config("home").is_some());
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

#[test]
fn justin_has_43_dof() {
    let r = load("justin");
    assert_eq!(r.dof(), 43);
    assert_eq!(r.group("left_arm").unwrap().vars.len(), 7);
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

/// Writes the parsed model back as URDF + SRDF and reads it again: same tree, limits, shapes,
/// groups, end effectors, states and disabled pairs.
#[test]
fn shipped_robots_round_trip_through_urdf_and_srdf() {
    use manyhands::model::{to_srdf, to_urdf};
    for name in ["armar", "justin"] {
        let r = load(name);
        let (u, s) = (to_urdf(&r), to_srdf(&r));
        let r2 = Robot::from_strings(&u, Some(&s), Path::new(".")).unwrap();
        assert_eq!(r.dof(), r2.dof());
        assert_eq!(r.links.len(), r2.links.len());
        for (a, b) in r.joints.iter().zip(&r2.joints) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.kind, b.kind);
            assert_eq!(a.limits, b.limits);
            assert!((a.origin.translation.vector - b.origin.translation.vector).norm() < 1e-12);
            assert!(a.origin.rotation.angle_to(&b.origin.rotation) < 1e-9);
        }
        for (a, b) in r.links.iter().zip(&r2.links) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.collision.len(), b.collision.len(), "link {}", a.name);
            for (ga, gb) in a.collision.iter().zip(&b.collision) {
                assert_eq!(ga.shape, gb.shape, "link {}", a.name);
            }
        }
        assert_eq!(r.groups, r2.groups);
        assert_eq!(r.end_effectors, r2.end_effectors);
        assert_eq!(r.group_states, r2.group_states);
        assert_eq!(r.disabled, r2.disabled);
        // A second round is textually stable.
        assert_eq!(to_urdf(&r2), u);
        assert_eq!(to_srdf(&r2), s);
    }
}

const GOOD: &str = r#"<robot name="t">
  <link name="a"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="b"/>
  <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"#;

fn urdf_err(text: &str) -> ModelError {
    Robot::from_strings(text, None, Path::new(".")).unwrap_err()
}

#[test]
fn good_minimal_urdf_loads() {
    let r = Robot::from_strings(GOOD, None, Path::new(".")).unwrap();
    assert_eq!(r.dof(), 1);
}

#[test]
fn missing_link_is_named() {
    let e = urdf_err(&GOOD.replace("<child link=\"b\"/>", "<child link=\"nope\"/>"));
    let s = e.to_string();
    assert!(
        s.contains("joint name=\"j\"") && s.contains("unknown link 'nope'"),
        "{s}"
    );
}

#[test]
fn bad_limit_is_named() {
    let e = urdf_err(&GOOD.replace("lower=\"-1\" upper=\"1\"", "lower=\"2\" upper=\"1\""));
    assert!(
        e.to_string().contains("<limit>") && e.to_string().contains("lower 2 > upper 1"),
        "{e}"
    );
    let e = urdf_err(&GOOD.replace("upper=\"1\"", "upper=\"abc\""));
    assert!(
        e.to_string().contains("upper=\"abc\" is not a number"),
        "{e}"
    );
    let e = urdf_err(&GOOD.replace(" velocity=\"1\"", ""));
    assert!(e.to_string().contains("missing attribute velocity"), "{e}");
}

/// URDF `<visual>` elements are read into the links (origin, box/cylinder/sphere/mesh with
/// scale, the mesh file located next to the URDF but not read), leniently: a visual that cannot
/// be read, or whose mesh is missing, is kept with its reason and the robot loads. The collision
/// model is the same as without the visuals.
#[test]
fn visual_elements_are_read_without_changing_collision() {
    use manyhands::model::VisualGeometry;
    let with = GOOD.replace(
        "<link name=\"a\">",
        "<link name=\"a\">\
         <visual name=\"shell\"><origin xyz=\"0.1 0 0\" rpy=\"0 0 0.5\"/>\
           <geometry><mesh filename=\"meshes/statuette.obj\" scale=\"2 2 2\"/></geometry></visual>\
         <visual><geometry><cylinder radius=\"0.1\" length=\"0.4\"/></geometry></visual>\
         <visual><geometry><mesh filename=\"package://nowhere/meshes/missing.dae\"/></geometry></visual>\
         <visual><geometry><box size=\"1 x 1\"/></geometry></visual>\
         <visual><geometry><teapot/></geometry></visual>",
    );
    let dir = root().join("scenes");
    let plain = Robot::from_strings(GOOD, None, &dir).unwrap();
    let r = Robot::from_strings(&with, None, &dir).unwrap();
    assert_eq!(r.links[0].collision, plain.links[0].collision);
    assert_eq!(r.disabled, plain.disabled);
    assert!(plain.links.iter().all(|l| l.visual.is_empty()));
    let v = &r.links[0].visual;
    assert_eq!(v.len(), 5);
    assert_eq!(v[0].name.as_deref(), Some("shell"));
    assert!((v[0].origin.translation.vector.x - 0.1).abs() < 1e-12);
    assert!((v[0].origin.rotation.angle() - 0.5).abs() < 1e-12);
    match &v[0].geometry {
        VisualGeometry::Mesh {
            filename,
            scale,
            path,
        } => {
            assert_eq!(filename, "meshes/statuette.obj");
            assert_eq!(*scale, [2.0; 3]);
            assert_eq!(
                path.as_deref(),
                Some(dir.join("meshes/statuette.obj").as_path())
            );
        }
        g => panic!("{g:?}"),
    }
    assert_eq!(
        v[1].geometry,
        VisualGeometry::Cylinder {
            radius: 0.1,
            length: 0.4
        }
    );
    assert!(matches!(
        &v[2].geometry,
        VisualGeometry::Mesh { path: None, .. }
    ));
    for (k, why) in [
        (3, "'x' is not a finite number"),
        (4, "unknown geometry 'teapot'"),
    ] {
        match &v[k].geometry {
            VisualGeometry::Invalid { reason } => {
                assert!(
                    reason.contains(why) && reason.contains("<visual>["),
                    "{reason}"
                )
            }
            g => panic!("visual {k}: {g:?}"),
        }
    }
}

#[test]
fn unknown_mesh_is_named() {
    let e = urdf_err(&GOOD.replace(
        "<box size=\"0.1 0.1 0.1\"/>",
        "<mesh filename=\"package://x/meshes/missing.stl\"/>",
    ));
    let s = e.to_string();
    assert!(
        s.contains("<mesh>") && s.contains("missing.stl") && s.contains("not found"),
        "{s}"
    );
}

#[test]
fn cycle_in_tree_is_named() {
    let text = GOOD.replace(
        "</robot>",
        r#"<joint name="back" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#,
    );
    let s = urdf_err(&text).to_string();
    assert!(s.contains("cycle"), "{s}");
}

#[test]
fn missing_joint_in_srdf_is_named() {
    let srdf = r#"<robot name="t"><group name="g"><joint name="ghost"/></group></robot>"#;
    let e = Robot::from_strings(GOOD, Some(srdf), Path::new(".")).unwrap_err();
    let s = e.to_string();
    assert!(
        s.contains("group name=\"g\"") && s.contains("ghost") && s.contains("unknown joint"),
        "{s}"
    );
}

#[test]
fn unsupported_and_malformed_input() {
    let s = urdf_err(&GOOD.replace("type=\"revolute\"", "type=\"planar\"")).to_string();
    assert!(s.contains("planar") && s.contains("prismatic"), "{s}");
    let s = urdf_err(&GOOD.replace("type=\"revolute\"", "type=\"spiral\"")).to_string();
    assert!(s.contains("unknown joint type 'spiral'"), "{s}");
    let s = urdf_err("<robot name=\"t\"><link name=\"a\"></robot>").to_string();
    assert!(s.contains("malformed"), "{s}");
    let s = urdf_err(&GOOD.replace("<box size=\"0.1 0.1 0.1\"/>", "<cone r=\"1\"/>")).to_string();
    assert!(s.contains("unknown geometry 'cone'"), "{s}");
    let s = urdf_err(&GOOD.replace("<link name=\"b\"/>", "<link name=\"b\"/><link name=\"c\"/>"))
        .to_string();
    assert!(s.contains("separate trees"), "{s}");
}

#[test]
fn mimic_joint_follows_its_master() {
    let text = GOOD.replace(
        "</robot>",
        r#"<link name="c"/><joint name="m" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="1 0 0"/>
           <limit lower="-1" upper="1" velocity="1" effort="1"/><mimic joint="j" multiplier="0.5" offset="0.1"/></joint></robot>"#,
    );
    let r = Robot::from_strings(&text, None, Path::new(".")).unwrap();
    assert_eq!(r.dof(), 1);
    let p = manyhands::kinematics::link_pose(&r, &[0.4], r.link("c").unwrap());
    let x = p.translation.vector;
    // Prismatic along b's x axis, rotated by 0.4 rad about z.
    assert!((x.norm() - 0.3).abs() < 1e-12, "{x:?}");
}

#[test]
fn shipped_scenes_load() {
    let lib = load_robot_dir(&root().join("robots")).unwrap();
    let scenes = load_scene_dir(&root().join("scenes"), &lib).unwrap();
    for name in ["kitchen", "empty", "obstacle"] {
        assert!(scenes.contains_key(name), "scene {name}");
    }
    let k = &scenes["kitchen"];
    let wok = k.object("wok").expect("wok");
    assert_eq!(
        wok.grasps
            .iter()
            .filter(|g| g.end_effector == "right_hand")
            .count(),
        15
    );
    assert!(k.object("plate").is_some());
    assert_eq!(k.robots[0].robot.dof(), 20);
}

#[test]
fn scene_errors_name_the_field() {
    let lib = load_robot_dir(&root().join("robots")).unwrap();
    let text = std::fs::read_to_string(root().join("scenes/kitchen.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["robots"][0]["configs"]["start"]["right_elbow"] = serde_json::json!(4.2);
    let json: SceneJson = serde_json::from_value(v.clone()).unwrap();
    let e = Scene::from_json(json, "k.json", Path::new("."), &lib).unwrap_err();
    assert_eq!(
        e.element(),
        Some("robots[0].configs.start.right_elbow"),
        "{e}"
    );
    assert!(e.to_string().contains("outside limit"), "{e}");

    let mut v2 = v.clone();
    v2["robots"][0]["configs"]["start"] = serde_json::json!({});
    v2["robots"][0]["model"] = serde_json::json!("r2d2");
    let e = Scene::from_json(
        serde_json::from_value(v2).unwrap(),
        "k.json",
        Path::new("."),
        &lib,
    )
    .unwrap_err();
    assert_eq!(e.element(), Some("robots[0].model"), "{e}");

    let mut v3 = v;
    v3["robots"][0]["configs"]["start"] = serde_json::json!({});
    v3["obstacles"][0]["shapes"][0] =
        serde_json::json!({"type": "box", "half_extents": [0.1, -0.2, 0.3]});
    let e = Scene::from_json(
        serde_json::from_value(v3).unwrap(),
        "k.json",
        Path::new("."),
        &lib,
    )
    .unwrap_err();
    assert_eq!(
        e.element(),
        Some("obstacles[0].shapes[0].half_extents[1]"),
        "{e}"
    );

    let e = Scene::from_str(
        "{\"name\": \"x\", \"obstacles\": [{\"name\": 3}]}",
        "bad.json",
        Path::new("."),
        &lib,
    )
    .unwrap_err();
    assert!(e.to_string().contains("bad.json"), "{e}");
    let e = Scene::from_str(
        "{\"name\": \"x\", \"bogus\": 1}",
        "bad.json",
        Path::new("."),
        &lib,
    )
    .unwrap_err();
    assert!(e.to_string().contains("bogus"), "{e}");
}

/// Truncated and mutated robot and scene files give errors, never panics.
#[test]
fn mutated_inputs_never_panic() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let urdf = std::fs::read_to_string(root().join("robots/armar.urdf")).unwrap();
    let srdf = std::fs::read_to_string(root().join("robots/armar.srdf")).unwrap();
    let scene = std::fs::read_to_string(root().join("scenes/kitchen.json")).unwrap();
    let lib = load_robot_dir(&root().join("robots")).unwrap();
    let tokens = [
        "-1", "nan", "inf", "1e309", "\"", "<", ">", "/>", "0 0", "", "x", "name", "link", "joint",
        "[", "]", "{", "}", ",",
    ];
    let mutate = |text: &str, rng: &mut rand_chacha::ChaCha8Rng| -> String {
        let mut s: Vec<char> = text.chars().collect();
        for _ in 0..rng.random_range(1..4) {
            let i = rng.random_range(0..s.len());
            match rng.random_range(0..3) {
                0 => s.truncate(i),
                1 => {
                    let end = (i + rng.random_range(1..20)).min(s.len());
                    s.drain(i..end);
                }
                _ => {
                    let t = tokens[rng.random_range(0..tokens.len())];
                    for (k, c) in t.chars().enumerate() {
                        s.insert((i + k).min(s.len()), c);
                    }
                }
            }
            if s.is_empty() {
                break;
            }
        }
        s.into_iter().collect()
    };
    let (mut ok, mut err) = (0, 0);
    for _ in 0..600 {
        let u = mutate(&urdf, &mut rng);
        match Robot::from_strings(&u, Some(&srdf), Path::new(".")) {
            Ok(_) => ok += 1,
            Err(e) => {
                assert!(!e.to_string().is_empty());
                err += 1;
            }
        }
        let s = mutate(&srdf, &mut rng);
        let _ = Robot::from_strings(&urdf, Some(&s), Path::new("."));
        let j = mutate(&scene, &mut rng);
        let _ = Scene::from_str(&j, "k.json", Path::new("."), &lib);
    }
    assert!(err > 100 && ok + err == 600, "ok {ok} err {err}");
}
