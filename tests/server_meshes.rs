//! Mesh uploads (`PUT /v1/meshes/{name}`): a copy of the shipped pick-and-place scene, whose
//! statuette is a mesh, is refused with the way out ("upload it first") until its mesh is
//! uploaded, then accepted and drawn; names, formats, sizes and triangle counts are bounded, a
//! mesh may not refer to other files, and a mesh in use cannot be deleted.

mod common;

use common::server::{field, start, Harness};
use reqwest::StatusCode;
use serde_json::{json, Value};

async fn put_bytes(h: &Harness, path: &str, body: Vec<u8>) -> (StatusCode, Value) {
    let r = h
        .http
        .put(format!("{}{path}", h.base))
        .header("content-type", "application/octet-stream")
        .body(body)
        .send()
        .await
        .expect("PUT");
    let s = r.status();
    (s, r.json().await.unwrap_or(Value::Null))
}

async fn put_json(h: &Harness, path: &str, body: &Value) -> (StatusCode, Value) {
    let r = h
        .http
        .put(format!("{}{path}", h.base))
        .json(body)
        .send()
        .await
        .expect("PUT");
    let s = r.status();
    (s, r.json().await.unwrap_or(Value::Null))
}

async fn delete(h: &Harness, path: &str) -> (StatusCode, Value) {
    let r = h
        .http
        .delete(format!("{}{path}", h.base))
        .send()
        .await
        .expect("DELETE");
    let s = r.status();
    (s, r.json().await.unwrap_or(Value::Null))
}

/// A binary STL of a tetrahedron (4 triangles).
fn tetrahedron_stl() -> Vec<u8> {
    let v = [
        [0.0f32, 0.0, 0.0],
        [0.1, 0.0, 0.0],
        [0.0, 0.1, 0.0],
        [0.0, 0.0, 0.1],
    ];
    let faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let mut out = vec![0u8; 80];
    out.extend_from_slice(&(faces.len() as u32).to_le_bytes());
    for f in faces {
        out.extend_from_slice(&[0u8; 12]);
        for i in f {
            for c in v[i] {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        out.extend_from_slice(&[0u8; 2]);
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_with_a_mesh_is_uploaded_after_its_mesh() {
    let h = start("meshes").await;
    let root = common::root();
    let mut scene: Value = serde_json::from_str(
        &std::fs::read_to_string(root.join("scenes/pick_place.json")).expect("scene"),
    )
    .expect("json");
    scene["name"] = json!("x");
    let obj = std::fs::read(root.join("scenes/meshes/statuette.obj")).expect("mesh");

    // Without the mesh: 422 naming the shape's path and how to upload it.
    let (s, e) = put_json(&h, "/v1/scenes/x", &scene).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
    assert_eq!(field(&e), "objects[0].shapes[0].path", "{e}");
    let msg = e["error"]["message"].as_str().unwrap_or("");
    assert!(msg.contains("PUT /v1/meshes/statuette.obj"), "{msg}");

    let (s, v) = put_bytes(&h, "/v1/meshes/statuette.obj", obj.clone()).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert_eq!(v["triangles"], 1312, "{v}");
    assert_eq!(v["solid"], true, "{v}");
    let (s, _) = put_bytes(&h, "/v1/meshes/statuette.obj", obj.clone()).await;
    assert_eq!(s, StatusCode::OK, "replaced");
    let r = h
        .http
        .get(format!("{}/v1/meshes/statuette.obj", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), 200);
    assert_eq!(r.bytes().await.expect("bytes").as_ref(), obj.as_slice());

    let (s, v) = put_json(&h, "/v1/scenes/x", &scene).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert_eq!(v["objects"], 1, "{v}");
    let r = h
        .http
        .get(format!("{}/v1/scenes/x/meshes/objects/0/0", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), 200);
    let text = r.text().await.expect("obj");
    assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), 1312);

    // In use: not deleted (nor replaced by a mesh the scene does not validate with? it does:
    // any valid mesh validates, so a replacement is accepted and the scene rebuilt).
    let (s, e) = delete(&h, "/v1/meshes/statuette.obj").await;
    assert_eq!(s, StatusCode::CONFLICT, "{e}");
    let (s, v) = put_bytes(&h, "/v1/meshes/statuette.obj", tetrahedron_stl()).await;
    assert_eq!(s.as_u16() / 100, 4, "an STL under an .obj name: {v}");
    let (s, v) = put_bytes(&h, "/v1/meshes/tet.stl", tetrahedron_stl()).await;
    assert_eq!(s, StatusCode::CREATED, "{v}");
    assert_eq!(v["triangles"], 4, "{v}");
    let list = h
        .http
        .get(format!("{}/v1/meshes", h.base))
        .send()
        .await
        .expect("GET")
        .json::<Value>()
        .await
        .expect("json");
    let names: Vec<&str> = list
        .as_array()
        .expect("list")
        .iter()
        .filter_map(|m| m["name"].as_str())
        .collect();
    assert_eq!(names, ["statuette.obj", "tet.stl"], "{list}");
    let (s, _) = delete(&h, "/v1/scenes/x").await;
    assert_eq!(s, StatusCode::NO_CONTENT);
    let (s, _) = delete(&h, "/v1/meshes/statuette.obj").await;
    assert_eq!(s, StatusCode::NO_CONTENT);
    let (s, _) = delete(&h, "/v1/meshes/statuette.obj").await;
    assert_eq!(s, StatusCode::NOT_FOUND);
    h.server.shutdown().await.expect("shutdown");
}

/// Hostile mesh uploads are refused; then an uploaded robot's visual meshes
/// ([`an_uploaded_robots_visual_meshes_are_its_uploaded_meshes`]).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hostile_mesh_uploads_are_refused() {
    let h = start("meshes-hostile").await;
    // Names: a file name with a mesh extension, nothing else.
    for name in [".hidden.obj", "x.txt", "x", "a%2F..%2Fb.obj", "..obj"] {
        let (s, e) = put_bytes(&h, &format!("/v1/meshes/{name}"), tetrahedron_stl()).await;
        assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{name}: {e}");
        assert_eq!(field(&e), "name", "{name}: {e}");
    }
    // Not a mesh.
    let (s, e) = put_bytes(&h, "/v1/meshes/junk.obj", b"v 1 2\nf 1 2 9\nhello".to_vec()).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
    assert_eq!(field(&e), "body", "{e}");
    let (s, e) = put_bytes(&h, "/v1/meshes/empty.stl", Vec::new()).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
    // An OBJ that names a material file outside: never read, and never a 5xx.
    let mut obj = b"mtllib ../../../../../../etc/passwd\n".to_vec();
    obj.extend(std::fs::read(common::root().join("scenes/meshes/statuette.obj")).expect("mesh"));
    let (s, e) = put_bytes(&h, "/v1/meshes/mtl.obj", obj).await;
    assert!(
        s == StatusCode::CREATED || s == StatusCode::UNPROCESSABLE_ENTITY,
        "{s}: {e}"
    );
    // Too many triangles (the bound is 200 000).
    let mut many = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n");
    for _ in 0..200_001 {
        many.push_str("f 1 2 3\n");
    }
    let (s, e) = put_bytes(&h, "/v1/meshes/many.obj", many.into_bytes()).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap_or("")
            .contains("200000"),
        "{e}"
    );
    // Too large a body (the bound is 16 MiB): 413 before it is read.
    let (s, e) = put_bytes(&h, "/v1/meshes/big.stl", vec![b' '; (16 << 20) + 1]).await;
    assert_eq!(s, StatusCode::PAYLOAD_TOO_LARGE, "{e}");
    // Scenes may only name meshes inside the data folder.
    let scene = json!({"name": "y", "robots": [], "obstacles": [{"name": "o", "pose": {"position": [0, 0, 0]},
        "shapes": [{"type": "mesh", "path": "../../etc/passwd.obj"}]}], "objects": []});
    let (s, e) = put_json(&h, "/v1/scenes/y", &scene).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
    assert_eq!(field(&e), "obstacles[0].shapes[0].path", "{e}");
    let (s, e) = delete(&h, "/v1/meshes/nothing.obj").await;
    assert_eq!(s, StatusCode::NOT_FOUND, "{e}");
    an_uploaded_robots_visual_meshes_are_its_uploaded_meshes(&h).await;
    h.server.shutdown().await.expect("shutdown");
}

async fn get_text(h: &Harness, path: &str) -> (StatusCode, String) {
    let r = h
        .http
        .get(format!("{}{path}", h.base))
        .send()
        .await
        .expect("GET");
    let s = r.status();
    (s, r.text().await.unwrap_or_default())
}

/// An uploaded robot's visual geometry (URDF `<visual>`): listed by
/// `GET /v1/robots/{name}/visuals` with a URL per mesh, its meshes served as OBJ text from the
/// uploaded meshes it names as `meshes/NAME` and from nothing else; a visual that cannot be read
/// or whose mesh the server lacks is listed with the reason and never stops the robot loading.
/// (Run by [`hostile_mesh_uploads_are_refused`] on its server: one server start less.)
async fn an_uploaded_robots_visual_meshes_are_its_uploaded_meshes(h: &Harness) {
    let (s, e) = put_bytes(h, "/v1/meshes/tetra.stl", tetrahedron_stl()).await;
    assert_eq!(s, StatusCode::CREATED, "{e}");
    let urdf = r#"<robot name="vis">
      <link name="base">
        <visual><origin xyz="0 0 0.1" rpy="0 0 1.5707963267948966"/>
          <geometry><box size="0.2 0.4 0.6"/></geometry></visual>
        <visual><geometry><mesh filename="meshes/tetra.stl" scale="2 2 2"/></geometry></visual>
        <visual><geometry><mesh filename="meshes/absent.stl"/></geometry></visual>
        <visual><geometry><mesh filename="meshes/visual/link1.obj"/></geometry></visual>
        <visual><geometry><sphere radius="-1"/></geometry></visual>
        <collision><geometry><sphere radius="0.05"/></geometry></collision>
      </link>
      <link name="arm">
        <visual><geometry><cylinder radius="0.03" length="0.5"/></geometry></visual>
        <collision><geometry><cylinder radius="0.03" length="0.5"/></geometry></collision>
      </link>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
    </robot>"#;
    let (s, e) = put_json(h, "/v1/robots/vis", &json!({"urdf": urdf})).await;
    assert_eq!(s, StatusCode::CREATED, "{e}");

    let r = h
        .http
        .get(format!("{}/v1/robots/vis/visuals", h.base))
        .send()
        .await
        .expect("GET");
    assert_eq!(r.status(), StatusCode::OK);
    let v: Value = r.json().await.expect("json");
    let list = v["visuals"].as_array().expect("visuals");
    assert_eq!(list.len(), 6, "{v}");
    let item = |link: &str, i: u64| {
        list.iter()
            .find(|x| x["link"] == link && x["index"] == i)
            .unwrap_or_else(|| panic!("no {link}/{i} in {v}"))
    };
    let b = item("base", 0);
    assert_eq!(b["shape"]["type"], "box", "{b}");
    assert_eq!(b["shape"]["half_extents"], json!([0.1, 0.2, 0.3]), "{b}");
    assert_eq!(b["pose"]["position"], json!([0.0, 0.0, 0.1]), "{b}");
    let q = b["pose"]["quat_xyzw"].as_array().expect("quat");
    assert!(
        (q[2].as_f64().unwrap_or(0.0) - 0.5f64.sqrt()).abs() < 1e-9,
        "{b}"
    );
    assert!(b.get("problem").is_none(), "{b}");
    let m = item("base", 1);
    assert_eq!(m["shape"]["type"], "mesh", "{m}");
    assert!(m.get("problem").is_none(), "{m}");
    let url = m["shape"]["url"].as_str().expect("url");
    assert_eq!(url, "/v1/robots/vis/visuals/base/1");
    for (i, why) in [
        (2, "absent.stl"),
        (3, "meshes/NAME"),
        (4, "radius must be > 0"),
    ] {
        let x = item("base", i);
        let p = x["problem"].as_str().unwrap_or("");
        assert!(p.contains(why), "base/{i}: {x}");
    }
    assert_eq!(item("arm", 0)["shape"]["type"], "cylinder");

    // The mesh as OBJ text: the tetrahedron's 4 corners (written once each), scale applied.
    let (s, obj) = get_text(h, url).await;
    assert_eq!(s, StatusCode::OK, "{obj}");
    let verts: Vec<&str> = obj.lines().filter(|l| l.starts_with("v ")).collect();
    assert_eq!(verts.len(), 4, "{obj}");
    assert_eq!(obj.lines().filter(|l| l.starts_with("f ")).count(), 4);
    assert!(verts.contains(&"v 0.2 0 0"), "{obj}");
    // Nothing else is read: meshes the server lacks, non-mesh visuals, unknown links.
    for (path, want) in [
        ("/v1/robots/vis/visuals/base/2", StatusCode::NOT_FOUND),
        ("/v1/robots/vis/visuals/base/3", StatusCode::NOT_FOUND),
        ("/v1/robots/vis/visuals/base/0", StatusCode::NOT_FOUND),
        ("/v1/robots/vis/visuals/base/9", StatusCode::NOT_FOUND),
        ("/v1/robots/vis/visuals/base/x", StatusCode::NOT_FOUND),
        ("/v1/robots/vis/visuals/nolink/0", StatusCode::NOT_FOUND),
        ("/v1/robots/nobody/visuals", StatusCode::NOT_FOUND),
    ] {
        let (s, body) = get_text(h, path).await;
        assert_eq!(s, want, "{path}: {body}");
        assert!(body.contains("\"field\""), "{path}: {body}");
    }
    // A visual path leaving the data folder is refused like a collision one.
    let bad = urdf.replace("meshes/absent.stl", "../../etc/passwd.stl");
    let (s, e) = put_json(h, "/v1/robots/vis2", &json!({"urdf": bad})).await;
    assert_eq!(s, StatusCode::UNPROCESSABLE_ENTITY, "{e}");
}
