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

use super::catalog::MeshSummary;
use super::error::{ApiError, ApiResult, ErrorBody};
use super::AppState;

#[utoipa::path(get, path = "/v1/meshes", tag = "resources",
    responses((status = 200, body = [MeshSummary], description = "the uploaded meshes")))]
pub async fn list_meshes(State(st): State<Arc<AppState>>) -> ApiResult<Json<Vec<MeshSummary>>> {
    let st2 = st.clone();
    Ok(Json(st.pool.run(move || Ok(st2.catalog.meshes())).await?))
}

#[utoipa::path(get, path = "/v1/meshes/{name}", tag = "resources", params(("name" = String, Path)),
    responses((status = 200, description = "the mesh file as uploaded", content_type = "application/octet-stream", body = Vec<u8>),
              (status = 404, body = ErrorBody)))]
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
              (status = 404, body = ErrorBody, description = "no such scene, body or mesh shape")))]
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
