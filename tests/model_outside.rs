//! Outside robots (written by others) load with their SRDFs: the MotionBenchMaker Panda and
//! Baxter (skipped without the data, see `manyhands::benchmark::mbm_data`), and the suite's own
//! sphere robot `tests/robots/twin_arms.urdf` (always).

use std::path::{Path, PathBuf};

use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::Robot;

fn mbm(dir: &Path, p: &str) -> PathBuf {
    dir.join(p)
}

#[test]
fn panda_loads_with_srdf() {
    let Some(dir) = data_for_test() else { return };
    let r = Robot::from_files(
        &mbm(&dir, "panda/panda_spherized.urdf"),
        Some(&mbm(&dir, "panda/panda.srdf")),
    )
    .unwrap();
    assert_eq!(r.dof(), 7);
    assert!(r.group("panda_arm").and_then(|g| g.chain).is_some());
    assert!(r.named_config("ready").is_some());
    let spheres: usize = r.links.iter().map(|l| l.collision.len()).sum();
    assert_eq!(spheres, 59);
    assert!(r.is_disabled(
        r.link("panda_link0").unwrap(),
        r.link("panda_link1").unwrap()
    ));
}

#[test]
fn baxter_loads_with_srdf() {
    let Some(dir) = data_for_test() else { return };
    let r = Robot::from_files(
        &mbm(&dir, "baxter/baxter_spherized.urdf"),
        Some(&mbm(&dir, "baxter/baxter.srdf")),
    )
    .unwrap();
    assert_eq!(r.dof(), 14);
    assert_eq!(r.group("both_arms").unwrap().vars.len(), 14);
    assert_eq!(r.group("left_arm").unwrap().vars.len(), 7);
    assert_eq!(r.end_effectors.len(), 2);
}

#[test]
fn twin_arms_loads_with_srdf() {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
    let r = Robot::from_files(&d.join("twin_arms.urdf"), Some(&d.join("twin_arms.srdf"))).unwrap();
    assert_eq!(r.dof(), 14);
    assert_eq!(r.group("both_arms").unwrap().vars.len(), 14);
    for side in ["left", "right"] {
        let g = r.group(&format!("{side}_arm")).unwrap();
        assert_eq!(g.vars.len(), 7);
        assert!(g.chain.is_some());
    }
    assert!(r.named_config("ready").is_some());
    assert_eq!(r.end_effectors.len(), 2);
    let spheres: usize = r.links.iter().map(|l| l.collision.len()).sum();
    assert_eq!(spheres, 4 + 2 * (3 + 6 * 3 + 4 + 6));
    assert!(r.is_disabled(r.link("left_link5").unwrap(), r.link("left_link6").unwrap()));
}
