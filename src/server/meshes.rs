//! Meshes: `PUT/GET/DELETE /v1/meshes/{name}` and `GET /v1/meshes` (uploaded STL, OBJ and
//! COLLADA files that uploaded scenes name as `meshes/NAME`), and
//! `GET /v1/scenes/{name}/meshes/{list}/{index}/{shape}`: a scene's mesh shape as the server
//! loaded it, as OBJ text (what the viewer draws; it reads only what the scene holds, never a
//! file named by the request).

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use crate::geometry::Shape;
use crate::model::VisualGeometry;

use super::catalog::MeshSummary;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::AppState;

#[utoipa::path(get, path = "/v1/meshes", tag = "resources",
    responses((status = 200, body = [MeshSummary], description = "the uploaded meshes"),
              (status = 503, body = ErrorBody, description = "overloaded (the query pool is full); see `Retry-After`")))]
pub async fn list_meshes(State(st): State<Arc<AppState>>) -> ApiResult<Json<Vec<MeshSummary>>> {
    let st2 = st.clone();
    Ok(Json(st.pool.run(move || Ok(st2.catalog.meshes())).await?))
}

#[utoipa::path(get, path = "/v1/meshes/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, description = "the mesh file as uploaded", content_type = "application/octet-stream", body = Vec<u8>),
              (status = 404, body = ErrorBody),
              (status = 503, body = ErrorBody, description = "overloaded (the query pool is full); see `Retry-After`")))]
pub async fn get_mesh(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<Response> {
    let st2 = st.clone();
    let n = name.clone();
    let bytes = st.pool.run(move || st2.catalog.mesh_bytes(&n)).await?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

/// Uploads a mesh file (the raw bytes of an STL, OBJ or COLLADA file; the name's extension
/// gives the format). An uploaded scene refers to it as `meshes/NAME` in a shape's `path`.
#[utoipa::path(put, path = "/v1/meshes/{name}", tag = "resources", params(("name" = String, Path, description = "file name ending in .stl, .obj or .dae")),
    request_body(content = Vec<u8>, content_type = "application/octet-stream", description = "the mesh file (at most 16 MiB and 200 000 triangles; an OBJ may not refer to material files)"),
    responses((status = 201, body = MeshSummary, description = "created"), (status = 200, body = MeshSummary, description = "replaced"),
              (status = 409, body = ErrorBody, description = "an uploaded scene using it does not validate with the new one"),
              (status = 413, body = ErrorBody, description = "body over the server's limit"),
              (status = 422, body = ErrorBody, description = "bad name, unreadable mesh or too many triangles; `field` is `name` or `body`")))]
pub async fn put_mesh(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
    body: Result<Bytes, BytesRejection>,
) -> ApiResult<Response> {
    let body = body.map_err(|e| {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                "body_too_large",
                e.body_text(),
            )
            .at("body")
        } else {
            ApiError::bad_request(format!("cannot read the body: {}", e.body_text())).at("body")
        }
    })?;
    super::catalog::check_mesh_name(&name)?;
    let st2 = st.clone();
    let n = name.clone();
    let bytes = body.to_vec();
    let (created, summary) = st
        .pool
        .run_heavy(move || st2.catalog.put_mesh(&n, &bytes))
        .await?;
    super::shared::publish(&st, "mesh", &name, body.to_vec()).await?;
    tracing::info!(mesh = %name, created, triangles = ?summary.triangles, "mesh uploaded");
    let status = if created {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    Ok((status, Json(summary)).into_response())
}

#[utoipa::path(delete, path = "/v1/meshes/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 204), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody, description = "an uploaded scene uses it")))]
pub async fn delete_mesh(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<StatusCode> {
    let st2 = st.clone();
    let n = name.clone();
    st.pool.run(move || st2.catalog.delete_mesh(&n)).await?;
    super::shared::unpublish(&st, "mesh", &name).await?;
    Ok(StatusCode::NO_CONTENT)
}

/// One mesh shape of a scene as OBJ text: shape `shape` of body `index` of `list`
/// (`obstacles` or `objects`), in the shape's frame with its scale applied.
#[utoipa::path(get, path = "/v1/scenes/{name}/meshes/{list}/{index}/{shape}", tag = "resources",
    params(("name" = String, Path), ("list" = String, Path, description = "obstacles or objects"),
           ("index" = usize, Path, description = "the body's index in the list"), ("shape" = usize, Path, description = "the shape's index in the body")),
    responses((status = 200, content_type = "model/obj", body = String, description = "Wavefront OBJ text"),
              (status = 404, body = ErrorBody, description = "no such scene, body or mesh shape"),
              (status = 503, body = ErrorBody, description = "overloaded (the query pool is full); see `Retry-After`")))]
pub async fn scene_mesh(
    State(st): State<Arc<AppState>>,
    Path((name, list, index, shape)): Path<(String, String, String, String)>,
) -> ApiResult<Response> {
    let e = st.catalog.scene(&name, "name")?;
    let s = &e.scene;
    let body = match list.as_str() {
        "obstacles" => index.parse::<usize>().ok().and_then(|i| s.obstacles.get(i)),
        "objects" => index
            .parse::<usize>()
            .ok()
            .and_then(|i| s.objects.get(i))
            .map(|o| &o.body),
        _ => {
            return Err(ApiError::not_found(
                "list",
                format!("'{list}' is not a body list (obstacles, objects)"),
            ))
        }
    };
    let body = body.ok_or_else(|| {
        ApiError::not_found("index", format!("scene '{name}' has no {list}[{index}]"))
    })?;
    let mesh = shape
        .parse::<usize>()
        .ok()
        .and_then(|k| body.shapes.get(k))
        .and_then(|g| match &g.shape {
            Shape::Mesh(m) => Some(m.clone()),
            _ => None,
        })
        .ok_or_else(|| {
            ApiError::not_found(
                "shape",
                format!(
                    "{list}[{index}] ('{}') has no mesh shape {shape}",
                    body.name
                ),
            )
        })?;
    let text = st.pool.run(move || Ok(mesh.to_obj())).await?;
    Ok((
        [
            (header::CONTENT_TYPE, "model/obj; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        text,
    )
        .into_response())
}

/// One `<visual>` element of a robot's link, as `GET /v1/robots/{name}/visuals` lists it.
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct VisualItem {
    /// The link it belongs to.
    pub link: String,
    /// Its index among the link's `<visual>` elements.
    pub index: usize,
    /// Pose of the geometry in the link frame: `position` (m) and `quat_xyzw`.
    #[schema(value_type = Object)]
    pub pose: crate::geometry::PoseJson,
    /// The geometry in the scene format's shape fields: `box` (`half_extents`), `cylinder` and
    /// `capsule` (`radius`, `length` along z), `sphere` (`radius`), `mesh` (`url`: the mesh as
    /// OBJ text in the geometry frame, scale applied; `filename` as the URDF writes it).
    /// Absent when the element cannot be drawn.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<VisualShape>,
    /// Why it cannot be drawn (an unreadable element, a mesh file the server does not have).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub problem: Option<String>,
}

/// The drawable geometry of a [`VisualItem`].
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct VisualShape {
    /// `box`, `cylinder`, `capsule`, `sphere` or `mesh`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_extents: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub filename: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub url: Option<String>,
}

/// A robot's visual geometry.
#[derive(Debug, Clone, serde::Serialize, utoipa::ToSchema)]
pub struct RobotVisuals {
    pub robot: String,
    /// Every `<visual>` element of every link, links in tree order.
    pub visuals: Vec<VisualItem>,
}

/// Where a visual mesh's bytes are.
enum VisualSource {
    /// A file of a built-in robot's folder, located when the robot was loaded.
    File(std::path::PathBuf),
    /// An uploaded mesh (`PUT /v1/meshes/NAME`), named `meshes/NAME` by an uploaded robot.
    Upload(String),
}

/// Where the mesh of a visual is, or why the server has none. An uploaded robot's visual meshes
/// are only ever uploaded meshes (`meshes/NAME`): nothing else of the server's files is read
/// for it. A built-in robot's are the files its URDF named, found next to it at load.
fn visual_source(
    source: super::api::Source,
    filename: &str,
    path: Option<&std::path::Path>,
) -> Result<VisualSource, String> {
    match source {
        super::api::Source::Uploaded => super::catalog::mesh_upload_name(filename)
            .filter(|n| super::catalog::check_mesh_name(n).is_ok())
            .map(VisualSource::Upload)
            .ok_or_else(|| {
                format!(
                    "mesh '{filename}' is not an uploaded mesh: an uploaded robot names one as \
                     'meshes/NAME' (PUT /v1/meshes/NAME)"
                )
            }),
        super::api::Source::Builtin => path
            .map(|p| VisualSource::File(p.to_path_buf()))
            .ok_or_else(|| {
                format!("mesh file '{filename}' is not on the server (next to the robot's URDF)")
            }),
    }
}

#[utoipa::path(get, path = "/v1/robots/{name}/visuals", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, body = RobotVisuals, description = "the robot's visual geometry (URDF `<visual>` elements); a viewer draws it, planners never check it"),
              (status = 404, body = ErrorBody),
              (status = 503, body = ErrorBody, description = "overloaded (the query pool is full); see `Retry-After`")))]
pub async fn robot_visuals(
    State(st): State<Arc<AppState>>,
    Path(name): Path<String>,
) -> ApiResult<Json<RobotVisuals>> {
    let e = st.catalog.robot(&name, "name")?;
    let uploaded: std::collections::BTreeSet<String> = match e.source {
        super::api::Source::Uploaded => {
            let st2 = st.clone();
            st.pool
                .run(move || Ok(st2.catalog.meshes()))
                .await?
                .into_iter()
                .map(|m| m.name)
                .collect()
        }
        super::api::Source::Builtin => Default::default(),
    };
    let enc = |s: &str| {
        s.bytes()
            .map(|b| {
                if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.' | b'~') {
                    (b as char).to_string()
                } else {
                    format!("%{b:02X}")
                }
            })
            .collect::<String>()
    };
    let mut visuals = Vec::new();
    for link in &e.robot.links {
        for (index, v) in link.visual.iter().enumerate() {
            let shape = |kind| VisualShape {
                kind,
                half_extents: None,
                radius: None,
                length: None,
                filename: None,
                url: None,
            };
            let (shape, problem) = match &v.geometry {
                VisualGeometry::Box { size } => (
                    Some(VisualShape {
                        half_extents: Some(size.map(|x| 0.5 * x)),
                        ..shape("box")
                    }),
                    None,
                ),
                VisualGeometry::Cylinder { radius, length } => (
                    Some(VisualShape {
                        radius: Some(*radius),
                        length: Some(*length),
                        ..shape("cylinder")
                    }),
                    None,
                ),
                VisualGeometry::Capsule { radius, length } => (
                    Some(VisualShape {
                        radius: Some(*radius),
                        length: Some(*length),
                        ..shape("capsule")
                    }),
                    None,
                ),
                VisualGeometry::Sphere { radius } => (
                    Some(VisualShape {
                        radius: Some(*radius),
                        ..shape("sphere")
                    }),
                    None,
                ),
                VisualGeometry::Mesh { filename, path, .. } => {
                    let found =
                        visual_source(e.source, filename, path.as_deref()).and_then(|s| match s {
                            VisualSource::Upload(n) if !uploaded.contains(&n) => Err(format!(
                                "mesh '{filename}': no uploaded mesh '{n}' (PUT /v1/meshes/{n})"
                            )),
                            s => Ok(s),
                        });
                    let url = format!(
                        "/v1/robots/{}/visuals/{}/{index}",
                        enc(&name),
                        enc(&link.name)
                    );
                    (
                        Some(VisualShape {
                            filename: Some(filename.clone()),
                            url: Some(url),
                            ..shape("mesh")
                        }),
                        found.err(),
                    )
                }
                VisualGeometry::Invalid { reason } => (None, Some(reason.clone())),
            };
            visuals.push(VisualItem {
                link: link.name.clone(),
                index,
                pose: crate::geometry::PoseJson::from_pose(&v.origin),
                shape,
                problem,
            });
        }
    }
    Ok(Json(RobotVisuals {
        robot: name,
        visuals,
    }))
}

/// A robot's visual mesh as OBJ text: visual `index` of link `link`, in the geometry frame with
/// the URDF's scale applied. Only meshes the robot's model names are read (see
/// [`visual_source`]), never a file named by the request.
#[utoipa::path(get, path = "/v1/robots/{name}/visuals/{link}/{index}", tag = "resources",
    params(("name" = String, Path), ("link" = String, Path), ("index" = usize, Path, description = "the visual's index in the link")),
    responses((status = 200, content_type = "model/obj", body = String, description = "Wavefront OBJ text"),
              (status = 404, body = ErrorBody, description = "no such robot, link or visual mesh, or the server does not have its file"),
              (status = 422, body = ErrorBody, description = "the mesh file does not read as a mesh"),
              (status = 503, body = ErrorBody, description = "overloaded (the query pool's heavy lane is full); see `Retry-After`")))]
pub async fn robot_visual_mesh(
    State(st): State<Arc<AppState>>,
    Path((name, link, index)): Path<(String, String, String)>,
) -> ApiResult<Response> {
    let e = st.catalog.robot(&name, "name")?;
    let l = e
        .robot
        .links
        .iter()
        .find(|l| l.name == link)
        .ok_or_else(|| {
            ApiError::not_found("link", format!("robot '{name}' has no link '{link}'"))
        })?;
    let (filename, scale, path) = index
        .parse::<usize>()
        .ok()
        .and_then(|i| l.visual.get(i))
        .and_then(|v| match &v.geometry {
            VisualGeometry::Mesh {
                filename,
                scale,
                path,
            } => Some((filename.clone(), *scale, path.clone())),
            _ => None,
        })
        .ok_or_else(|| {
            ApiError::not_found(
                "index",
                format!("link '{link}' of robot '{name}' has no visual mesh {index}"),
            )
        })?;
    let source = visual_source(e.source, &filename, path.as_deref())
        .map_err(|m| ApiError::not_found("mesh", m))?;
    let st2 = st.clone();
    let text = st
        .pool
        .run_heavy(move || {
            let scene = match &source {
                VisualSource::File(p) => mesh_loader::Loader::default()
                    .merge_meshes(true)
                    .load(p)
                    .map_err(|err| format!("mesh '{filename}': {err}")),
                VisualSource::Upload(n) => {
                    let bytes = st2.catalog.mesh_bytes(n)?;
                    mesh_loader::Loader::default()
                        .merge_meshes(true)
                        .load_from_slice_with_reader(
                            &bytes,
                            std::path::Path::new(n),
                            |p: &std::path::Path| {
                                Err::<Vec<u8>, _>(std::io::Error::new(
                                    std::io::ErrorKind::PermissionDenied,
                                    format!("'{}' is not read", p.display()),
                                ))
                            },
                        )
                        .map_err(|err| format!("mesh '{filename}': {err}"))
                }
            };
            scene
                .map(|s| visual_obj(&s, scale))
                .map_err(|m| ApiError::invalid("mesh", m))
        })
        .await?;
    Ok((
        [
            (header::CONTENT_TYPE, "model/obj; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        text,
    )
        .into_response())
}

/// The triangles of a loaded mesh file as OBJ text, `scale` applied, equal vertices written
/// once (a file's per-face vertex copies would triple the text).
fn visual_obj(scene: &mesh_loader::Scene, scale: [f64; 3]) -> String {
    use std::fmt::Write;
    let mut index: std::collections::HashMap<[u32; 3], usize> = Default::default();
    let mut verts = String::new();
    let mut faces = String::new();
    for m in &scene.meshes {
        let ids: Vec<usize> = m
            .vertices
            .iter()
            .map(|v| {
                let p = [0, 1, 2].map(|k| (v[k] as f64 * scale[k]) as f32);
                let n = index.len();
                *index.entry(p.map(f32::to_bits)).or_insert_with(|| {
                    let _ = writeln!(verts, "v {} {} {}", p[0], p[1], p[2]);
                    n
                })
            })
            .collect();
        for f in &m.faces {
            let [a, b, c] = f.map(|i| ids.get(i as usize).copied());
            if let (Some(a), Some(b), Some(c)) = (a, b, c) {
                let _ = writeln!(faces, "f {} {} {}", a + 1, b + 1, c + 1);
            }
        }
    }
    verts + &faces
}
