//! `manyhands roadmap build` (paper 003 §V-A: the super graph, built offline and kept in a
//! file) and `manyhands bench roadmap` (its build time and the online query, lazy
//! revalidation and repair times, §V-B).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{anyhow, Context, Result};
use clap::Args;
use rand::{Rng, SeedableRng};
use serde_json::json;

use manyhands::collision::CollisionWorld;
use manyhands::geometry::Pose;
use manyhands::planning::planners::roadmap_cache::{load_or_build, RoadmapSource};
use manyhands::planning::planners::roadmap_query::{
    attach_at_link, query_super_graph, RoadmapQuerySettings, RoadmapQueryStats,
};
use manyhands::planning::planners::super_graph::{
    build_super_graph, Decomposition, SuperGraph, SuperGraphParams,
};
use manyhands::planning::planners::visibility_prm::VisibilityPrmSettings;
use manyhands::planning::{PlannerRng, Termination};

use super::commands::Ctx;

/// The roadmap of a scene's robot: decomposition and build parameters.
#[derive(Args, Debug, Clone)]
pub struct RoadmapArgs {
    /// Scene name or path to a scene .json (its free objects are left out of the roadmap).
    #[arg(long)]
    pub scene: String,
    /// Robot instance of the scene (default: the first).
    #[arg(long)]
    pub robot: Option<String>,
    /// SRDF group of the common part.
    #[arg(long, default_value = "torso")]
    pub common: String,
    /// SRDF groups of the two independent parts, comma-separated.
    #[arg(long, default_value = "right_arm,left_arm")]
    pub parts: String,
    /// Visibility-PRM nodes per elementary roadmap at most.
    #[arg(long, default_value_t = 50)]
    pub nodes: usize,
    /// Visibility-PRM: stop after this many free samples in a row added no guard.
    #[arg(long, default_value_t = 100)]
    pub failures: usize,
    /// Visibility-PRM: samples per elementary roadmap at most.
    #[arg(long, default_value_t = 20_000)]
    pub samples: usize,
    /// No stationary super edges (a part standing still while the other moves).
    #[arg(long)]
    pub no_stationary: bool,
    /// Only edges joining components (003's "roadmap tree").
    #[arg(long)]
    pub tree: bool,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl RoadmapArgs {
    fn params(&self) -> SuperGraphParams {
        SuperGraphParams {
            prm: VisibilityPrmSettings {
                max_nodes: self.nodes,
                max_failures: self.failures,
                max_samples: self.samples,
                seed: self.seed,
            },
            stationary: !self.no_stationary,
            tree: self.tree,
            ..SuperGraphParams::default()
        }
    }

    /// The scene world, the decomposition and the base (start) configuration.
    fn setup(&self, ctx: &Ctx) -> Result<(CollisionWorld, Decomposition, Vec<f64>)> {
        let scene = ctx.scene(&self.scene)?;
        let world = CollisionWorld::from_scene(&scene);
        let robot = match &self.robot {
            None => 0,
            Some(n) => world
                .robots
                .iter()
                .position(|p| &p.name == n)
                .ok_or_else(|| anyhow!("--robot: no robot '{n}' in the scene"))?,
        };
        let parts: Vec<&str> = self.parts.split(',').map(str::trim).collect();
        let [a, b] = parts[..] else {
            return Err(anyhow!("--parts: give two groups, e.g. right_arm,left_arm"));
        };
        let dec = Decomposition::from_groups(&world, robot, &self.common, [a, b])?;
        let base = CollisionWorld::start_config(&scene);
        Ok((world, dec, base))
    }
}

#[derive(Args, Debug)]
pub struct BuildArgs {
    #[command(flatten)]
    pub roadmap: RoadmapArgs,
    /// Folder of roadmap files: a file with the right keys is loaded, else the roadmap is
    /// built and saved there.
    #[arg(long, default_value = "data/roadmaps")]
    pub dir: PathBuf,
    /// Build even when a file exists (and replace it).
    #[arg(long)]
    pub force: bool,
}

fn graph_json(g: &SuperGraph) -> serde_json::Value {
    json!({
        "elementary": g.elementary.iter().map(|r| json!({
            "nodes": r.nodes.len(), "edges": r.edges.len(), "guards": r.stats.guards,
            "connectors": r.stats.connectors, "components": r.stats.components,
            "samples": r.stats.samples,
        })).collect::<Vec<_>>(),
        "nodes": g.nodes.len(),
        "edges": g.edges.len(),
        "stats": g.stats,
    })
}

fn graph_text(g: &SuperGraph) -> String {
    let mut s = String::new();
    for (k, r) in g.elementary.iter().enumerate() {
        s += &format!(
            "elementary {} ({} + {}): {} nodes ({} guards, {} connectors), {} edges, {} components, {} samples, {:.0} ms\n",
            k,
            g.decomposition.common_group,
            g.decomposition.part_groups[k],
            r.nodes.len(),
            r.stats.guards,
            r.stats.connectors,
            r.edges.len(),
            r.stats.components,
            r.stats.samples,
            g.stats.elementary_millis[k]
        );
    }
    s += &format!(
        "super graph: {} nodes ({} candidates, {:.0} ms), {} edges ({} candidates checked, {:.0} ms), {} components; total {:.2} s",
        g.nodes.len(),
        g.stats.node_candidates,
        g.stats.nodes_millis,
        g.edges.len(),
        g.stats.edge_candidates,
        g.stats.edges_millis,
        g.stats.components,
        g.stats.total_millis / 1e3
    );
    s
}

pub fn build(ctx: &Ctx, a: &BuildArgs) -> Result<()> {
    let (world, dec, base) = a.roadmap.setup(ctx)?;
    let params = a.roadmap.params();
    let mut term = Termination::new();
    if a.force {
        let key = manyhands::planning::planners::roadmap_cache::RoadmapKey::of(
            &world, &dec, &base, &params,
        )?;
        let g = build_super_graph(&world, &dec, &base, &params, &mut term)?;
        std::fs::create_dir_all(&a.dir).with_context(|| a.dir.display().to_string())?;
        let f = a
            .dir
            .join(key.file_name(&world.robots[dec.robot].robot.name));
        manyhands::planning::planners::roadmap_cache::save_super_graph(&g, &key, &f)?;
        ctx.print(
            &json!({"file": f, "source": "built", "graph": graph_json(&g)}),
            || format!("built {}\n{}", f.display(), graph_text(&g)),
        );
        return Ok(());
    }
    let (g, file, src) =
        load_or_build(Some(&a.dir), None, &world, &dec, &base, &params, &mut term)?;
    let src = match src {
        RoadmapSource::Built => "built",
        RoadmapSource::Loaded => "loaded",
    };
    let f = file.map(|f| f.display().to_string()).unwrap_or_default();
    ctx.print(
        &json!({"file": f, "source": src, "graph": graph_json(&g)}),
        || format!("{src} {f}\n{}", graph_text(&g)),
    );
    Ok(())
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    #[command(flatten)]
    pub roadmap: RoadmapArgs,
    /// Seeded queries (random collision-free goals from the start configuration).
    #[arg(long, default_value_t = 20)]
    pub queries: u64,
    /// The free object revalidated online (default: the scene's first object).
    #[arg(long)]
    pub object: Option<String>,
    /// Link the object is carried by in the "carried" queries (default: the TCP of the first
    /// independent part's chain).
    #[arg(long)]
    pub link: Option<String>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

pub fn bench(ctx: &Ctx, a: &BenchArgs) -> Result<()> {
    let (world, dec, base) = a.roadmap.setup(ctx)?;
    let params = a.roadmap.params();
    let t = Instant::now();
    let g = build_super_graph(&world, &dec, &base, &params, &mut Termination::new())?;
    let build_s = t.elapsed().as_secs_f64();
    let object = match &a.object {
        Some(o) => o.clone(),
        None => world
            .statics
            .iter()
            .find(|s| s.kind == manyhands::collision::StaticKind::Object)
            .map(|s| s.name.clone())
            .ok_or_else(|| anyhow!("the scene has no free object; give --object"))?,
    };
    let robot = &world.robots[dec.robot].robot;
    let link = match &a.link {
        Some(l) => robot
            .link(l)
            .ok_or_else(|| anyhow!("--link: no link '{l}'"))?,
        None => robot
            .group(&dec.part_groups[0])
            .and_then(|gr| gr.chain)
            .map(|(_, tip)| tip)
            .ok_or_else(|| anyhow!("group '{}' is no chain; give --link", dec.part_groups[0]))?,
    };
    // Carried: the object 10 cm beyond the link along its z axis; every link of the part may
    // touch it.
    let grasp = Pose::translation(0.0, 0.0, 0.1);
    let touch = dec.part_links[0].clone();
    let carried = attach_at_link(&world, &object, dec.robot, link, &grasp, &base, touch)?;
    let space = g.space(&world, base.clone())?;
    let settings = RoadmapQuerySettings::default();
    let mut rows = Vec::new();
    for (label, qworld) in [("object resting", &world), ("object carried", &carried)] {
        let mut checker = manyhands::planning::space_checker(qworld, &space);
        let mut stats: Vec<RoadmapQueryStats> = Vec::new();
        let mut failed = 0;
        let mut first_error: Option<String> = None;
        for seed in 1..=a.queries.max(1) {
            // A free goal of the super space, drawn with the query's seed.
            let mut rng = PlannerRng::seed_from_u64(seed);
            let mut goal = None;
            for _ in 0..10_000 {
                let mut q = vec![0.0; space.dim()];
                for (k, x) in q.iter_mut().enumerate() {
                    *x = space.lower()[k]
                        + (space.upper()[k] - space.lower()[k]) * rng.random::<f64>();
                }
                let w = space.to_world(&q);
                if manyhands::collision::CollisionChecker::is_free(&mut checker, &w) {
                    goal = Some(w);
                    break;
                }
            }
            let Some(goal) = goal else {
                failed += 1;
                first_error.get_or_insert_with(|| "no free goal in 10 000 samples".into());
                continue;
            };
            let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(10));
            match query_super_graph(&g, qworld, &base, &goal, &settings, &mut term, seed) {
                Ok(r) => stats.push(r.stats),
                Err(e) => {
                    failed += 1;
                    first_error.get_or_insert_with(|| e.to_string());
                }
            }
        }
        let col = |f: &dyn Fn(&RoadmapQueryStats) -> f64| {
            median(&mut stats.iter().map(f).collect::<Vec<_>>())
        };
        rows.push(json!({
            "queries": label,
            "solved": stats.len(),
            "failed": failed,
            "median_total_ms": col(&|s| s.total_ms),
            "median_connect_ms": col(&|s| s.connect_ms),
            "median_search_ms": col(&|s| s.search_ms),
            "median_validation_ms": col(&|s| s.validation_ms),
            "median_rrt_ms": col(&|s| s.rrt_ms),
            "median_shortcut_ms": col(&|s| s.shortcut_ms),
            "median_path_nodes": col(&|s| s.first_path_nodes as f64),
            "direct": stats.iter().filter(|s| s.direct).count(),
            "searches_total": stats.iter().map(|s| s.searches).sum::<usize>(),
            "invalid_edges_total": stats.iter().map(|s| s.invalid_edges).sum::<usize>(),
            "invalid_nodes_total": stats.iter().map(|s| s.invalid_nodes).sum::<usize>(),
            "rrt_repairs_total": stats.iter().map(|s| s.rrt_repairs).sum::<usize>(),
            "first_error": first_error,
        }));
    }
    let out = json!({
        "build_s": build_s,
        "target_build_s": 10.0,
        "graph": graph_json(&g),
        "rows": rows,
    });
    ctx.print(&out, || {
        let mut s = format!(
            "roadmap offline: {:.2} s (target ≤ 10 s; paper: about 5 min)\n{}\n",
            build_s,
            graph_text(&g)
        );
        s += &format!(
            "{:<16} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>6} {:>7} {:>7} {:>5}\n",
            "queries", "solved", "total ms", "connect", "search", "validate", "rrt", "shortcut",
            "direct", "inv.edg", "inv.nod", "rrt#"
        );
        for r in &rows {
            s += &format!(
                "{:<16} {:>3}/{:<2} {:>9.2} {:>9.2} {:>9.3} {:>9.2} {:>9.2} {:>9.2} {:>6} {:>7} {:>7} {:>5}\n",
                r["queries"].as_str().unwrap_or_default(),
                r["solved"],
                r["solved"].as_u64().unwrap_or(0) + r["failed"].as_u64().unwrap_or(0),
                r["median_total_ms"].as_f64().unwrap_or(f64::NAN),
                r["median_connect_ms"].as_f64().unwrap_or(f64::NAN),
                r["median_search_ms"].as_f64().unwrap_or(f64::NAN),
                r["median_validation_ms"].as_f64().unwrap_or(f64::NAN),
                r["median_rrt_ms"].as_f64().unwrap_or(f64::NAN),
                r["median_shortcut_ms"].as_f64().unwrap_or(f64::NAN),
                r["direct"],
                r["invalid_edges_total"],
                r["invalid_nodes_total"],
                r["rrt_repairs_total"],
            );
        }
        for r in &rows {
            if let Some(e) = r["first_error"].as_str() {
                s += &format!("{}: first failure: {e}\n", r["queries"].as_str().unwrap_or_default());
            }
        }
        s += "medians over the solved queries; validation = lazy revalidation of the graph path with the object";
        s
    });
    Ok(())
}
