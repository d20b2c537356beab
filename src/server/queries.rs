//! Synchronous queries: `POST /v1/fk`, `POST /v1/ik`, `POST /v1/check`. Parsing and lookups
//! happen on the async side; validation of values and the computation run on the CPU pool.

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::Json;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionChecker, ExactChecker, FastChecker};
use crate::geometry::{quat_to_rpy, Pose, PoseJson};
use crate::kinematics::numeric::NumericIk;
use crate::kinematics::srs::SolutionOrder;
use crate::kinematics::{forward, link_pose};
use crate::model::RobotPlacement;
use crate::Robot;

use super::api::*;
use super::error::{ApiError, ApiResult};
use super::extract::ApiJson;
use super::AppState;

fn join(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_string()
    } else {
        format!("{prefix}.{name}")
    }
}

/// Applies a `joint → value` map on top of `base`; errors name `field.joint`.
pub fn apply_config(
    robot: &Robot,
    base: &[f64],
    map: &ConfigMap,
    field: &str,
) -> ApiResult<Vec<f64>> {
    let mut q = base.to_vec();
    for (name, &x) in map {
        let f = join(field, name);
        let v = robot.var(name).ok_or_else(|| {
            ApiError::invalid(
                &f,
                format!("robot '{}' has no movable joint '{name}'", robot.name),
            )
        })?;
        if !x.is_finite() {
            return Err(ApiError::invalid(&f, "value must be finite"));
        }
        let l = robot.var_limits(v);
        // Within `Limits::TOLERANCE` of a limit: accepted, clamped.
        let Some(x) = l.clamp_near(x) else {
            return Err(ApiError::invalid(
                &f,
                format!("value {x} outside limit [{}, {}]", l.lower, l.upper),
            ));
        };
        q[v] = x;
    }
    robot
        .accept_config(&mut q)
        .map_err(|e| ApiError::invalid(field, e))?;
    Ok(q)
}

/// A model's group state (`named`, default `home`, else zero).
pub fn named_base(robot: &Robot, named: Option<&str>, field: &str) -> ApiResult<Vec<f64>> {
    match named {
        Some(n) => robot.named_config(n).ok_or_else(|| {
            ApiError::invalid(
                field,
                format!("robot '{}' has no group state '{n}'", robot.name),
            )
        }),
        None => Ok(robot
            .named_config("home")
            .unwrap_or_else(|| robot.zero_config())),
    }
}

/// A scene placement's configuration: a named scene config or group state, else its start.
pub fn placement_base(p: &RobotPlacement, named: Option<&str>, field: &str) -> ApiResult<Vec<f64>> {
    match named {
        Some(n) => p
            .configs
            .get(n)
            .cloned()
            .or_else(|| p.robot.named_config(n))
            .ok_or_else(|| {
                ApiError::invalid(
                    field,
                    format!("robot '{}' has no configuration '{n}'", p.name),
                )
            }),
        None => Ok(p.start_config()),
    }
}

pub fn pose_out(p: &Pose) -> PoseOut {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    PoseOut {
        position: [t.x, t.y, t.z],
        rpy: quat_to_rpy(&p.rotation),
        quat_xyzw: [q.i, q.j, q.k, q.w],
    }
}

pub fn pose_in(p: &PoseBody, field: &str) -> ApiResult<Pose> {
    PoseJson {
        position: p.position,
        rpy: p.rpy,
        quat_xyzw: p.quat_xyzw,
    }
    .to_pose()
    .map_err(|m| match m.split_once(": ") {
        Some((head, tail)) if !head.contains(' ') => ApiError::invalid(join(field, head), tail),
        _ => ApiError::invalid(field, m),
    })
}

#[utoipa::path(post, path = "/v1/fk", tag = "queries", request_body = FkRequest,
    responses((status = 200, body = FkResponse), (status = 404, body = super::error::ErrorBody),
              (status = 422, body = super::error::ErrorBody)))]
pub async fn fk(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<FkRequest>,
) -> ApiResult<Json<FkResponse>> {
    let robot = st.catalog.robot(&req.robot, "robot")?.robot.clone();
    st.pool
        .run(move || fk_compute(&robot, &req))
        .await
        .map(Json)
}

fn fk_compute(r: &Robot, req: &FkRequest) -> ApiResult<FkResponse> {
    let base = named_base(r, req.named.as_deref(), "named")?;
    let q = apply_config(r, &base, &req.config, "config")?;
    let links: Vec<usize> = match &req.links {
        Some(names) => names
            .iter()
            .enumerate()
            .map(|(i, l)| {
                r.link(l).ok_or_else(|| {
                    ApiError::invalid(
                        format!("links[{i}]"),
                        format!("robot '{}' has no link '{l}'", r.name),
                    )
                })
            })
            .collect::<ApiResult<_>>()?,
        None => (0..r.links.len()).collect(),
    };
    let mut poses = vec![Pose::identity(); r.links.len()];
    forward(r, &Pose::identity(), &q, &mut poses);
    Ok(FkResponse {
        robot: req.robot.clone(),
        joints: (0..r.dof()).map(|v| r.var_name(v).to_string()).collect(),
        config: q,
        links: links
            .iter()
            .map(|&l| LinkPose {
                link: r.links[l].name.clone(),
                pose: pose_out(&poses[l]),
            })
            .collect(),
    })
}

#[utoipa::path(post, path = "/v1/ik", tag = "queries", request_body = IkRequest,
    responses((status = 200, body = IkResponse), (status = 404, body = super::error::ErrorBody),
              (status = 422, body = super::error::ErrorBody)))]
pub async fn ik(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<IkRequest>,
) -> ApiResult<Json<IkResponse>> {
    let entry = st.catalog.robot(&req.robot, "robot")?;
    st.pool
        .run(move || ik_compute(&entry, &req))
        .await
        .map(Json)
}

pub fn ik_compute(entry: &super::catalog::RobotEntry, req: &IkRequest) -> ApiResult<IkResponse> {
    let r = &*entry.robot;
    let psi_steps = req.psi_steps.unwrap_or(36);
    if !(1..=3600).contains(&psi_steps) {
        return Err(ApiError::invalid(
            "psi_steps",
            format!("{psi_steps} is not in 1..=3600"),
        ));
    }
    let max = req.max_solutions.unwrap_or(16);
    if !(1..=10_000).contains(&max) {
        return Err(ApiError::invalid(
            "max_solutions",
            format!("{max} is not in 1..=10000"),
        ));
    }
    let base = named_base(r, req.named.as_deref(), "named")?;
    let q0 = apply_config(r, &base, &req.config, "config")?;
    let solver = entry.arm(&req.group).ok_or_else(|| {
        let why = if r.group(&req.group).is_some() {
            "is not a chain group"
        } else {
            "does not exist"
        };
        ApiError::invalid(
            "group",
            format!("group '{}' of robot '{}' {why}", req.group, r.name),
        )
    })?;
    let chain = &solver.chain;
    let target_in = pose_in(&req.pose, "pose")?;
    let target = match req.frame {
        IkFrame::Root => link_pose(r, &q0, chain.base_link).inverse() * target_in,
        IkFrame::Base => target_in,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(req.seed.unwrap_or(1));
    let started = Instant::now();
    let arm = match req.solver {
        IkSolver::Numeric => None,
        IkSolver::Auto => solver.srs.as_ref().ok(),
        IkSolver::Analytic => Some(
            solver
                .srs
                .as_ref()
                .map_err(|e| ApiError::invalid("solver", e.to_string()))?,
        ),
    };
    let (solver, solutions): (&str, Vec<Vec<f64>>) = match arm {
        Some(arm) => {
            let order = match req.order {
                IkOrder::Seed => SolutionOrder::NearestTo(arm.from_config(&q0)),
                IkOrder::Random => SolutionOrder::Random,
            };
            let sols = arm.solve_enumerate(&target, psi_steps as usize, order, &mut rng);
            ("analytic", sols.iter().map(|s| s.to_vec()).collect())
        }
        None => {
            let mut nik = NumericIk::new(r, chain);
            match nik.solve(&target, &q0, &mut rng) {
                Ok(q) => ("numeric", vec![chain.vars.iter().map(|&v| q[v]).collect()]),
                Err(_) => ("numeric", Vec::new()),
            }
        }
    };
    let found = solutions.len();
    Ok(IkResponse {
        robot: req.robot.clone(),
        group: req.group.clone(),
        solver: solver.to_string(),
        solutions_found: found,
        joints: chain
            .vars
            .iter()
            .map(|&v| r.var_name(v).to_string())
            .collect(),
        solutions: solutions.into_iter().take(max as usize).collect(),
        time_us: started.elapsed().as_secs_f64() * 1e6,
    })
}

#[utoipa::path(post, path = "/v1/check", tag = "queries", request_body = CheckRequest,
    responses((status = 200, body = CheckResponse), (status = 404, body = super::error::ErrorBody),
              (status = 422, body = super::error::ErrorBody)))]
pub async fn check(
    State(st): State<Arc<AppState>>,
    ApiJson(req): ApiJson<CheckRequest>,
) -> ApiResult<Json<CheckResponse>> {
    let entry = st.catalog.scene(&req.scene, "scene")?;
    // What the check costs is what it tests, not the request's size: a cheap check runs on the
    // light lane, a costly one on the heavy lane (where it never delays FK, IK and cheap
    // checks), one past the bound is refused.
    let pairs = check_pairs(&entry.world());
    if pairs > MAX_CHECK_PAIRS {
        return Err(ApiError::invalid(
            "scene",
            format!(
                "a check of scene '{}' tests up to {pairs} pairs of collision shapes (its robots' \
                 shapes with each other and with its fixed bodies); a synchronous check tests at \
                 most {MAX_CHECK_PAIRS}: run a collision_sweep job instead",
                req.scene
            ),
        ));
    }
    let work = move || {
        let scene = &entry.scene;
        let world = entry.world();
        let mut q = crate::collision::CollisionWorld::start_config(scene);
        let mut seen = std::collections::BTreeSet::new();
        for (i, rc) in req.robots.iter().enumerate() {
            let field = format!("robots[{i}]");
            let ri = scene
                .robots
                .iter()
                .position(|p| p.name == rc.name)
                .ok_or_else(|| {
                    ApiError::invalid(
                        format!("{field}.name"),
                        format!("scene '{}' has no robot '{}'", scene.name, rc.name),
                    )
                })?;
            if !seen.insert(ri) {
                return Err(ApiError::invalid(
                    format!("{field}.name"),
                    format!("robot '{}' listed twice", rc.name),
                ));
            }
            let p = &scene.robots[ri];
            let base = placement_base(p, rc.named.as_deref(), &format!("{field}.named"))?;
            let qr = apply_config(&p.robot, &base, &rc.config, &format!("{field}.config"))?;
            let off = world.robots[ri].offset;
            q[off..off + qr.len()].copy_from_slice(&qr);
        }
        let ce = ExactChecker::new(&world).first_contact(&q);
        let cf = FastChecker::new(&world).first_contact(&q);
        Ok(CheckResponse {
            scene: req.scene.clone(),
            collision: ce.is_some(),
            pair: ce.map(|c| [c.a, c.b]),
            fast_checker: CheckFast {
                collision: cf.is_some(),
                pair: cf.map(|c| [c.a, c.b]),
            },
        })
    };
    if pairs > LIGHT_MAX_PAIRS {
        st.pool.run_heavy(work).await.map(Json)
    } else {
        st.pool.run(work).await.map(Json)
    }
}

/// Most shape pairs a `POST /v1/check` may test on the light lane (FK, IK, cheap checks);
/// a costlier check runs on the heavy lane.
pub const LIGHT_MAX_PAIRS: u64 = 20_000;

/// Most shape pairs a synchronous `POST /v1/check` may test at all (422 above).
pub const MAX_CHECK_PAIRS: u64 = 200_000;

/// The pairs of collision shapes a check of `world` may test: the robots' shapes with each
/// other and with the fixed bodies' (an upper bound: allowed pairs are not subtracted). The
/// cost of building the checkers and of one check grows with it.
pub fn check_pairs(world: &crate::collision::CollisionWorld) -> u64 {
    let robot: u64 = world
        .robots
        .iter()
        .flat_map(|p| p.robot.links.iter())
        .map(|l| l.collision.len() as u64)
        .sum();
    let fixed: u64 = world.statics.iter().map(|b| b.shapes.len() as u64).sum();
    robot * robot.saturating_sub(1) / 2 + robot * fixed
}
