//! `manyhands plan multi-arm`: the `multi_arm` job without a server (its HTTP body in, its
//! answer out).

use anyhow::{anyhow, bail, Result};
use clap::Args;

use super::commands::Ctx;

#[derive(Args, Debug)]
pub struct MultiArmArgs {
    /// The request body of job kind `multi_arm` (its `kind` field may be given): JSON text,
    /// `@FILE`, or `-` for standard input.
    pub body: String,
    /// Most seconds the search may take (the server's `--max-plan-seconds`).
    #[arg(long, default_value_t = 60.0)]
    pub max_seconds: f64,
}

pub fn plan(ctx: &Ctx, a: &MultiArmArgs) -> Result<()> {
    let text = super::query::body_text(&a.body)?;
    let mut v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| anyhow!("request body: {e}"))?;
    if let Some(o) = v.as_object_mut() {
        match o.remove("kind") {
            None => {}
            Some(serde_json::Value::String(k)) if k == "multi_arm" => {}
            Some(k) => bail!("request body, field 'kind': {k} is not \"multi_arm\""),
        }
    }
    let req: manyhands::server::multi_arm::MultiArmRequest = super::query::parse(&v.to_string())?;
    let scene = std::sync::Arc::new(ctx.scene(&req.scene)?);
    let out = manyhands::server::multi_arm::multi_arm_locally(&req, scene, a.max_seconds)
        .map_err(|e| anyhow!("{e}"))?;
    ctx.print(&out, || {
        format!(
            "multi-arm: {} ({} vertices), makespan {:.3} s (before shortcutting {:.3} s), \
             planned in {:.1} ms",
            out["method"].as_str().unwrap_or(""),
            out["path"].as_array().map_or(0, |p| p.len()),
            out["makespan"].as_f64().unwrap_or(0.0),
            out["makespan_before_shortcut"].as_f64().unwrap_or(0.0),
            out["stats"]["time_ms"].as_f64().unwrap_or(0.0),
        )
    });
    Ok(())
}
