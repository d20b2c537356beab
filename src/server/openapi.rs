//! The OpenAPI 3.1 description of the API, generated from the Rust types (utoipa; the bodies are
//! the `manyhands-api` crate's types, built with its `openapi` feature). The checked-in
//! copy is `api/openapi.json`; `tests/server_openapi.rs` fails when it drifts
//! (regenerate with `manyhands serve --print-openapi > api/openapi.json`).

use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

use super::api::*;
use super::error::{ErrorBody, ErrorDetail};

struct BearerAuth;

impl Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        if let Some(c) = openapi.components.as_mut() {
            c.add_security_scheme(
                "bearer",
                SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
            );
        }
    }
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "manyhands",
        description = "Multi-robot grasp-and-motion planning server. Every 4xx/5xx answer has the body \
            `{\"error\": {\"code\", \"message\", \"field\"}}`; `field` is the path of the offending request \
            field (e.g. `robots[1].start.right_elbow`). With a server token, send `Authorization: Bearer TOKEN`.",
        license(name = "Apache-2.0")
    ),
    paths(
        super::healthz, super::readyz, super::metrics_handler,
        super::resources::list_robots, super::resources::get_robot, super::resources::get_robot_urdf, super::resources::put_robot,
        super::resources::delete_robot, super::resources::list_scenes, super::resources::get_scene,
        super::resources::put_scene, super::resources::delete_scene,
        super::meshes::list_meshes, super::meshes::get_mesh, super::meshes::put_mesh, super::meshes::delete_mesh,
        super::meshes::scene_mesh, super::meshes::robot_visuals, super::meshes::robot_visual_mesh,
        super::queries::fk, super::queries::ik, super::queries::check, super::trajectories::time_path,
        super::grasp_ik::grasp_ik, super::dual_arm_ik::dual_arm_ik, super::dual_arm_ik::base_placement,
        super::grasp_quality::grasp_quality,
        super::grasp_lists::list_index, super::grasp_lists::get_list,
        super::plans::submit, super::plans::list, super::plans::get, super::plans::cancel, super::plans::events,
    ),
    components(schemas(
        ErrorBody, ErrorDetail, PoseBody, PoseOut, Source, RobotSummary, RobotDetail, JointInfo, GroupInfo,
        EndEffectorInfo, RobotUpload, SceneSummary, SceneRobotInfo, FkRequest, FkResponse, LinkPose,
        IkRequest, IkResponse, IkFrame, IkSolver, IkOrder, CheckRequest, CheckResponse, CheckFast,
        SceneRobotConfig, PlanRequest, JointSpacePlan, super::api::SamplerName, PlanRobot, CollisionSweep, ReachPlan, GraspPlannerName, HandRef, RegraspPlan, KitchenTaskPlan, BimanualPlan, super::api::GraspListPlan, super::api::GraspListParamsBody, super::api::PickPlaceTaskPlan, crate::server::multi_robot::MultiRobotRequest, crate::server::multi_robot::ScheduleRequest, crate::server::multi_robot::ScheduleTrajectory, crate::server::multi_arm::MultiArmRequest, crate::server::multi_arm::MultiArmRobot, Job, JobState, JobList,
        JobSummary, Health, super::catalog::MeshSummary, super::meshes::RobotVisuals, super::meshes::VisualItem, super::meshes::VisualShape,
        GraspIkRequest, GraspIkResponse, DualArmIkRequest, BasePlacementRequest, RegionJson, TwoHandIkResponse,
        GraspContact, GraspQualityRequest, GraspQualityResponse, GraspQualityScore,
        JointTrajectory, TrajectoryPoint, TimedWaypoint, TrajectoryEvent, TrajectoryRequest,
    )),
    modifiers(&BearerAuth),
    security(("bearer" = [])),
    tags(
        (name = "resources", description = "robots (URDF + SRDF), scenes and meshes"),
        (name = "queries", description = "synchronous FK, IK, collision checks and trajectory timing"),
        (name = "plans", description = "asynchronous planning jobs"),
        (name = "operations", description = "health, readiness, metrics"),
    )
)]
pub struct ApiDoc;

/// The spec as pretty JSON with a trailing newline (the form of `api/openapi.json`).
pub fn openapi_json() -> String {
    let spec = ApiDoc::openapi();
    let mut s = match serde_json::to_value(&spec) {
        Ok(mut v) => {
            close_tagged_unions(&mut v);
            document_common_answers(&mut v);
            grasp_list_frame_rule(&mut v);
            grasp_quality_source_rule(&mut v);
            serde_json::to_string_pretty(&v)
        }
        Err(e) => Err(e),
    }
    .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    s.push('\n');
    s
}

/// Names of robots, scenes and grasp lists: 1–64 of `A-Z a-z 0-9 _ - .`, not starting with `.`
/// (`catalog::check_name`).
const NAME_PATTERN: &str = r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}$";
/// [`NAME_PATTERN`] ending in `.stl`, `.obj` or `.dae` (any case).
const MESH_NAME_PATTERN: &str =
    r"^[A-Za-z0-9_-][A-Za-z0-9_.-]{0,59}\.([Ss][Tt][Ll]|[Oo][Bb][Jj]|[Dd][Aa][Ee])$";

/// Bounds of the query parameters the server enforces (`name`, minimum, maximum); a value
/// outside is answered 400 or 422 naming the parameter.
const QUERY_BOUNDS: [(&str, f64, f64); 2] = [
    ("wait", 0.0, super::plans::MAX_WAIT),
    ("limit", 1.0, super::plans::MAX_PAGE as f64),
];

/// Adds to every operation the answers the server gives before its handler runs, so that the
/// spec lists every status an operation can return: 401 on the operations behind the bearer
/// token, 400 (malformed JSON, too deep, an unknown query parameter), 408 (body timeout), 413
/// (body limit) and 415 (content type) on those that read a JSON body; and puts the bounds the
/// server enforces on the query parameters into their schemas.
fn document_common_answers(spec: &mut serde_json::Value) {
    use serde_json::{json, Value};
    let error = |d: &str| {
        json!({"description": d, "content": {"application/json": {"schema":
            {"$ref": "#/components/schemas/ErrorBody"}}}})
    };
    let Some(paths) = spec["paths"].as_object_mut() else {
        return;
    };
    for (path, ops) in paths.iter_mut() {
        let Some(ops) = ops.as_object_mut() else {
            continue;
        };
        for op in ops.values_mut() {
            let open = op
                .get("security")
                .and_then(Value::as_array)
                .is_some_and(|s| {
                    s.iter()
                        .all(|r| r.as_object().is_some_and(|o| o.is_empty()))
                });
            let has_body = op.get("requestBody").is_some();
            let has_query = op
                .get("parameters")
                .and_then(Value::as_array)
                .is_some_and(|ps| ps.iter().any(|p| p["in"] == "query"));
            let has_header = op
                .get("parameters")
                .and_then(Value::as_array)
                .is_some_and(|ps| ps.iter().any(|p| p["in"] == "header"));
            if let Some(ps) = op.get_mut("parameters").and_then(Value::as_array_mut) {
                for p in ps.iter_mut() {
                    let name = p["name"].as_str().unwrap_or("").to_string();
                    let place = p["in"].as_str().unwrap_or("").to_string();
                    let schema = &mut p["schema"];
                    // An optional parameter is given or absent, never `null`.
                    if let Some(types) = schema.get_mut("type").and_then(Value::as_array_mut) {
                        types.retain(|t| t != "null");
                        if types.len() == 1 {
                            schema["type"] = types[0].clone();
                        }
                    }
                    if let Some(&(_, lo, hi)) = QUERY_BOUNDS.iter().find(|b| b.0 == name) {
                        schema["minimum"] = json!(lo);
                        schema["maximum"] = json!(hi);
                    }
                    match (Some(place.as_str()), name.as_str()) {
                        // Names of robots, scenes and grasp lists (`catalog::check_name`).
                        // Mesh uploads: a file name ending in its format (`catalog::check_mesh_name`).
                        (Some("path"), "name") if path.starts_with("/v1/meshes/") => {
                            schema["pattern"] = json!(MESH_NAME_PATTERN)
                        }
                        (Some("path"), "name") => schema["pattern"] = json!(NAME_PATTERN),
                        (Some("path"), "id") if path.starts_with("/v1/grasp-lists") => {
                            schema["pattern"] = json!(NAME_PATTERN)
                        }
                        // `next_cursor` of a page: creation time and job id.
                        (Some("query"), "cursor") => {
                            schema["pattern"] = json!(r"^[0-9]{1,19}\.[A-Za-z0-9]{1,64}$")
                        }
                        (Some("query"), "kind") => {
                            schema["enum"] = json!(super::api::PlanRequest::KINDS)
                        }
                        (Some("header"), "Last-Event-ID") => {
                            schema["maximum"] = json!(u64::MAX);
                        }
                        _ => {}
                    }
                }
            }
            let Some(responses) = op.get_mut("responses").and_then(Value::as_object_mut) else {
                continue;
            };
            let mut add = |code: &str, d: &str| {
                responses.entry(code).or_insert_with(|| error(d));
            };
            if path.starts_with("/v1/") && !open {
                add(
                    "401",
                    "missing or wrong bearer token (when the server has one); see `WWW-Authenticate`",
                );
            }
            if has_body {
                add(
                    "400",
                    "malformed JSON, or JSON nested deeper than 32 levels",
                );
                add(
                    "408",
                    "the request body did not arrive within the server's body timeout (`--body-timeout`); the connection is closed",
                );
                add(
                    "413",
                    "the request body is larger than the server's limit (`--max-body`); the connection is closed",
                );
                add("415", "the body is not `Content-Type: application/json`");
            }
            if has_query {
                add("400", "an unknown query parameter, or a malformed one");
            }
            if path.starts_with("/v1/meshes/") {
                add(
                    "422",
                    "the mesh name is not 1-64 characters of A-Z a-z 0-9 _ - . ending in .stl, .obj or .dae",
                );
            }
            if has_header {
                add("400", "a malformed header parameter");
            }
            // The synchronous queries and uploads run on the bounded CPU pool, the jobs and
            // grasp lists live in the job store.
            if has_body || path.starts_with("/v1/plans") || path.starts_with("/v1/grasp-lists") {
                add(
                    "503",
                    "overloaded (the query pool is full), shutting down, or the job store is unreachable; see `Retry-After`",
                );
            }
        }
    }
}

/// The bound of a single-grasp list's size, positions × 72 · 8^level orientations ≤
/// [`MAX_FRAMES`](crate::grasp::list::MAX_FRAMES), in the schema of its parameters: `positions`
/// at most the level-0 bound, and for each higher level (`if` it is given, `then`) the bound of
/// that level — with `positions` required where its default exceeds it.
fn grasp_list_frame_rule(spec: &mut serde_json::Value) {
    use crate::grasp::list::{GraspListParams, MAX_FRAMES, MAX_POSITIONS};
    use crate::grasp::so3_grid::{so3_grid_len, MAX_SO3_LEVEL};
    use serde_json::{json, Value};
    let s = &mut spec["components"]["schemas"]["GraspListParamsBody"];
    if !s["properties"]["positions"].is_object() {
        return;
    }
    let cap = |level: u32| (MAX_FRAMES / so3_grid_len(level)).min(MAX_POSITIONS);
    s["properties"]["positions"]["maximum"] = json!(cap(0));
    let default_positions = GraspListParams::default().positions;
    let rules: Vec<Value> = (1..=MAX_SO3_LEVEL)
        .map(|level| {
            let mut then = json!({"properties": {"positions": {"maximum": cap(level)}}});
            if default_positions > cap(level) {
                then["required"] = json!(["positions"]);
            }
            json!({
                "if": {"properties": {"orientation_level": {"const": level}},
                       "required": ["orientation_level"]},
                "then": then,
            })
        })
        .collect();
    s["allOf"] = Value::Array(rules);
    // Each weight of the quality score (`GraspListParams::validate`).
    if s["properties"]["weights"].is_object() {
        s["properties"]["weights"]["items"] =
            json!({"type": "number", "minimum": 0, "maximum": 1e6});
    }
}

/// What a grasp-quality request scores, in its schema: `scene` with `object` (their grasps, and
/// the contacts if any), or neither and at least one contact.
fn grasp_quality_source_rule(spec: &mut serde_json::Value) {
    use serde_json::json;
    let s = &mut spec["components"]["schemas"]["GraspQualityRequest"];
    if !s["properties"]["contacts"].is_object() {
        return;
    }
    s["anyOf"] = json!([
        {"required": ["scene", "object"],
         "properties": {"scene": {"type": "string"}, "object": {"type": "string"}}},
        {"required": ["contacts"],
         "properties": {"contacts": {"minItems": 1}, "scene": {"type": "null"},
                        "object": {"type": "null"}}},
    ]);
}

/// Makes the schemas of internally tagged enums (`PlanRequest`: `#[serde(tag = "kind")]`)
/// satisfiable. utoipa renders each variant as `allOf: [{$ref: Variant}, {required: [kind],
/// properties: {kind}}]`, but the variant's own schema is closed (`additionalProperties: false`,
/// from `deny_unknown_fields`) and has no `kind`, so no body matches. Each such `allOf` becomes
/// one closed object: the variant's properties plus `kind`, required as both declare.
fn close_tagged_unions(spec: &mut serde_json::Value) {
    use serde_json::Value;
    let prefix = "#/components/schemas/";
    let schemas = spec["components"]["schemas"].clone();
    fn merged(all: &[Value], schemas: &Value, prefix: &str) -> Option<Value> {
        let [Value::Object(a), Value::Object(tag)] = all else {
            return None;
        };
        let name = a.get("$ref")?.as_str()?.strip_prefix(prefix)?;
        let mut base = schemas.get(name)?.as_object()?.clone();
        if base.get("additionalProperties") != Some(&Value::Bool(false)) {
            return None;
        }
        let props = base
            .entry("properties")
            .or_insert_with(|| Value::Object(Default::default()));
        for (k, v) in tag.get("properties")?.as_object()? {
            props.as_object_mut()?.insert(k.clone(), v.clone());
        }
        let mut required: Vec<Value> = tag.get("required")?.as_array()?.clone();
        if let Some(r) = base.get("required").and_then(Value::as_array) {
            required.extend(r.iter().cloned());
        }
        base.insert("required".into(), Value::Array(required));
        base.remove("description");
        base.remove("title");
        base.insert("title".into(), Value::String(name.to_string()));
        Some(Value::Object(base))
    }
    let Some(map) = spec["components"]["schemas"].as_object_mut() else {
        return;
    };
    for schema in map.values_mut() {
        let Some(branches) = schema.get_mut("oneOf").and_then(Value::as_array_mut) else {
            continue;
        };
        for b in branches.iter_mut() {
            let all = b.get("allOf").and_then(Value::as_array).cloned();
            if let Some(m) = all.and_then(|all| merged(&all, &schemas, prefix)) {
                *b = m;
            }
        }
    }
}

/// Standalone JSON Schemas (draft 2020-12) of the request bodies, one per operation that takes a
/// JSON body described by a component: `(file name, pretty JSON with a trailing newline)`, e.g.
/// `post-v1-ik-dual-arm.request.schema.json`. Each holds its component and every component it
/// refers to under `$defs`, so it validates on its own (the scene body has its own
/// hand-written `api/scene.schema.json`). Checked in under `api/schemas/`.
pub fn request_schemas() -> Vec<(String, String)> {
    use serde_json::{json, Map, Value};
    let spec: Value = serde_json::from_str(&openapi_json()).unwrap_or(Value::Null);
    let components = spec["components"]["schemas"].clone();
    let prefix = "#/components/schemas/";
    // Names of the components `v` refers to, and `v` with its references moved to `$defs`.
    fn rewrite(v: &Value, prefix: &str, refs: &mut Vec<String>) -> Value {
        match v {
            Value::Object(m) => Value::Object(
                m.iter()
                    .map(|(k, x)| match (k.as_str(), x.as_str()) {
                        ("$ref", Some(r)) if r.starts_with(prefix) => {
                            let name = r[prefix.len()..].to_string();
                            let out = Value::String(format!("#/$defs/{name}"));
                            refs.push(name);
                            (k.clone(), out)
                        }
                        _ => (k.clone(), rewrite(x, prefix, refs)),
                    })
                    .collect(),
            ),
            Value::Array(a) => Value::Array(a.iter().map(|x| rewrite(x, prefix, refs)).collect()),
            x => x.clone(),
        }
    }
    let mut out = Vec::new();
    let Some(paths) = spec["paths"].as_object() else {
        return out;
    };
    for (path, ops) in paths {
        let Some(ops) = ops.as_object() else { continue };
        for (method, op) in ops {
            let r = &op["requestBody"]["content"]["application/json"]["schema"]["$ref"];
            let Some(name) = r.as_str().and_then(|r| r.strip_prefix(prefix)) else {
                continue;
            };
            let mut todo = vec![name.to_string()];
            let mut defs = Map::new();
            while let Some(n) = todo.pop() {
                if defs.contains_key(&n) {
                    continue;
                }
                let mut refs = Vec::new();
                defs.insert(n.clone(), rewrite(&components[&n], prefix, &mut refs));
                todo.extend(refs);
            }
            let slug: String = format!("{method}{path}")
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect::<String>()
                .split('-')
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join("-");
            let file = format!("{slug}.request.schema.json");
            let doc = json!({
                "$schema": "https://json-schema.org/draft/2020-12/schema",
                "$id": format!("https://manyhands.local/api/schemas/{file}"),
                "title": format!("{} {path} request body", method.to_uppercase()),
                "description": format!("Body of `{} {path}` (component `{name}` of api/openapi.json).", method.to_uppercase()),
                "$ref": format!("#/$defs/{name}"),
                "$defs": Value::Object(defs),
            });
            let mut text = serde_json::to_string_pretty(&doc).unwrap_or_default();
            text.push('\n');
            out.push((file, text));
        }
    }
    out.sort();
    out
}
