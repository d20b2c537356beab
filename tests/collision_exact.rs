//! The exact (parry3d) checker against hand-computed cases: primitive shapes, self-collision and
//! SRDF-disabled pairs, two robots, attached objects, meshes, clearance, and a two-arm robot of spheres.

mod common;

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use manyhands::collision::{
    CollisionChecker, CollisionWorld, Contact, ExactChecker, StaticBody, StaticKind,
};
use manyhands::geometry::{iso_from_rpy, Geometry, Pose, Shape};
use manyhands::kinematics::forward;
use manyhands::model::{RobotLibrary, Scene};
use manyhands::Robot;
use nalgebra::Vector3;

// ---------------------------------------------------------------------------------------------
// Helpers

fn robot(urdf: &str, srdf: Option<&str>) -> Arc<Robot> {
    Arc::new(Robot::from_strings(urdf, srdf, Path::new(".")).unwrap())
}

fn cuboid(h: [f64; 3]) -> Shape {
    Shape::Box {
        half_extents: Vector3::from(h),
    }
}

fn obstacle(name: &str, pos: [f64; 3], shape: Shape) -> StaticBody {
    StaticBody {
        name: name.into(),
        kind: StaticKind::Obstacle,
        pose: iso_from_rpy(pos, [0.0; 3]),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape,
        }],
    }
}

fn world(r: &Arc<Robot>, statics: Vec<StaticBody>) -> CollisionWorld {
    let mut w = CollisionWorld::single(r.clone(), Pose::identity());
    w.statics = statics;
    w
}

fn contact(a: &str, b: &str) -> Option<Contact> {
    Some(Contact {
        a: a.into(),
        b: b.into(),
    })
}

fn revolute(name: &str, parent: &str, child: &str, xyz: &str) -> String {
    format!(
        r#"<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
           <origin xyz="{xyz}"/><axis xyz="0 0 1"/>
           <limit lower="-3.2" upper="3.2" velocity="1" effort="1"/></joint>"#
    )
}

/// A planar arm turning about z: link1 is a box along x (length 1), link2 a cylinder along x
/// (length 0.8, radius 0.05, its URDF axis z turned onto x by pitch +90°) and a small box "hand"
/// fixed at the tip of link2 (x in [0.8, 0.9] of link2).
fn arm_urdf() -> String {
    format!(
        r#"<robot name="arm">
  <link name="base"/>
  <link name="link1"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 0.1 0.1"/></geometry></collision></link>
  <link name="link2"><collision><origin xyz="0.4 0 0" rpy="0 {h} 0"/>
    <geometry><cylinder radius="0.05" length="0.8"/></geometry></collision></link>
  <link name="hand"><collision><origin xyz="0.05 0 0"/>
    <geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  {j1}
  {j2}
  <joint name="j3" type="fixed"><parent link="link2"/><child link="hand"/>
    <origin xyz="0.8 0 0"/></joint>
</robot>"#,
        h = FRAC_PI_2,
        j1 = revolute("j1", "base", "link1", "0 0 0"),
        j2 = revolute("j2", "link1", "link2", "1 0 0"),
    )
}

const ARM_SRDF: &str = r#"<robot name="arm">
  <disable_collisions link1="link1" link2="link2" reason="Adjacent"/>
  <disable_collisions link1="link2" link2="hand" reason="Adjacent"/>
</robot>"#;

fn probe(geometry: &str, obstacle_shape: Shape) -> ExactChecker {
    probe_with_base(geometry, obstacle_shape, Path::new("."))
}

fn probe_with_base(geometry: &str, obstacle_shape: Shape, base: &Path) -> ExactChecker {
    let r = Arc::new(Robot::from_strings(&common::probe_urdf(geometry, 10.0), None, base).unwrap());
    ExactChecker::new(&world(&r, vec![obstacle("o", [0.0; 3], obstacle_shape)]))
}

// ---------------------------------------------------------------------------------------------
// Two-link arm against a box

#[test]
fn arm_against_box_obstacle() {
    let r = robot(&arm_urdf(), Some(ARM_SRDF));
    // Block on the line of link2 (x in [1, 1.8] at q = 0).
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("block", [1.5, 0.0, 0.0], cuboid([0.1; 3]))],
    ));
    assert!(!c.is_free(&[0.0, 0.0]));
    assert_eq!(
        c.first_contact(&[0.0, 0.0]),
        contact("arm/link2", "obstacle:block")
    );
    // Arm turned to +y: free.
    assert!(c.is_free(&[FRAC_PI_2, 0.0]));
    assert_eq!(c.first_contact(&[FRAC_PI_2, 0.0]), None);
    // Only link2 turned to +y (from (1,0,0) to (1,0.8,0)): free.
    assert!(c.is_free(&[0.0, FRAC_PI_2]));
    // Arm turned to -x (link1 over x in [-1, 0]), link2 straight on: free.
    assert!(c.is_free(&[PI, 0.0]));
    assert_eq!(c.checks(), 6);
    // link2 folded back over link1: the hand (x in [-0.2, -0.1]) hits link1 (not disabled).
    assert_eq!(c.first_contact(&[PI, PI]), contact("arm/link1", "arm/hand"));

    // Block hit by link1 only.
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("low", [0.5, 0.0, 0.1], cuboid([0.1, 0.1, 0.06]))],
    ));
    assert_eq!(
        c.first_contact(&[0.0, 0.0]),
        contact("arm/link1", "obstacle:low")
    );
    // 0.01 above the box of link1 (top at z = 0.05).
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("high", [0.5, 0.0, 0.16], cuboid([0.1, 0.1, 0.1]))],
    ));
    assert!(c.is_free(&[0.0, 0.0]));
}

#[test]
fn cylinder_axis_is_mapped_from_z() {
    let r = robot(&arm_urdf(), Some(ARM_SRDF));
    // At q = 0 the cylinder of link2 lies along world x (x in [1, 1.8], radius 0.05). A cylinder
    // left along parry's y would lie along world y at x = 1.4 instead.
    // Near the far end of the true cylinder, off the wrong one: collides.
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("tip", [1.75, 0.0, 0.0], cuboid([0.02; 3]))],
    ));
    assert_eq!(
        c.first_contact(&[0.0, 0.0]),
        contact("arm/link2", "obstacle:tip")
    );
    // Beside the middle of the true cylinder, on the wrong one: free.
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("side", [1.4, 0.3, 0.0], cuboid([0.05; 3]))],
    ));
    assert!(c.is_free(&[0.0, 0.0]));
    // Radius: a box 0.049 from the axis touches, 0.051 does not.
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("r", [1.4, 0.0, 0.149], cuboid([0.1; 3]))],
    ));
    assert!(!c.is_free(&[0.0, 0.0]));
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("r", [1.4, 0.0, 0.151], cuboid([0.1; 3]))],
    ));
    assert!(c.is_free(&[0.0, 0.0]));
    // Round, not square: a box at 45° in the y-z plane, its corner 0.06 from the axis (inside
    // the square of half side 0.05 around the axis would reach 0.0707).
    let d = 0.06 / 2f64.sqrt() + 0.02; // box centre offset per axis (half size 0.02)
    let mut c = ExactChecker::new(&world(
        &r,
        vec![obstacle("diag", [1.4, d, d], cuboid([0.02; 3]))],
    ));
    assert!(c.is_free(&[0.0, 0.0]));
}

// ---------------------------------------------------------------------------------------------
// Self-collision

/// link1 (x in [0, 1]), a short link2 (0.4) and link3 (1.0), all boxes along x turning about z.
fn folding_urdf() -> String {
    format!(
        r#"<robot name="fold">
  <link name="base"/>
  <link name="link1"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 0.1 0.1"/></geometry></collision></link>
  <link name="link2"><collision><origin xyz="0.2 0 0"/>
    <geometry><box size="0.4 0.1 0.1"/></geometry></collision></link>
  <link name="link3"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 0.1 0.1"/></geometry></collision></link>
  {}{}{}
</robot>"#,
        revolute("j1", "base", "link1", "0 0 0"),
        revolute("j2", "link1", "link2", "1 0 0"),
        revolute("j3", "link2", "link3", "0.4 0 0"),
    )
}

#[test]
fn self_collision_and_srdf_disabled_pairs() {
    let adjacent = r#"<robot name="fold">
      <disable_collisions link1="link1" link2="link2" reason="Adjacent"/>
      <disable_collisions link1="link2" link2="link3" reason="Adjacent"/>
    </robot>"#;
    // Folded: link2 goes up to (1, 0.4), link3 comes back down across link1.
    let folded = [0.0, FRAC_PI_2, FRAC_PI_2 + 0.5];
    // Folded parallel: link3 runs along y = 0.4 above link1, 0.3 apart.
    let parallel = [0.0, FRAC_PI_2, FRAC_PI_2];

    let r = robot(&folding_urdf(), Some(adjacent));
    let mut c = ExactChecker::new(&CollisionWorld::single(r.clone(), Pose::identity()));
    assert_eq!(c.num_pairs(), 1);
    assert!(c.is_free(&[0.0, 0.0, 0.0]));
    assert!(c.is_free(&parallel));
    assert!(!c.is_free(&folded));
    assert_eq!(
        c.first_contact(&folded),
        contact("fold/link1", "fold/link3")
    );
    assert!((c.clearance(&parallel) - 0.3).abs() < 1e-9);

    // Without the SRDF, the adjacent links overlap at their joints in every configuration:
    // found at load as always colliding (issue 28) and disabled, each with a warning giving
    // the SRDF line; link1–link3 stays checked.
    let r = robot(&folding_urdf(), None);
    let found: Vec<(String, String)> = r
        .always_colliding
        .iter()
        .map(|p| (r.links[p.a].name.clone(), r.links[p.b].name.clone()))
        .collect();
    assert_eq!(
        found,
        [("link1", "link2"), ("link2", "link3")].map(|(a, b)| (a.to_string(), b.to_string()))
    );
    assert!(
        r.warnings
            .iter()
            .any(|w| w
                .contains(r#"<disable_collisions link1="link1" link2="link2" reason="Always"/>"#)),
        "{:?}",
        r.warnings
    );
    let mut c = ExactChecker::new(&CollisionWorld::single(r, Pose::identity()));
    assert_eq!(c.num_pairs(), 1);
    assert_eq!(c.first_contact(&parallel), None);
    assert_eq!(
        c.first_contact(&folded),
        contact("fold/link1", "fold/link3")
    );

    // link1–link3 disabled too: nothing left to check.
    let all = r#"<robot name="fold">
      <disable_collisions link1="link1" link2="link2" reason="Adjacent"/>
      <disable_collisions link1="link2" link2="link3" reason="Adjacent"/>
      <disable_collisions link1="link3" link2="link1" reason="Never"/>
    </robot>"#;
    let r = robot(&folding_urdf(), Some(all));
    let mut c = ExactChecker::new(&CollisionWorld::single(r, Pose::identity()));
    assert_eq!(c.num_pairs(), 0);
    assert!(c.is_free(&folded));
    assert_eq!(c.first_contact(&folded), None);
    assert_eq!(c.clearance(&folded), f64::INFINITY);
}

// ---------------------------------------------------------------------------------------------
// Two robots

const STICK: &str = r#"<robot name="stick">
  <link name="base"/>
  <link name="rod"><collision><origin xyz="0.5 0 0"/>
    <geometry><box size="1 0.1 0.1"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 0 1"/>
    <limit lower="-3.2" upper="3.2" velocity="1" effort="1"/></joint>
</robot>"#;

fn two_sticks(b_xyz: [f64; 3], b_yaw: f64) -> ExactChecker {
    let mut lib = RobotLibrary::new();
    lib.insert("stick".into(), robot(STICK, None));
    let json = serde_json::json!({
        "name": "two",
        "robots": [
            {"name": "a", "model": "stick"},
            {"name": "b", "model": "stick",
             "base_pose": {"position": b_xyz, "rpy": [0.0, 0.0, b_yaw]}}
        ]
    });
    let scene = Scene::from_json(
        serde_json::from_value(json).unwrap(),
        "two.json",
        Path::new("."),
        &lib,
    )
    .unwrap();
    let w = CollisionWorld::from_scene(&scene);
    assert_eq!(w.dof(), 2);
    ExactChecker::new(&w)
}

#[test]
fn robot_robot_collision_with_base_poses() {
    // b at x = 1.9 facing -x: its rod covers x in [0.9, 1.9], a's rod covers [0, 1].
    let mut c = two_sticks([1.9, 0.0, 0.0], PI);
    assert_eq!(c.first_contact(&[0.0, 0.0]), contact("a/rod", "b/rod"));
    // a turned to +y: free; b turned to -y: free.
    assert!(c.is_free(&[FRAC_PI_2, 0.0]));
    assert!(c.is_free(&[0.0, FRAC_PI_2]));
    // Both turned towards +y: parallel, 1.9 - 0.1 apart.
    assert!((c.clearance(&[FRAC_PI_2, -FRAC_PI_2]) - 1.8).abs() < 1e-9);

    // b facing +x: [1.9, 2.9], 0.9 from a's tip.
    let mut c = two_sticks([1.9, 0.0, 0.0], 0.0);
    assert!(c.is_free(&[0.0, 0.0]));
    assert!((c.clearance(&[0.0, 0.0]) - 0.9).abs() < 1e-9);
    // b turned round to face a: [0.9, 1.9].
    assert!(!c.is_free(&[0.0, PI]));

    // b lifted by 0.2 above a: free in every yaw (rods are 0.1 thick).
    let mut c = two_sticks([0.5, 0.0, 0.2], PI);
    for k in 0..8 {
        let t = k as f64 * 0.7 - 2.8;
        assert!(c.is_free(&[t, -t]));
    }
    // Lifted by 0.09: they overlap in z and cross.
    let mut c = two_sticks([0.5, 0.0, 0.09], FRAC_PI_2);
    assert!(!c.is_free(&[0.0, 0.0]));
}

// ---------------------------------------------------------------------------------------------
// Attached object

#[test]
fn attached_object_moves_with_the_hand() {
    let r = robot(&arm_urdf(), Some(ARM_SRDF));
    let mut w = world(
        &r,
        vec![
            // Overlaps the hand at q = 0 (hand covers x in [1.8, 1.9], z in [-0.05, 0.05]).
            obstacle("cup", [1.9, 0.0, 0.1], cuboid([0.08; 3])),
            // Reached by the cup, not by the arm, when the arm points along +y.
            obstacle("wall", [0.0, 1.9, 0.25], cuboid([0.2, 0.2, 0.1])),
        ],
    );
    w.statics[0].kind = StaticKind::Object;
    let q0 = [0.0, 0.0];
    let up = [FRAC_PI_2, 0.0];
    // Before grasping, the cup in the scene touches the hand.
    let mut c = ExactChecker::new(&w);
    assert_eq!(c.first_contact(&q0), contact("arm/hand", "object:cup"));
    assert!(c.is_free(&up));

    let link2 = r.link("link2").unwrap();
    let hand = r.link("hand").unwrap();
    assert_eq!(w.attach("cup", 0, link2, &q0, vec![hand]), Some(0));
    let mut c = ExactChecker::new(&w);
    // Held: the touch link is never reported.
    assert!(c.is_free(&q0));
    for k in 0..12 {
        let t = -1.0 + k as f64 * 0.1;
        let q = [t, 0.0];
        if let Some(ct) = c.first_contact(&q) {
            assert!(ct.a != "arm/hand" && ct.b != "arm/hand", "{ct:?}");
        }
    }
    // The cup follows the hand into the wall.
    assert_eq!(
        c.first_contact(&up),
        contact("object:cup (held)", "obstacle:wall")
    );
    // Without the cup the arm itself clears the wall.
    let w2 = world(
        &r,
        vec![obstacle("wall", [0.0, 1.9, 0.25], cuboid([0.2, 0.2, 0.1]))],
    );
    assert!(ExactChecker::new(&w2).is_free(&up));
}

// ---------------------------------------------------------------------------------------------
// Other shapes against a box

#[test]
fn sphere_capsule_cylinder_against_box() {
    let unit = || cuboid([0.5; 3]);
    let mut s = probe(r#"<geometry><sphere radius="0.2"/></geometry>"#, unit());
    assert!(!s.is_free(&[0.69, 0.0, 0.0]));
    assert!(s.is_free(&[0.71, 0.0, 0.0]));
    // Near the corner (0.5, 0.5, 0.5): distance |(0.1, 0.1, 0.1)| = 0.173 < 0.2.
    assert!(!s.is_free(&[0.6, 0.6, 0.6]));
    assert!(s.is_free(&[0.62, 0.62, 0.62])); // 0.208
    assert_eq!(
        s.first_contact(&[0.0, 0.0, 0.6]),
        contact("probe/tool", "obstacle:o")
    );

    // Capsule along z: radius 0.1, half length 0.3 (reaches 0.4 along z, 0.1 sideways).
    let mut c = probe(
        r#"<geometry><capsule radius="0.1" length="0.6"/></geometry>"#,
        unit(),
    );
    assert!(!c.is_free(&[0.0, 0.0, 0.89]));
    assert!(c.is_free(&[0.0, 0.0, 0.91]));
    assert!(!c.is_free(&[0.59, 0.0, 0.0]));
    assert!(c.is_free(&[0.61, 0.0, 0.0]));
    // The rounded end: above the edge x = 0.5, z = 0.5.
    assert!(!c.is_free(&[0.55, 0.0, 0.85])); // end centre (0.55, 0.55): 0.0707 from the edge
    assert!(c.is_free(&[0.58, 0.0, 0.88])); // 0.113

    // Cylinder along z: flat end, reaches 0.3 along z.
    let mut c = probe(
        r#"<geometry><cylinder radius="0.1" length="0.6"/></geometry>"#,
        unit(),
    );
    assert!(!c.is_free(&[0.0, 0.0, 0.79]));
    assert!(c.is_free(&[0.0, 0.0, 0.81]));
    assert!(!c.is_free(&[0.59, 0.0, 0.0]));
    assert!(c.is_free(&[0.61, 0.0, 0.0]));
    // Flat end, not rounded: its bottom rim (z = 0.48) reaches x = 0.48 over the edge.
    assert!(!c.is_free(&[0.58, 0.0, 0.78]));
}

/// A cube of half side 0.1 as OBJ text (and optionally shifted).
fn cube_obj(h: f64, shift: [f64; 3]) -> String {
    let mut s = String::new();
    for i in 0..8 {
        let x = if i & 1 == 0 { -h } else { h } + shift[0];
        let y = if i & 2 == 0 { -h } else { h } + shift[1];
        let z = if i & 4 == 0 { -h } else { h } + shift[2];
        s.push_str(&format!("v {x} {y} {z}\n"));
    }
    // 1-based faces (two triangles per side).
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s.push_str(&format!(
            "f {} {} {}\nf {} {} {}\n",
            f[0], f[1], f[2], f[0], f[2], f[3]
        ));
    }
    s
}

#[test]
fn mesh_uses_its_convex_hull() {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_nanos();
    let dir =
        common::tmp::run_root().join(format!("manyhands_exact_{}_{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("cube.obj"), cube_obj(0.1, [0.0; 3])).unwrap();
    // A cube shifted by +0.3 in x inside its own frame.
    std::fs::write(dir.join("shifted.obj"), cube_obj(0.1, [0.3, 0.0, 0.0])).unwrap();

    let mut c = probe_with_base(
        r#"<geometry><mesh filename="cube.obj"/></geometry>"#,
        cuboid([0.5; 3]),
        &dir,
    );
    assert!(!c.is_free(&[0.59, 0.0, 0.0]));
    assert!(c.is_free(&[0.61, 0.0, 0.0]));
    assert!(!c.is_free(&[0.0, -0.59, 0.0]));
    // Cube corner (0.5, 0.5, 0.5) against the mesh cube's corner: a sphere of radius 0.1 would
    // be free at (0.59, 0.59, 0.59), the cube is not.
    assert!(!c.is_free(&[0.59, 0.59, 0.59]));
    let d = c.clearance(&[0.8, 0.0, 0.0]);
    // GJK on a polyhedron: ~1e-9 accurate.
    assert!((d - 0.2).abs() < 1e-7, "{d}");

    let mut c = probe_with_base(
        r#"<geometry><mesh filename="shifted.obj" scale="1 1 1"/></geometry>"#,
        cuboid([0.5; 3]),
        &dir,
    );
    // Mesh covers x in [q + 0.2, q + 0.4].
    assert!(!c.is_free(&[0.29, 0.0, 0.0]));
    assert!(c.is_free(&[0.31, 0.0, 0.0]));
    assert!(c.is_free(&[-0.91, 0.0, 0.0]));
    assert!(!c.is_free(&[-0.89, 0.0, 0.0]));

    // A flat square (no volume: the hull may fail, then the box of its bounds is used).
    std::fs::write(
        dir.join("flat.obj"),
        "v -0.1 -0.1 0\nv 0.1 -0.1 0\nv 0.1 0.1 0\nv -0.1 0.1 0\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let mut c = probe_with_base(
        r#"<geometry><mesh filename="flat.obj"/></geometry>"#,
        cuboid([0.5; 3]),
        &dir,
    );
    assert!(!c.is_free(&[0.59, 0.0, 0.0]));
    assert!(c.is_free(&[0.61, 0.0, 0.0]));
    assert!(!c.is_free(&[0.0, 0.0, 0.49]));
    assert!(c.is_free(&[0.0, 0.0, 0.51]));

    // Four points on a line (x in [-0.1, 0.2]): no hull; the box of its bounds is used.
    std::fs::write(
        dir.join("line.obj"),
        "v -0.1 0 0\nv 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nf 1 2 3\nf 2 3 4\n",
    )
    .unwrap();
    let mut c = probe_with_base(
        r#"<geometry><mesh filename="line.obj"/></geometry>"#,
        cuboid([0.5; 3]),
        &dir,
    );
    assert!(!c.is_free(&[0.59, 0.0, 0.0]));
    assert!(c.is_free(&[0.61, 0.0, 0.0]));
    assert!(!c.is_free(&[-0.69, 0.0, 0.0]));
    assert!(c.is_free(&[-0.71, 0.0, 0.0]));
    assert!(c.is_free(&[0.0, 0.51, 0.0]));
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------------------------------------
// Clearance and margins

#[test]
fn clearance_and_margin() {
    // Sphere (r = 0.2) to sphere (r = 0.3) at the origin.
    let mut c = probe(
        r#"<geometry><sphere radius="0.2"/></geometry>"#,
        Shape::Sphere { radius: 0.3 },
    );
    let q = [1.0, 0.5, 0.2];
    let d = (1.0f64 + 0.25 + 0.04).sqrt() - 0.5;
    assert!((c.clearance(&q) - d).abs() < 1e-9);
    assert!(c.is_free_with_margin(&q, d - 1e-6));
    assert!(!c.is_free_with_margin(&q, d + 1e-6));
    assert!(c.is_free_with_margin(&q, 0.0));
    let (dd, pair) = c.closest_pair(&q).unwrap();
    assert!((dd - d).abs() < 1e-9);
    assert_eq!(Some(pair), contact("probe/tool", "obstacle:o"));
    // Overlapping: 0, and never free with any margin.
    assert_eq!(c.clearance(&[0.3, 0.0, 0.0]), 0.0);
    assert!(!c.is_free_with_margin(&[0.3, 0.0, 0.0], 1e-3));
    assert!(!c.is_free_with_margin(&[0.3, 0.0, 0.0], 0.0));

    // Sphere (r = 0.2) to a box of half side 0.5: nearest the corner (0.5, 0.5, 0.5).
    let mut c = probe(
        r#"<geometry><sphere radius="0.2"/></geometry>"#,
        cuboid([0.5; 3]),
    );
    let q = [1.0, 0.7, 0.6];
    let d = (0.25f64 + 0.04 + 0.01).sqrt() - 0.2;
    assert!((c.clearance(&q) - d).abs() < 1e-9);
    assert!(c.is_free_with_margin(&q, d - 1e-6));
    assert!(!c.is_free_with_margin(&q, d + 1e-6));
    // Facing a side: plain difference.
    assert!((c.clearance(&[0.0, 0.0, -1.2]) - 0.5).abs() < 1e-9);
    // A margin far beyond the bounding spheres still finds the pair.
    assert!(!c.is_free_with_margin(&[5.0, 0.0, 0.0], 4.5));
    assert!(c.is_free_with_margin(&[5.0, 0.0, 0.0], 4.2));
}

// ---------------------------------------------------------------------------------------------
// A two-arm robot of spheres (the suite's own, Panda arm kinematics: tests/robots/twin_arms.py)

fn twin_arms() -> Arc<Robot> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
    Arc::new(Robot::from_files(&d.join("twin_arms.urdf"), Some(&d.join("twin_arms.srdf"))).unwrap())
}

#[test]
fn twin_arms_ready_is_free_and_a_box_at_the_gripper_collides() {
    let r = twin_arms();
    let ready = r.named_config("ready").unwrap();
    let mut c = ExactChecker::new(&CollisionWorld::single(r.clone(), Pose::identity()));
    assert!(c.num_pairs() > 0);
    assert_eq!(c.first_contact(&ready), None);
    assert!(c.clearance(&ready) > 0.0);

    let mut poses = vec![Pose::identity(); r.links.len()];
    forward(&r, &Pose::identity(), &ready, &mut poses);
    let hand = poses[r.link("left_hand").unwrap()].translation.vector;
    let mut w = CollisionWorld::single(r.clone(), Pose::identity());
    w.statics.push(obstacle(
        "cage",
        [hand.x, hand.y, hand.z],
        cuboid([0.05; 3]),
    ));
    let mut c = ExactChecker::new(&w);
    let ct = c
        .first_contact(&ready)
        .expect("box around the gripper collides");
    assert!(ct.a.starts_with("twin_arms/left_"), "{ct:?}");
    assert_eq!(ct.b, "obstacle:cage");
    // Moved 0.5 m above the gripper: free.
    let mut w = CollisionWorld::single(r.clone(), Pose::identity());
    w.statics.push(obstacle(
        "cage",
        [hand.x, hand.y, hand.z + 0.5],
        cuboid([0.05; 3]),
    ));
    assert!(ExactChecker::new(&w).is_free(&ready));
}

#[test]
fn twin_arms_timing_with_ten_boxes() {
    let r = twin_arms();
    let mut w = CollisionWorld::single(r.clone(), Pose::identity());
    // A table, shelves and posts around the robot; none at the ready pose of the gripper.
    let boxes: [([f64; 3], [f64; 3]); 10] = [
        ([0.5, 0.0, -0.1], [0.6, 0.8, 0.04]),
        ([0.7, 0.5, 0.3], [0.1, 0.1, 0.3]),
        ([0.7, -0.5, 0.3], [0.1, 0.1, 0.3]),
        ([0.8, 0.0, 0.9], [0.2, 0.6, 0.02]),
        ([-0.5, 0.5, 0.4], [0.05, 0.05, 0.4]),
        ([-0.5, -0.5, 0.4], [0.05, 0.05, 0.4]),
        ([0.0, 0.8, 0.5], [0.4, 0.02, 0.5]),
        ([0.0, -0.8, 0.5], [0.4, 0.02, 0.5]),
        ([0.9, 0.0, 0.3], [0.05, 0.2, 0.05]),
        ([0.3, 0.4, 1.2], [0.1, 0.1, 0.1]),
    ];
    for (i, (p, h)) in boxes.iter().enumerate() {
        w.statics.push(obstacle(&format!("b{i}"), *p, cuboid(*h)));
    }
    let mut c = ExactChecker::new(&w);
    // Deterministic pseudo-random configurations within the limits.
    let mut s: u64 = 0x9e3779b97f4a7c15;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let ready = r.named_config("ready").unwrap();
    let n = 2000;
    // Uniform in the limits, then within ±0.4 rad of `ready` (mostly free).
    let mut qs: Vec<Vec<f64>> = Vec::with_capacity(2 * n);
    for k in 0..2 * n {
        let q = (0..r.dof())
            .map(|v| {
                let l = r.var_limits(v);
                if k < n {
                    l.lower + (l.upper - l.lower) * next()
                } else {
                    (ready[v] + 0.8 * (next() - 0.5)).clamp(l.lower, l.upper)
                }
            })
            .collect();
        qs.push(q);
    }
    let mut runs: Vec<(f64, bool)> = Vec::with_capacity(2 * n);
    for q in &qs {
        let t = Instant::now();
        let free = c.is_free(q);
        runs.push((t.elapsed().as_secs_f64() * 1e6, free));
    }
    let median = |mut v: Vec<f64>| {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v[v.len() / 2]
    };
    for (label, part) in [("uniform", &runs[..n]), ("near ready", &runs[n..])] {
        let all: Vec<f64> = part.iter().map(|r| r.0).collect();
        let free: Vec<f64> = part.iter().filter(|r| r.1).map(|r| r.0).collect();
        eprintln!(
            "exact is_free, twin_arms + 10 boxes ({} pairs), {label}: median {:.1} us \
             ({} of {n} free; median of free ones {:.1} us)",
            c.num_pairs(),
            median(all),
            free.len(),
            median(free.clone()),
        );
    }
    assert_eq!(c.checks(), 2 * n as u64);
}
