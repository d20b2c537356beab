//! The forward-kinematics paths agree: `forward` (isometries), `FkModel` (frames), the reduced
//! `FkModel` (fixed joints folded, links mounted on the last moving link), and the single-link
//! `link_pose` and `FkPath`; on the shipped robots and the suite's own `tests/robots/twin_arms`,
//! and on the MotionBenchMaker Panda and Baxter when their data is there.

use std::path::PathBuf;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::geometry::Pose;
use manyhands::kinematics::{forward, link_pose, FkModel, FkPath, Frame};
use manyhands::Robot;

/// The shipped robots and the suite's own sphere robot (always there).
fn robots() -> Vec<Robot> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut v = Vec::new();
    for (dir, name) in [
        ("robots", "armar"),
        ("robots", "justin"),
        ("tests/robots", "twin_arms"),
    ] {
        let d = root.join(dir);
        v.push(
            Robot::from_files(
                &d.join(format!("{name}.urdf")),
                Some(&d.join(format!("{name}.srdf"))),
            )
            .unwrap(),
        );
    }
    v
}

/// The MotionBenchMaker Panda and Baxter (`None` without the data: the test is skipped).
fn mbm_robots() -> Option<Vec<Robot>> {
    let mbm = data_for_test()?;
    Some(
        ["panda", "baxter"]
            .iter()
            .map(|name| {
                Robot::from_files(
                    &mbm.join(format!("{name}/{name}_spherized.urdf")),
                    Some(&mbm.join(format!("{name}/{name}.srdf"))),
                )
                .unwrap()
            })
            .collect(),
    )
}

/// A configuration drawn uniformly within the joint limits.
fn random_config(r: &Robot, rng: &mut ChaCha8Rng) -> Vec<f64> {
    (0..r.dof())
        .map(|v| {
            let l = r.var_limits(v);
            rng.random_range(l.lower..=l.upper)
        })
        .collect()
}

#[test]
fn all_fk_paths_agree() {
    fk_paths_agree(robots());
}

#[test]
fn all_fk_paths_agree_on_the_benchmark_robots() {
    let Some(robots) = mbm_robots() else { return };
    fk_paths_agree(robots);
}

fn fk_paths_agree(robots: Vec<Robot>) {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for r in robots {
        let full = FkModel::new(&r);
        let reduced = FkModel::reduced(&r);
        let base = manyhands::geometry::iso_from_rpy([0.3, -0.2, 0.1], [0.1, 0.2, -0.7]);
        let mut iso = vec![Pose::identity(); r.links.len()];
        let mut f1 = vec![Frame::identity(); r.links.len()];
        let mut f2 = vec![Frame::identity(); r.links.len()];
        let paths: Vec<FkPath> = (0..r.links.len()).map(|l| FkPath::new(&r, l)).collect();
        for _ in 0..200 {
            let q = random_config(&r, &mut rng);
            forward(&r, &base, &q, &mut iso);
            full.compute(&Frame::from_pose(&base), &q, &mut f1);
            reduced.compute(&Frame::from_pose(&base), &q, &mut f2);
            for l in 0..r.links.len() {
                let (rep, off) = reduced.mount(l);
                let m = match off {
                    Some(o) => f2[rep].mul(&o),
                    None => f2[rep],
                };
                let want = Frame::from_pose(&iso[l]);
                for got in [f1[l], m] {
                    assert!(
                        (got.t - want.t).norm() < 1e-12,
                        "{} link {}",
                        r.name,
                        r.links[l].name
                    );
                    assert!(
                        (got.rot - want.rot).abs().max() < 1e-12,
                        "{} link {}",
                        r.name,
                        r.links[l].name
                    );
                }
                let single = base * link_pose(&r, &q, l);
                assert!((single.translation.vector - iso[l].translation.vector).norm() < 1e-12);
                let path = base * paths[l].pose(&q);
                assert!(
                    (path.translation.vector - iso[l].translation.vector).norm() < 1e-12
                        && path.rotation.angle_to(&iso[l].rotation) < 1e-9,
                    "{} link {}: FkPath",
                    r.name,
                    r.links[l].name
                );
            }
        }
    }
}

/// `FkModel::update` (recompute what changed since the last configuration) gives the frames of
/// `compute` bit for bit, full and reduced models, when a random subset of the variables moves
/// (none, one, an arm's worth, all), a mimic joint's master included.
#[test]
fn incremental_fk_matches_full_bit_for_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for r in robots() {
        for model in [FkModel::new(&r), FkModel::reduced(&r)] {
            let base = Frame::from_pose(&manyhands::geometry::iso_from_rpy(
                [0.1, 0.4, -0.3],
                [0.2, -0.1, 0.5],
            ));
            let n = r.links.len();
            let mut q = random_config(&r, &mut rng);
            let mut last = q.clone();
            let mut inc = vec![Frame::identity(); n];
            let mut full = vec![Frame::identity(); n];
            model.compute(&base, &q, &mut inc);
            for round in 0..300 {
                let other = random_config(&r, &mut rng);
                let share = [0.0, 0.1, 0.4, 1.0][round % 4];
                for (v, x) in q.iter_mut().enumerate() {
                    if rng.random::<f64>() < share {
                        *x = other[v];
                    }
                }
                model.update(&base, &q, &mut last, &mut inc);
                model.compute(&base, &q, &mut full);
                assert_eq!(last, q);
                for l in 0..n {
                    assert!(
                        inc[l] == full[l],
                        "{} link {} round {round}",
                        r.name,
                        r.links[l].name
                    );
                }
            }
        }
    }
}

/// `FkModel::reach_ball`: a sphere riding on a (computed) link stays inside the ball the model gives for
/// each of the link's ancestors, in every configuration within the limits (here 300 random
/// ones per robot, all links, all ancestors), and the ball is fixed in the ancestor's frame.
#[test]
fn reach_balls_hold_their_link_in_every_configuration() {
    reach_balls_hold(robots());
}

#[test]
fn reach_balls_hold_on_the_benchmark_robots() {
    let Some(robots) = mbm_robots() else { return };
    reach_balls_hold(robots);
}

fn reach_balls_hold(robots: Vec<Robot>) {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for r in robots {
        let reduced = FkModel::reduced(&r);
        let mut f = vec![Frame::identity(); r.links.len()];
        let (centre, radius) = (nalgebra::Vector3::new(0.05, -0.03, 0.02), 0.04);
        let mut balls = Vec::new();
        for l in 0..r.links.len() {
            for a in reduced.ancestors(l) {
                if let Some(b) = reduced.reach_ball(&r, l, &centre, radius, a) {
                    balls.push((l, a, b));
                }
            }
        }
        assert!(
            balls.len() > r.links.len(),
            "{}: balls for links and ancestors",
            r.name
        );
        for _ in 0..300 {
            let q = random_config(&r, &mut rng);
            reduced.compute(&Frame::identity(), &q, &mut f);
            for &(l, a, (c, rad)) in &balls {
                // The sphere is given in the frame of the computed link the link rides on.
                let frame = f[reduced.mount(l).0];
                // The sphere's centre in the ancestor's frame.
                let inv = f[a].to_pose().inverse();
                let p = inv * nalgebra::Point3::from(frame.transform_point(&centre));
                assert!(
                    (p.coords - c).norm() + radius <= rad + 1e-9,
                    "{}: link {} about ancestor {}: {} + {radius} > {rad}",
                    r.name,
                    r.links[l].name,
                    r.links[a].name,
                    (p.coords - c).norm()
                );
            }
        }
    }
}
