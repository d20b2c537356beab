//! Time-optimal parameterisation (src/trajectory/timing.rs, TOPP-RA on the polyline): limits,
//! staying on the path, rest at both ends, and the duration against toppra (the reference
//! implementation of Pham & Pham 2018) on the same paths and limits — a fixture generated once
//! by tests/data/timing/make_toppra_fixture.py; this test only reads its JSON.

mod common;

use std::sync::Arc;

use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::model::load_robot_dir;
use manyhands::trajectory::timing::{time_polyline, TimedPath, TimingLimits};
use manyhands::Robot;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

/// Relative tolerance of the limit checks (issue 25).
const TOL: f64 = 1e-6;

fn robot(name: &str) -> Arc<Robot> {
    load_robot_dir(&common::root().join("robots"))
        .expect("robots")
        .get(name)
        .cloned()
        .expect("robot")
}

fn robot_limits(r: &Robot, vars: &[usize]) -> TimingLimits {
    TimingLimits {
        velocity: vars.iter().map(|&v| r.velocity_limit(v)).collect(),
        acceleration: vars.iter().map(|&v| r.acceleration_limit(v)).collect(),
    }
}

/// Distance of `q` from the segment a–b.
fn off_segment(q: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| y - x).collect();
    let dd: f64 = d.iter().map(|x| x * x).sum();
    let t = if dd > 0.0 {
        (q.iter()
            .zip(a)
            .zip(&d)
            .map(|((q, a), d)| (q - a) * d)
            .sum::<f64>()
            / dd)
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    q.iter()
        .zip(a)
        .zip(&d)
        .map(|((q, a), d)| (q - a - t * d).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Every check of issue 25 on one timed path sampled every `period` s.
fn assert_valid(label: &str, tp: &TimedPath, limits: &TimingLimits, period: f64) {
    let wps = tp.waypoints();
    let pts = tp.sample(period, "sample_period").expect("sample");
    assert!(pts.len() >= 2 || tp.duration == 0.0, "{label}");
    let (first, last) = (&pts[0], &pts[pts.len() - 1]);
    assert_eq!(first.time, 0.0);
    assert!((last.time - tp.duration).abs() < 1e-12, "{label}");
    for p in [first, last] {
        assert!(
            p.velocities.iter().all(|v| v.abs() < 1e-12),
            "{label}: not at rest"
        );
    }
    for (j, (&a, &b)) in first.positions.iter().zip(&wps[0]).enumerate() {
        assert!((a - b).abs() < 1e-12, "{label}: start joint {j}");
    }
    for (j, (&a, &b)) in last.positions.iter().zip(&wps[wps.len() - 1]).enumerate() {
        assert!((a - b).abs() < 1e-9, "{label}: end joint {j}");
    }
    let times = &tp.waypoint_times;
    assert!(times.windows(2).all(|w| w[1] >= w[0]), "{label}: times");
    for (i, p) in pts.iter().enumerate() {
        for j in 0..p.positions.len() {
            assert!(
                p.velocities[j].abs() <= limits.velocity[j] * (1.0 + TOL),
                "{label}: point {i} joint {j}: velocity {} > {}",
                p.velocities[j],
                limits.velocity[j]
            );
            assert!(
                p.accelerations[j].abs() <= limits.acceleration[j] * (1.0 + TOL),
                "{label}: point {i} joint {j}: acceleration {} > {}",
                p.accelerations[j],
                limits.acceleration[j]
            );
        }
        // On the segment the waypoint times say it is on (the checked polyline).
        let k =
            (times.partition_point(|&t| t <= p.time).max(1) - 1).min(wps.len().saturating_sub(2));
        let off = off_segment(&p.positions, &wps[k], &wps[(k + 1).min(wps.len() - 1)]);
        assert!(off < 1e-9, "{label}: point {i} is {off} off segment {k}");
    }
    // The velocities are those of the positions (central differences), and the accelerations
    // those of the velocities, where both neighbours are one period away.
    for w in pts.windows(3) {
        let dt = w[2].time - w[0].time;
        if (dt - 2.0 * period).abs() > 1e-12 {
            continue;
        }
        for j in 0..w[1].positions.len() {
            let v = (w[2].positions[j] - w[0].positions[j]) / dt;
            let vmax = limits.velocity[j];
            // Second-order error of the difference: at most a_max · period.
            assert!(
                (v - w[1].velocities[j]).abs() <= limits.acceleration[j] * period + 1e-9 * vmax,
                "{label}: velocity of joint {j} at {} is {} but positions move at {v}",
                w[1].time,
                w[1].velocities[j]
            );
        }
    }
}

fn random_path(r: &Robot, vars: &[usize], n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            vars.iter()
                .map(|&v| r.var_limits(v).sample(&mut rng))
                .collect()
        })
        .collect()
}

#[test]
fn random_paths_of_armar_and_justin_respect_the_limits() {
    for name in ["armar", "justin"] {
        let r = robot(name);
        // The shipped joint-limits file is read with the robot.
        assert!(
            r.dynamics.iter().all(|d| d.acceleration.is_some()),
            "{name}"
        );
        let all: Vec<usize> = (0..r.dof()).collect();
        let arm = r
            .groups
            .iter()
            .find(|g| g.name == "right_arm")
            .expect("right_arm")
            .vars
            .clone();
        for (vars, label) in [(all, "all"), (arm, "right_arm")] {
            let limits = robot_limits(&r, &vars);
            for seed in 0..8 {
                let n = 2 + (seed as usize * 3) % 11;
                let path = random_path(&r, &vars, n, seed);
                let tp = time_polyline(&path, &limits, &[]).expect("timed");
                assert!(tp.duration > 0.0);
                assert_valid(&format!("{name}/{label}/{seed}"), &tp, &limits, 0.01);
                // Half the velocity and acceleration: no faster than before.
                let slow = limits.scaled(0.5, 0.5).expect("scaled");
                let ts = time_polyline(&path, &slow, &[]).expect("timed");
                assert!(ts.duration > tp.duration);
                assert_valid(&format!("{name}/{label}/{seed}/scaled"), &ts, &slow, 0.013);
            }
        }
    }
}

#[test]
fn rest_points_and_collinear_waypoints() {
    let r = robot("armar");
    let vars: Vec<usize> = (0..r.dof()).collect();
    let limits = robot_limits(&r, &vars);
    let mut path = random_path(&r, &vars, 2, 9);
    // A waypoint in the middle of the line: passed at speed, unless it is a rest point.
    let mid: Vec<f64> = path[0]
        .iter()
        .zip(&path[1])
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    path.insert(1, mid);
    let through = time_polyline(&path, &limits, &[]).expect("timed");
    let direct = time_polyline(&[path[0].clone(), path[2].clone()], &limits, &[]).expect("timed");
    assert!((through.duration - direct.duration).abs() < 1e-9 * direct.duration);
    let at = through.state_at(through.waypoint_times[1]);
    assert!(at.velocities.iter().any(|v| v.abs() > 1e-3));
    let stop = time_polyline(&path, &limits, &[1]).expect("timed");
    assert!(stop.duration > through.duration);
    let at = stop.state_at(stop.waypoint_times[1]);
    assert!(at.velocities.iter().all(|v| v.abs() < 1e-9));
    assert_valid("rest", &stop, &limits, 0.01);
}

#[test]
fn durations_match_toppra_within_two_percent() {
    let text =
        std::fs::read_to_string(common::root().join("tests/data/timing/toppra_fixture.json"))
            .expect("fixture");
    let f: Value = serde_json::from_str(&text).expect("json");
    let cases = f["cases"].as_array().expect("cases");
    assert!(cases.len() >= 10);
    for c in cases {
        let name = c["name"].as_str().expect("name");
        let wps: Vec<Vec<f64>> = serde_json::from_value(c["waypoints"].clone()).expect("wps");
        let limits = TimingLimits {
            velocity: serde_json::from_value(c["max_velocity"].clone()).expect("v"),
            acceleration: serde_json::from_value(c["max_acceleration"].clone()).expect("a"),
        };
        // The fixture's limits are the robot's (URDF velocity, joint_limits.yaml acceleration).
        if let Some(rn) = c["robot"].as_str() {
            let r = robot(rn);
            let names: Vec<String> = serde_json::from_value(c["joint_names"].clone()).expect("n");
            let vars: Vec<usize> = names.iter().map(|n| r.var(n).expect("joint")).collect();
            assert_eq!(robot_limits(&r, &vars), limits, "{name}");
        }
        let tp = time_polyline(&wps, &limits, &[]).expect("timed");
        let reference = c["toppra_duration"].as_f64().expect("duration");
        let ratio = tp.duration / reference;
        eprintln!(
            "{name}: {:.6} s, toppra {reference:.6} s, ratio {ratio:.5}",
            tp.duration
        );
        assert!(
            (ratio - 1.0).abs() <= 0.02,
            "{name}: {} s here, toppra {reference} s (ratio {ratio})",
            tp.duration
        );
        assert_valid(name, &tp, &limits, 0.01);
    }
}

/// The MotionBenchMaker Panda (skipped without the data, as tests/mbm.rs): its URDF velocity
/// limits and the default acceleration.
#[test]
fn random_paths_of_the_benchmark_panda() {
    let Some(dir) = data_for_test() else { return };
    let r = Robot::from_files(
        &dir.join("panda/panda_spherized.urdf"),
        Some(&dir.join("panda/panda.srdf")),
    )
    .expect("panda");
    let vars: Vec<usize> = (0..r.dof()).collect();
    let limits = robot_limits(&r, &vars);
    for seed in 0..8 {
        let path = random_path(&r, &vars, 2 + seed as usize * 4, seed);
        let tp = time_polyline(&path, &limits, &[]).expect("timed");
        assert_valid(&format!("panda/{seed}"), &tp, &limits, 0.01);
    }
}
