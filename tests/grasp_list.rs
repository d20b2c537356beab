//! Single-grasp lists (paper 003 §IV-A) of justin's four-finger hands on the shipped statuette:
//! every grasp is force closure with ε > 0 and free of its own hand under the exact checker
//! (fingertips may enter the object only at their contacts, within the list's contact
//! tolerance); the true mesh is used (a grasp the statuette's convex hull would refuse exists);
//! list files are refused when hand, object or parameters differ; lists are reproducible.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use manyhands::cache_tier::{MemoryTier, GRASPS};
use manyhands::collision::{
    BodyId, CollisionChecker, CollisionWorld, ExactChecker, StaticBody, StaticKind,
};
use manyhands::geometry::{Geometry, Mesh, Pose, Shape};
use manyhands::grasp::list::workspace_params;
use manyhands::grasp::list_cache::list_file_name;
use manyhands::grasp::{
    build_grasp_list, grasp_quality, load_grasp_list, mass_properties, save_grasp_list, separation,
    Contact, GraspList, GraspListCache, GraspListParams, GraspObject, Hand, ListFileError,
    WrenchSpaceSettings,
};
use manyhands::kinematics::link_pose;
use manyhands::model::Robot;
use nalgebra::{Point3, Vector3};
use parry3d_f64::math::{Pose as PPose, Rot3, Vector as PVector};
use parry3d_f64::query;
use parry3d_f64::shape::{ConvexPolyhedron, SharedShape};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn justin() -> Arc<Robot> {
    static R: OnceLock<Arc<Robot>> = OnceLock::new();
    R.get_or_init(|| {
        Arc::new(
            Robot::from_files(
                &root().join("robots/justin.urdf"),
                Some(&root().join("robots/justin.srdf")),
            )
            .expect("justin loads"),
        )
    })
    .clone()
}

fn statuette_mesh() -> Arc<Mesh> {
    Arc::new(Mesh::load(&root().join("scenes/meshes/statuette.obj"), [1.0; 3]).unwrap())
}

fn statuette() -> GraspObject {
    GraspObject::from_mesh_file(&root().join("scenes/meshes/statuette.obj")).unwrap()
}

fn hand(group: &str, params: &GraspListParams) -> Hand {
    Hand::new(justin(), group, None, &workspace_params(params)).unwrap()
}

/// The default list of a hand, built once per test binary.
fn default_list(group: &str) -> &'static GraspList {
    static L: OnceLock<GraspList> = OnceLock::new();
    static R: OnceLock<GraspList> = OnceLock::new();
    let cell = if group == "left_hand" { &L } else { &R };
    cell.get_or_init(|| {
        let p = GraspListParams::default();
        let l =
            build_grasp_list(&hand(group, &p), &statuette(), &p, &|_, _| {}, &|| false).unwrap();
        println!(
            "{group}: {} grasps in {:.2} s; stats {:?}",
            l.grasps.len(),
            l.stats.seconds,
            l.stats
        );
        l
    })
}

fn to_pp(p: &Pose) -> PPose {
    let t = p.translation.vector;
    let q = p.rotation.as_ref().coords;
    PPose::from_parts(
        PVector::new(t.x, t.y, t.z),
        Rot3::from_xyzw(q[0], q[1], q[2], q[3]),
    )
}

/// The URDF and SRDF of justin's subtree below `palm` (the hand alone), so the exact checker
/// sees only the hand.
fn hand_robot(palm: &str) -> Arc<Robot> {
    let urdf = std::fs::read_to_string(root().join("robots/justin.urdf")).unwrap();
    let srdf = std::fs::read_to_string(root().join("robots/justin.srdf")).unwrap();
    let doc = roxmltree::Document::parse(&urdf).unwrap();
    let robot = doc.root_element();
    let joints: Vec<roxmltree::Node> = robot
        .children()
        .filter(|n| n.has_tag_name("joint"))
        .collect();
    let child_of = |j: &roxmltree::Node, tag: &str| {
        j.children()
            .find(|c| c.has_tag_name(tag))
            .and_then(|c| c.attribute("link"))
            .unwrap_or("")
            .to_string()
    };
    let mut links = vec![palm.to_string()];
    let mut keep_joints = Vec::new();
    loop {
        let before = links.len();
        for j in &joints {
            let (p, c) = (child_of(j, "parent"), child_of(j, "child"));
            if links.contains(&p) && !links.contains(&c) {
                links.push(c);
                keep_joints.push(*j);
            }
        }
        if links.len() == before {
            break;
        }
    }
    let text = |n: &roxmltree::Node| urdf[n.range()].to_string();
    let mut out = String::from("<robot name=\"hand\">\n");
    for l in robot.children().filter(|n| n.has_tag_name("link")) {
        if links
            .iter()
            .any(|k| Some(k.as_str()) == l.attribute("name"))
        {
            out += &text(&l);
            out += "\n";
        }
    }
    for j in &keep_joints {
        out += &text(j);
        out += "\n";
    }
    out += "</robot>\n";
    let sdoc = roxmltree::Document::parse(&srdf).unwrap();
    let mut s = String::from("<robot name=\"hand\">\n");
    for d in sdoc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("disable_collisions"))
    {
        let (a, b) = (d.attribute("link1").unwrap(), d.attribute("link2").unwrap());
        if links.iter().any(|l| l == a) && links.iter().any(|l| l == b) {
            s += &srdf[d.range()];
            s += "\n";
        }
    }
    s += "</robot>\n";
    Arc::new(Robot::from_strings(&out, Some(&s), root()).unwrap())
}

/// Every grasp: ≥ 3 contacts, thumb first, contacts on the surface, force closure with ε > 0,
/// its fingertips at the contacts; the hand alone under the exact checker is free of itself and
/// of the statuette except the contact links, which enter it by at most the tolerance.
fn check_list(group: &str) {
    let l = default_list(group);
    assert!(!l.grasps.is_empty(), "{group}: no grasp");
    let full = justin();
    let palm = &l.palm_link;
    let hr = hand_robot(palm);
    let mesh = statuette_mesh();
    let solid = mesh.solid.as_ref().unwrap().clone();
    let tm = SharedShape::trimesh(
        solid
            .vertices
            .iter()
            .map(|v| PVector::new(v.x, v.y, v.z))
            .collect(),
        solid.triangles.clone(),
    )
    .unwrap();
    let object = statuette();
    let settings = WrenchSpaceSettings {
        mu: l.params.mu,
        cone_edges: l.params.cone_edges,
        lambda: Some(1.0 / object.radius),
        soft_finger: None,
    };
    let body = StaticBody {
        name: "statuette".into(),
        kind: StaticKind::Object,
        pose: Pose::identity(),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Mesh(mesh.clone()),
        }],
    };
    let h = hand(group, &l.params);
    let thumb = &h.fingers[0].group;
    for (gi, g) in l.grasps.iter().enumerate() {
        assert!(g.contacts.len() >= 3, "grasp {gi}");
        assert_eq!(&g.contacts[0].finger, thumb, "grasp {gi}: thumb first");
        let contacts: Vec<Contact> = g
            .contacts
            .iter()
            .map(|c| Contact::new(Vector3::from(c.point), Vector3::from(c.normal)))
            .collect();
        let q = grasp_quality(&contacts, &object.centre, &settings).unwrap();
        assert!(q.force_closure && q.epsilon > 0.0, "grasp {gi}: {q:?}");
        assert!((q.epsilon - g.epsilon).abs() < 1e-9);
        // Hand configuration on the hand robot.
        let mut qh = hr.zero_config();
        for (name, v) in l.joints.iter().zip(&g.config) {
            let var = hr.var(name).unwrap();
            assert!(hr.var_limits(var).contains(*v), "grasp {gi}: {name} = {v}");
            qh[var] = *v;
        }
        let palm_pose = g.palm_pose();
        let mut world = CollisionWorld::single(hr.clone(), palm_pose);
        world.statics = vec![body.clone()];
        let mut touching = Vec::new();
        for c in &g.contacts {
            let f = h.fingers.iter().find(|f| f.group == c.finger).unwrap();
            let link = hr.link(&full.links[f.contact_link].name).unwrap();
            touching.push(link);
            world.allow(BodyId::Link { robot: 0, link }, BodyId::Static(0));
            // The contact link touches the contact point (within the tolerance), on the surface.
            let p = Vector3::from(c.point);
            let lp = palm_pose * link_pose(&hr, &qh, link);
            let gap = hr.links[link]
                .collision
                .iter()
                .filter_map(|g2| {
                    let Shape::Box { half_extents: he } = &g2.shape else {
                        return None;
                    };
                    let bx = SharedShape::cuboid(he.x, he.y, he.z);
                    Some(query::PointQuery::distance_to_point(
                        &*bx,
                        &to_pp(&(lp * g2.origin)),
                        PVector::new(p.x, p.y, p.z),
                        true,
                    ))
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                gap <= l.params.contact_tolerance + 1e-6,
                "grasp {gi}: contact {gap} m from its finger"
            );
            let proj = query::PointQuery::project_point(
                &*tm,
                &PPose::IDENTITY,
                PVector::new(p.x, p.y, p.z),
                false,
            );
            let d = (PVector::new(p.x, p.y, p.z) - proj.point).length();
            assert!(d < 1e-6, "grasp {gi}: contact {d} m off the surface");
        }
        let mut exact = ExactChecker::new(&world);
        assert!(
            exact.is_free(&qh),
            "grasp {gi}: the hand collides with itself or the statuette"
        );
        // The contact links: within the tolerance of the surface, never inside.
        for &link in &touching {
            let lp = palm_pose * link_pose(&hr, &qh, link);
            for g2 in &hr.links[link].collision {
                let Shape::Box { half_extents: he } = &g2.shape else {
                    continue;
                };
                let bx = SharedShape::cuboid(he.x, he.y, he.z);
                let w = lp * g2.origin;
                if let Some(c) =
                    query::contact(&PPose::IDENTITY, &*tm, &to_pp(&w), &*bx, 0.0).unwrap()
                {
                    assert!(
                        -c.dist <= l.params.contact_tolerance + 1e-9,
                        "grasp {gi}: {} m deep",
                        -c.dist
                    );
                }
                let centre = w.translation.vector;
                assert!(
                    !solid.contains(&centre),
                    "grasp {gi}: a fingertip inside the statuette"
                );
            }
        }
    }
}

#[test]
fn every_left_hand_grasp_is_force_closure_and_free_of_its_hand() {
    check_list("left_hand");
}

#[test]
fn every_right_hand_grasp_is_force_closure_and_free_of_its_hand() {
    check_list("right_hand");
}

/// Paper 003 §VI: 17 grasps in the right hand's list, 22 in the left's. The default lists hold
/// at least as many force-closure grasps (each re-checked by `check_list`), no two of them
/// near-duplicates (same fingers, palm origin and every contact within the list's
/// near-duplicate distance, a fingertip's width), with the object's centre and torque scale of
/// the solid (the union of the statuette's overlapping parts).
#[test]
fn default_lists_are_as_rich_as_the_papers_and_hold_no_near_duplicates() {
    let m = mass_properties(&statuette().geometry);
    for (group, paper) in [("right_hand", 17), ("left_hand", 22)] {
        let l = default_list(group);
        assert!(
            l.grasps.len() >= paper,
            "{group}: {} grasps, paper 003 has {paper}; stats {:?}",
            l.grasps.len(),
            l.stats
        );
        let d = l.stats.min_separation;
        assert!((d - 2.0 * 0.008).abs() < 1e-12, "a fingertip's width: {d}");
        for (i, a) in l.grasps.iter().enumerate() {
            assert!(a.epsilon > 0.0);
            for (j, b) in l.grasps.iter().enumerate().skip(i + 1) {
                let s = separation(a, b);
                assert!(s >= d, "{group}: grasps {i} and {j} {s} m apart");
            }
        }
        let sets: std::collections::BTreeSet<Vec<&str>> = l
            .grasps
            .iter()
            .map(|g| g.contacts.iter().map(|c| c.finger.as_str()).collect())
            .collect();
        assert!(sets.len() >= 2, "{group}: one finger set only");
        assert_eq!(Vector3::from(l.centre), m.centre);
        assert_eq!(l.radius, m.radius);
    }
}

/// The near-duplicate rule is enforced in the list: a larger distance drops grasps that the
/// default keeps, and what remains keeps that distance pairwise.
#[test]
fn near_duplicates_are_dropped_in_quality_order() {
    let p = GraspListParams {
        min_separation: Some(0.1),
        ..Default::default()
    };
    let h = hand("left_hand", &p);
    let l = build_grasp_list(&h, &statuette(), &p, &|_, _| {}, &|| false).unwrap();
    let all = default_list("left_hand");
    assert!(l.stats.duplicates > 0, "{:?}", l.stats);
    assert_eq!(l.grasps.len() + l.stats.duplicates, l.stats.force_closure);
    assert_eq!(l.stats.force_closure, all.stats.force_closure);
    assert!(l.grasps.len() < all.grasps.len());
    // The best grasp is never a duplicate of a better one.
    assert_eq!(l.grasps[0], all.grasps[0]);
    for (i, a) in l.grasps.iter().enumerate() {
        for b in &l.grasps[i + 1..] {
            assert!(separation(a, b) >= 0.1);
        }
    }
}

#[test]
fn a_grasp_exists_that_the_convex_hull_would_refuse() {
    let l = default_list("left_hand");
    let mesh = statuette_mesh();
    let hull = ConvexPolyhedron::from_convex_hull(
        &mesh
            .vertices
            .iter()
            .map(|v| PVector::new(v.x, v.y, v.z))
            .collect::<Vec<_>>(),
    )
    .unwrap();
    let hr = hand_robot(&l.palm_link);
    let mut deepest = 0.0f64;
    let mut refused = 0;
    for g in &l.grasps {
        let mut qh = hr.zero_config();
        for (name, v) in l.joints.iter().zip(&g.config) {
            qh[hr.var(name).unwrap()] = *v;
        }
        let palm = g.palm_pose();
        let mut worst = 0.0f64;
        for (li, link) in hr.links.iter().enumerate() {
            let lp = palm * link_pose(&hr, &qh, li);
            for g2 in &link.collision {
                let Shape::Box { half_extents: he } = &g2.shape else {
                    continue;
                };
                let bx = SharedShape::cuboid(he.x, he.y, he.z);
                if let Some(c) = query::contact(
                    &PPose::IDENTITY,
                    &hull,
                    &to_pp(&(lp * g2.origin)),
                    &*bx,
                    0.0,
                )
                .unwrap()
                {
                    worst = worst.max(-c.dist);
                }
            }
        }
        deepest = deepest.max(worst);
        // Deeper than a contact may go: the hull would call this grasp colliding.
        if worst > 0.005 {
            refused += 1;
        }
    }
    println!("{refused} of {} grasps enter the statuette's convex hull by more than 5 mm (deepest {deepest:.3} m)", l.grasps.len());
    assert!(refused > 0);
}

#[test]
fn list_files_are_refused_when_hand_object_or_parameters_differ() {
    let p = GraspListParams {
        positions: 8,
        ..Default::default()
    };
    let left = hand("left_hand", &p);
    let obj = statuette();
    let l = build_grasp_list(&left, &obj, &p, &|_, _| {}, &|| false).unwrap();
    let dir = common::tmp::run_root().join(format!("manyhands-grasp-list-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("left.grasps.json");
    save_grasp_list(&l, &file).unwrap();
    // Same hand, object, parameters: served, unchanged.
    assert_eq!(load_grasp_list(&file, &left, &obj, &p).unwrap(), l);
    let what = |r: Result<GraspList, ListFileError>| match r {
        Err(ListFileError::Mismatch { what, .. }) => what,
        other => panic!("expected a mismatch, got {other:?}"),
    };
    // Another hand.
    assert_eq!(
        what(load_grasp_list(&file, &hand("right_hand", &p), &obj, &p)),
        "hand"
    );
    // The same hand of a changed model (a finger joint limit moved).
    let urdf = std::fs::read_to_string(root().join("robots/justin.urdf")).unwrap();
    let srdf = std::fs::read_to_string(root().join("robots/justin.srdf")).unwrap();
    let changed = urdf.replacen(
        r#"<limit lower="-0.35" upper="0.35" velocity="2" effort="5"/>"#,
        r#"<limit lower="-0.30" upper="0.35" velocity="2" effort="5"/>"#,
        1,
    );
    assert_ne!(changed, urdf);
    let r2 = Arc::new(Robot::from_strings(&changed, Some(&srdf), root()).unwrap());
    let left2 = Hand::new(r2, "left_hand", None, &workspace_params(&p)).unwrap();
    assert_eq!(what(load_grasp_list(&file, &left2, &obj, &p)), "hand");
    // Another object: the statuette scaled by 1.1.
    let m = Mesh::load(&root().join("scenes/meshes/statuette.obj"), [1.1; 3]).unwrap();
    let bigger = GraspObject::new(
        "statuette",
        vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Mesh(Arc::new(m)),
        }],
    )
    .unwrap();
    assert_eq!(what(load_grasp_list(&file, &left, &bigger, &p)), "object");
    // Other parameters.
    for q in [
        GraspListParams {
            seed: 2,
            ..p.clone()
        },
        GraspListParams {
            mu: 0.6,
            ..p.clone()
        },
        GraspListParams {
            weights: [1.0, 1.0, 1.0, 5.0],
            ..p.clone()
        },
    ] {
        assert_eq!(what(load_grasp_list(&file, &left, &obj, &q)), "parameters");
    }
    // A damaged file: a clear format error.
    std::fs::write(&file, b"{\"format\": \"something else\"}").unwrap();
    let e = load_grasp_list(&file, &left, &obj, &p).unwrap_err();
    assert!(matches!(e, ListFileError::Format { .. }), "{e}");
    assert!(e.to_string().contains("not a manyhands grasp list"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_list_is_reproducible_and_bad_parameters_name_their_field() {
    let p = GraspListParams {
        positions: 8,
        seed: 5,
        ..Default::default()
    };
    let h = hand("right_hand", &p);
    let obj = statuette();
    let a = build_grasp_list(&h, &obj, &p, &|_, _| {}, &|| false).unwrap();
    let b = build_grasp_list(&h, &obj, &p, &|_, _| {}, &|| false).unwrap();
    assert_eq!(a.grasps, b.grasps);
    for (q, field) in [
        (
            GraspListParams {
                positions: 0,
                ..p.clone()
            },
            "positions",
        ),
        (
            GraspListParams {
                orientation_level: 9,
                ..p.clone()
            },
            "orientation_level",
        ),
        (
            GraspListParams {
                mu: -1.0,
                ..p.clone()
            },
            "mu",
        ),
        (
            GraspListParams {
                weights: [1.0, f64::NAN, 1.0, 1.0],
                ..p.clone()
            },
            "weights[1]",
        ),
        (
            GraspListParams {
                contact_tolerance: 0.5,
                ..p.clone()
            },
            "contact_tolerance",
        ),
        (
            GraspListParams {
                thumb_contacts: 0,
                ..p.clone()
            },
            "thumb_contacts",
        ),
        (
            GraspListParams {
                min_separation: Some(-0.01),
                ..p.clone()
            },
            "min_separation",
        ),
    ] {
        let e = build_grasp_list(&h, &obj, &q, &|_, _| {}, &|| false).unwrap_err();
        assert_eq!(e.field(), field, "{e}");
    }
    // A stop ends the build.
    let e = build_grasp_list(&h, &obj, &p, &|_, _| {}, &|| true).unwrap_err();
    assert_eq!(e, manyhands::grasp::GraspListError::Stopped);
    let _ = Point3::<f64>::origin();
}

/// Two list caches with their own folders and one shared tier (two server replicas): the
/// first builds the list and publishes it, the second fetches it (`find` too) instead of
/// building; an entry of the tier that does not load is rebuilt, not served, and replaced.
#[test]
fn list_caches_sharing_a_tier_build_a_list_once() {
    let p = GraspListParams {
        positions: 8,
        seed: 3,
        ..Default::default()
    };
    let h = hand("left_hand", &p);
    let obj = statuette();
    let dirs: Vec<_> = (1..=3)
        .map(|i| {
            let d = common::tmp::run_root()
                .join(format!("manyhands-grasp-tier-{}-{i}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            d
        })
        .collect();
    let tier = Arc::new(MemoryTier::new());
    let counts = |t: &MemoryTier| (t.fetches(), t.misses(), t.publishes(), t.replaces());
    let none = |_: usize, _: usize| {};
    let a = GraspListCache::new(Some(dirs[0].clone())).with_tier(tier.clone());
    let (la, built) = a.get_or_build(&h, &obj, &p, &none, &|| false).unwrap();
    assert!(built);
    assert_eq!(counts(&tier), (0, 1, 1, 0));
    let name = list_file_name(&h, &obj, &p);
    assert_eq!(tier.names(GRASPS), [name.as_str()]);
    // In memory: the tier is not asked.
    let (again, built) = a.get_or_build(&h, &obj, &p, &none, &|| false).unwrap();
    assert!(!built && Arc::ptr_eq(&again, &la));
    assert_eq!(counts(&tier), (0, 1, 1, 0));

    // "Process 2": an empty folder, the same tier. `find` (which never builds) fetches it.
    let b = GraspListCache::new(Some(dirs[1].clone()));
    assert!(b.set_tier(tier.clone()));
    let lb = b.find(&h, &obj, &p).expect("fetched");
    assert_eq!(counts(&tier), (1, 1, 1, 0), "fetched, not built");
    assert_eq!(*lb, *la);
    let (lb2, built) = b.get_or_build(&h, &obj, &p, &none, &|| false).unwrap();
    assert!(!built && Arc::ptr_eq(&lb, &lb2));
    assert_eq!(counts(&tier), (1, 1, 1, 0));

    // A damaged entry is not served: rebuilt (the same grasps) and replaced.
    tier.insert(GRASPS, &name, b"{\"format\": \"something else\"}".to_vec());
    let c = GraspListCache::new(Some(dirs[2].clone())).with_tier(tier.clone());
    assert!(c.find(&h, &obj, &p).is_none());
    let (lc, built) = c.get_or_build(&h, &obj, &p, &none, &|| false).unwrap();
    assert!(built);
    assert_eq!(lc.grasps, la.grasps);
    assert_eq!((tier.publishes(), tier.replaces()), (1, 1));
    assert_eq!(
        tier.get(GRASPS, &name).unwrap(),
        std::fs::read(dirs[2].join(&name)).unwrap()
    );
    for d in &dirs {
        let _ = std::fs::remove_dir_all(d);
    }
}

mod common;

/// Over HTTP: a `grasp_list` job builds a small list (the answer names its id and best grasps),
/// `GET /v1/grasp-lists[/{id}]` serves it, and bad input is a 4xx naming the field.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grasp_lists_over_http() {
    use common::server::{field, start};
    use serde_json::{json, Value};
    let h = start("grasp-list").await;
    let ok = json!({"kind": "grasp_list", "robot": "justin", "hand": "left_hand",
        "mesh": "statuette", "params": {"positions": 27, "mu": 1.0}});
    let (s, job) = h.post("/v1/plans?wait=60", &ok).await;
    assert!(s.is_success(), "{s} {job}");
    assert_eq!(job["state"], "succeeded", "{job}");
    let r = &job["result"];
    let id = r["id"].as_str().unwrap().to_string();
    assert!(r["grasps"].as_u64().unwrap() > 0, "{r}");
    assert_eq!(r["built"], true);
    // The same request again: served from the cache.
    let (_, again) = h.post("/v1/plans?wait=60", &ok).await;
    assert_eq!(again["result"]["built"], false, "{again}");
    assert_eq!(again["result"]["id"], json!(id));
    let get = |path: String| {
        let http = h.http.clone();
        let base = h.base.clone();
        async move {
            let r = http.get(format!("{base}{path}")).send().await.unwrap();
            let s = r.status();
            (s, r.json::<Value>().await.unwrap_or(Value::Null))
        }
    };
    let (s, index) = get("/v1/grasp-lists".into()).await;
    assert!(s.is_success());
    assert!(
        index["lists"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| l["id"] == json!(id)),
        "{index}"
    );
    let (s, list) = get(format!("/v1/grasp-lists/{id}")).await;
    assert!(s.is_success());
    assert_eq!(
        list["grasps"].as_array().unwrap().len() as u64,
        r["grasps"].as_u64().unwrap()
    );
    assert!(list["grasps"][0]["epsilon"].as_f64().unwrap() > 0.0);
    let (s, e) = get("/v1/grasp-lists/nope".into()).await;
    assert_eq!((s.as_u16(), field(&e).as_str()), (404, "id"), "{e}");
    let (s, e) = get("/v1/grasp-lists/..%2Fx".into()).await;
    assert!(s.is_client_error(), "{s}");
    let _ = e;
    // Bad input: 4xx naming the field.
    let with = |patch: Value| {
        let mut b = ok.clone();
        for (k, v) in patch.as_object().unwrap() {
            if v.is_null() {
                b.as_object_mut().unwrap().remove(k);
            } else {
                b[k] = v.clone();
            }
        }
        b
    };
    for (body, want) in [
        (with(json!({"robot": "nobody"})), "robot"),
        (with(json!({"hand": "left_arm_x"})), "hand"),
        (with(json!({"hand": "left_arm"})), "hand"),
        (with(json!({"mesh": "no_such_mesh"})), "mesh"),
        (with(json!({"mesh": "../robots/justin"})), "mesh"),
        (with(json!({"mesh": null})), "mesh"),
        (with(json!({"mesh": null, "scene": "kitchen"})), "object"),
        (
            with(json!({"mesh": null, "scene": "kitchen", "object": "nothing"})),
            "object",
        ),
        (
            with(json!({"params": {"positions": 0}})),
            "params.positions",
        ),
        (
            with(json!({"params": {"orientation_level": 7}})),
            "params.orientation_level",
        ),
        (with(json!({"params": {"mu": -0.5}})), "params.mu"),
        (
            with(json!({"params": {"thumb_contacts": 0}})),
            "params.thumb_contacts",
        ),
        (
            with(json!({"params": {"min_separation": 0.5}})),
            "params.min_separation",
        ),
        (
            with(json!({"params": {"weights": [1, 1, 1, -6]}})),
            "params.weights[3]",
        ),
        (
            with(json!({"params": {"fingers": ["left_pinky"]}})),
            "params.fingers",
        ),
        (with(json!({"params": {"colour": 1}})), "params"),
        (with(json!({"time_limit": -1})), "time_limit"),
    ] {
        let (s, e) = h.post("/v1/plans", &body).await;
        assert!(s.is_client_error(), "{body}: {s} {e}");
        let f = field(&e);
        assert!(
            f.starts_with(want),
            "{body}: field '{f}', expected '{want}': {e}"
        );
    }
    h.server.shutdown().await.unwrap();
}

/// Double grasps (003 §IV-B): the right hand picks the statuette from a table, the left places it
/// on another; grasps whose hand would enter a table are filtered out, pairs whose hands collide
/// are refused, scores are the normalised min quality + normalised min approach score.
#[test]
fn double_grasps_filter_the_environment_and_hand_collisions() {
    use manyhands::grasp::double_grasp::{double_grasps, DoubleGraspParams};
    use nalgebra::{Translation3, UnitQuaternion};
    // Richer lists than the defaults': μ = 1.
    let p = GraspListParams {
        mu: 1.0,
        ..Default::default()
    };
    let (hr, hl) = (hand("right_hand", &p), hand("left_hand", &p));
    let obj = statuette();
    let right = &build_grasp_list(&hr, &obj, &p, &|_, _| {}, &|| false).unwrap();
    let left = &build_grasp_list(&hl, &obj, &p, &|_, _| {}, &|| false).unwrap();
    let at = |x: f64, y: f64, z: f64| {
        Pose::from_parts(Translation3::new(x, y, z), UnitQuaternion::identity())
    };
    let table = |name: &str, pose: Pose| StaticBody {
        name: name.into(),
        kind: StaticKind::Obstacle,
        pose,
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Box {
                half_extents: Vector3::new(0.3, 0.3, 0.02),
            },
        }],
    };
    let initial = at(0.6, -0.4, 0.8);
    let final_pose = at(0.6, 0.4, 0.8);
    let env = vec![
        table("right_table", at(0.6, -0.4, 0.78)),
        table("left_table", at(0.6, 0.4, 0.78)),
    ];
    let base = Vector3::new(0.0, 0.0, 0.8);
    let r = double_grasps(
        (&hr, right),
        (&hl, left),
        &env,
        &initial,
        &final_pose,
        &base,
        &DoubleGraspParams::default(),
    );
    println!(
        "double grasps: {} of {} right grasps free at the initial pose, {} of {} left at the final; {} pairs tested, {} hand collisions, {} kept",
        r.pick_free.len(), right.grasps.len(), r.place_free.len(), left.grasps.len(), r.pairs_tested, r.hand_collisions, r.grasps.len()
    );
    assert!(
        r.pick_free.len() < right.grasps.len(),
        "the table removes some grasps"
    );
    assert!(!r.pick_free.is_empty() && !r.place_free.is_empty());
    assert_eq!(r.pairs_tested, r.pick_free.len() * r.place_free.len());
    let params = DoubleGraspParams::default();
    assert_eq!(
        r.grasps.len(),
        (r.pairs_tested - r.hand_collisions).min(params.max_results)
    );
    assert!(!r.grasps.is_empty());
    // Independent re-check with the exact checker: both hands on the object at the final pose,
    // no pair between them colliding; each hand free of its table.
    let right_hand = hand_robot(&right.palm_link);
    let left_hand = hand_robot(&left.palm_link);
    let config = |hr: &Arc<Robot>, l: &GraspList, g: usize| {
        let mut q = hr.zero_config();
        for (n, v) in l.joints.iter().zip(&l.grasps[g].config) {
            q[hr.var(n).unwrap()] = *v;
        }
        q
    };
    for (k, d) in r.grasps.iter().take(50).enumerate() {
        assert!(d.score >= 0.0 && d.score <= 2.0 + 1e-12);
        if k > 0 {
            assert!(r.grasps[k - 1].score >= d.score);
        }
        let (gr, gl) = (&right.grasps[d.pick], &left.grasps[d.place]);
        assert!((d.quality - gr.quality.min(gl.quality)).abs() < 1e-12);
        let mut w = CollisionWorld::single(right_hand.clone(), initial * gr.palm_pose());
        w.statics = env.clone();
        let qr = config(&right_hand, right, d.pick);
        assert!(
            ExactChecker::new(&w).is_free(&qr),
            "pair {k}: the right hand enters a table"
        );
        let mut w2 = CollisionWorld::single(left_hand.clone(), final_pose * gl.palm_pose());
        w2.statics = env.clone();
        let ql = config(&left_hand, left, d.place);
        assert!(
            ExactChecker::new(&w2).is_free(&ql),
            "pair {k}: the left hand enters a table"
        );
        // Both hands on the object: a two-robot world.
        let mut both = CollisionWorld::single(right_hand.clone(), gr.palm_pose());
        both.robots.push(manyhands::collision::PlacedRobot {
            name: "left".into(),
            robot: left_hand.clone(),
            base: gl.palm_pose(),
            offset: right_hand.dof(),
        });
        let mut q = qr.clone();
        q.extend(&ql);
        assert!(
            ExactChecker::new(&both).is_free(&q),
            "pair {k}: the hands collide"
        );
    }
}
