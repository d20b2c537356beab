//! `manyhands query`: the synchronous grasp-IK queries of the server, run locally. The request
//! body is the very JSON the HTTP endpoint takes (`POST /v1/ik/grasp`, `/v1/ik/dual-arm`,
//! `/v1/ik/base-placement`), validated the same way; the answer is the endpoint's JSON.
//! Reachability grids are kept under `<data-dir>/reach`, shared with `manyhands serve`.

use std::io::Read;
use std::path::PathBuf;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, ValueEnum};
use serde::de::DeserializeOwned;
use serde_json::Value;

use manyhands::reachability::GridCache;
use manyhands::server::dual_arm_ik::{base_placement_compute, dual_arm_compute};
use manyhands::server::error::ApiError;
use manyhands::server::grasp_ik;

use super::commands::Ctx;

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Endpoint {
    /// Randomized whole-body IK over a grasp set (POST /v1/ik/grasp; paper 000 §II-D).
    #[value(name = "ik-grasp")]
    Grasp,
    /// Dual-arm IK, object pose free or held in the left hand (POST /v1/ik/dual-arm; 000 §III).
    #[value(name = "ik-dual-arm")]
    DualArm,
    /// IkDualArm with base placement (POST /v1/ik/base-placement; paper 002 Alg. 1).
    #[value(name = "ik-base-placement")]
    BasePlacement,
}

#[derive(Args, Debug)]
pub struct QueryArgs {
    pub endpoint: Endpoint,
    /// The request body: JSON text, `@FILE`, or `-` for standard input.
    pub body: String,
    /// Folder of cached reachability grids (`<data-dir>/reach`), as for `serve`.
    #[arg(long, env = "MANYHANDS_DATA_DIR", default_value = "./data")]
    pub data_dir: PathBuf,
}

pub(super) fn body_text(b: &str) -> Result<String> {
    if b == "-" {
        let mut s = String::new();
        std::io::stdin().read_to_string(&mut s)?;
        Ok(s)
    } else if let Some(f) = b.strip_prefix('@') {
        std::fs::read_to_string(f).with_context(|| format!("reading {f}"))
    } else {
        Ok(b.to_string())
    }
}

pub(super) fn parse<T: DeserializeOwned>(text: &str) -> Result<T> {
    let de = &mut serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        anyhow!("request body, field '{path}': {}", e.into_inner())
    })
}

/// The endpoint's error; its message starts with the field it names.
fn api(e: ApiError) -> anyhow::Error {
    anyhow!("{}", e.message)
}

pub fn run(ctx: &Ctx, a: &QueryArgs) -> Result<()> {
    let text = body_text(&a.body)?;
    let v: Value = parse(&text)?;
    let scene_name = v
        .get("scene")
        .and_then(Value::as_str)
        .ok_or_else(|| anyhow!("request body, field 'scene': missing"))?;
    let scene = ctx.scene(scene_name)?;
    let grids = GridCache::new(Some(a.data_dir.join("reach")));
    let answer = match a.endpoint {
        Endpoint::Grasp => serde_json::to_value(
            grasp_ik::compute(&scene, &parse(&text)?, Some(&grids)).map_err(api)?,
        )?,
        Endpoint::DualArm => serde_json::to_value(
            dual_arm_compute(&scene, &parse(&text)?, Some(&grids)).map_err(api)?,
        )?,
        Endpoint::BasePlacement => serde_json::to_value(
            base_placement_compute(&scene, &parse(&text)?, &grids).map_err(api)?,
        )?,
    };
    let found = answer.get("found").and_then(Value::as_bool) == Some(true);
    if ctx.json {
        println!("{}", serde_json::to_string_pretty(&answer)?);
    } else {
        let get = |k: &str| answer.get(k).cloned().unwrap_or(Value::Null);
        if found {
            let grasps: Vec<String> = ["grasp", "left_grasp", "right_grasp"]
                .iter()
                .filter_map(|k| answer.get(*k).and_then(Value::as_str))
                .map(str::to_string)
                .collect();
            println!("found: grasp {}", grasps.join(" + "));
            if let (Some(j), Some(s)) = (get("joints").as_array(), get("solution").as_array()) {
                for (n, x) in j.iter().zip(s) {
                    println!(
                        "  {:<20} {:>10.6}",
                        n.as_str().unwrap_or(""),
                        x.as_f64().unwrap_or(f64::NAN)
                    );
                }
            }
        } else {
            println!("not found: {}", get("reason"));
        }
        println!(
            "tries {}, IK calls {}, collision checks {}, reachability {}, {:.1} µs",
            get("tries"),
            get("ik_calls"),
            get("collision_checks"),
            get("reachability"),
            get("time_us").as_f64().unwrap_or(f64::NAN)
        );
    }
    if !found {
        bail!("no solution");
    }
    Ok(())
}
