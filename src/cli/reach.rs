//! `manyhands reach …`: build, inspect and plot reachability grids (paper 000 §II-B).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use manyhands::kinematics::Chain;
use manyhands::reachability::{slice_svg, GridParams, ReachabilityGrid, SliceAxes};

use super::commands::Ctx;

#[derive(Subcommand, Debug)]
pub enum ReachCmd {
    /// Builds the 6-D reachability grid of a chain group by sampling self-collision-free
    /// configurations through FK, and writes it to a file.
    Build(BuildArgs),
    /// Prints the header of a grid file (robot, chain, parameters, counts).
    Info {
        /// Grid file.
        file: PathBuf,
    },
    /// Writes an SVG slice of a grid (mean or max over orientations), like paper 000 Fig. 2a.
    Plot(PlotArgs),
}

#[derive(Args, Debug)]
pub struct BuildArgs {
    /// Model name or path to a .urdf.
    pub robot: String,
    /// SRDF chain group (its base link is the grid frame), e.g. right_arm or torso_right_arm.
    #[arg(long)]
    pub chain: String,
    /// Joint configurations sampled.
    #[arg(long, default_value_t = 4_000_000)]
    pub samples: u64,
    /// Voxel edge (m).
    #[arg(long, default_value_t = 0.05)]
    pub resolution: f64,
    /// Bins per angle (roll, pitch, yaw).
    #[arg(long, default_value_t = 8)]
    pub rot_bins: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// Grid file.
    pub file: PathBuf,
    /// Axis normal to the slice: x, y or z.
    #[arg(long, default_value = "z")]
    pub normal: String,
    /// Slice coordinate along the normal (m, chain-base frame); default: through the cell with
    /// the most reachable poses.
    #[arg(long)]
    pub at: Option<f64>,
    /// Maximum over orientations instead of the mean.
    #[arg(long)]
    pub max: bool,
    /// Output SVG file.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(ctx: &Ctx, cmd: &ReachCmd) -> Result<()> {
    match cmd {
        ReachCmd::Build(a) => build(ctx, a),
        ReachCmd::Info { file } => {
            let g = load(ctx, file)?;
            print_info(ctx, &g, None);
            Ok(())
        }
        ReachCmd::Plot(a) => plot(ctx, a),
    }
}

/// Loads a grid file and checks it against the model named in its header.
fn load(ctx: &Ctx, file: &std::path::Path) -> Result<ReachabilityGrid> {
    let g = ReachabilityGrid::load_unchecked(file)?;
    let robot = ctx.robot(g.robot())?;
    g.check(&robot, g.group())
        .with_context(|| format!("grid file {}", file.display()))?;
    Ok(g)
}

fn print_info(ctx: &Ctx, g: &ReachabilityGrid, secs: Option<f64>) {
    let p = g.params();
    let s = g.stats();
    let v = json!({
        "robot": g.robot(), "group": g.group(), "base_link": g.base_link(), "tip_link": g.tip_link(),
        "hash": format!("{:016x}", g.hash()), "resolution": p.resolution, "rot_bins": p.rot_bins,
        "min": p.min, "max": p.max, "dims": g.dims(), "cells": p.cells(), "samples": s.samples,
        "self_collision_free": s.free, "outside": s.outside, "filled_cells": s.filled,
        "max_entry": g.max_entry(), "seed": p.seed, "build_seconds": secs,
    });
    ctx.print(&v, || {
        let mut t = format!(
            "{} {} ({}→{}), kinematics hash {:016x}\n  voxel {} m × {} bins per angle, extents {:?} – {:?} m, {:?} × {}³ = {} cells\n  {} samples (seed {}): {} self-collision-free ({:.1} %), {} outside; {} cells filled ({:.2} %), max entry {}",
            g.robot(), g.group(), g.base_link(), g.tip_link(), g.hash(),
            p.resolution, p.rot_bins, p.min, p.max, g.dims(), p.rot_bins, p.cells(),
            s.samples, p.seed, s.free, 100.0 * s.free as f64 / s.samples.max(1) as f64, s.outside,
            s.filled, 100.0 * s.filled as f64 / p.cells().max(1) as f64, g.max_entry()
        );
        if let Some(secs) = secs {
            t.push_str(&format!("\n  built in {secs:.2} s"));
        }
        t
    });
}

fn build(ctx: &Ctx, a: &BuildArgs) -> Result<()> {
    let robot: Arc<_> = ctx.robot(&a.robot)?;
    let chain = Chain::from_group(&robot, &a.chain)
        .with_context(|| format!("robot '{}' has no chain group '{}'", robot.name, a.chain))?;
    let params = GridParams::auto(&robot, &chain, a.resolution, a.rot_bins, a.samples, a.seed)?;
    let bar = if a.quiet || ctx.json {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(a.samples)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} samples ({per_sec}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let t0 = Instant::now();
    let grid = ReachabilityGrid::build(&robot, &a.chain, &params, &|n| bar.set_position(n))?;
    bar.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    grid.save(&a.out)?;
    print_info(ctx, &grid, Some(secs));
    if !ctx.json {
        use std::io::Write;
        let _ = writeln!(std::io::stdout().lock(), "  written to {}", a.out.display());
    }
    Ok(())
}

fn plot(ctx: &Ctx, a: &PlotArgs) -> Result<()> {
    let g = load(ctx, &a.file)?;
    let normal = match a.normal.as_str() {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        o => anyhow::bail!("--normal must be x, y or z, not '{o}'"),
    };
    let at = match a.at {
        Some(v) => v,
        None => {
            // The layer along `normal` with the most filled cells.
            let p = g.params();
            let d = g.dims();
            let per = (p.rot_bins as usize).pow(3);
            let mut count = vec![0usize; d[normal]];
            for (i, chunk) in g.data().chunks(per).enumerate() {
                let c = [i / (d[1] * d[2]), (i / d[2]) % d[1], i % d[2]];
                count[c[normal]] += chunk.iter().filter(|&&e| e > 0).count();
            }
            let best = (0..d[normal]).max_by_key(|&k| count[k]).unwrap_or(0);
            g.cell_centre(normal, best)
        }
    };
    let svg = slice_svg(
        &g,
        &SliceAxes {
            normal,
            at,
            max: a.max,
        },
    );
    std::fs::write(&a.out, svg).with_context(|| format!("writing {}", a.out.display()))?;
    ctx.print(
        &json!({"file": a.out, "normal": a.normal, "at": at}),
        || {
            format!(
                "slice {} = {at:.3} m written to {}",
                a.normal,
                a.out.display()
            )
        },
    );
    Ok(())
}
