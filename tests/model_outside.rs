//! Outside robots (written by others) load with their SRDFs.

use std::path::PathBuf;

use manyhands::Robot;

fn mbm(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/benchmarks/mbm")
        .join(p)
}

#[test]
fn panda_loads_with_srdf() {
    let r = Robot::from_files(
        &mbm("panda/panda_spherized.urdf"),
        Some(&mbm("panda/panda.srdf")),
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
    let r = Robot::from_files(
        &mbm("baxter/baxter_spherized.urdf"),
        Some(&mbm("baxter/baxter.srdf")),
    )
    .unwrap();
    assert_eq!(r.dof(), 14);
    assert_eq!(r.group("both_arms").unwrap().vars.len(), 14);
    assert_eq!(r.group("left_arm").unwrap().vars.len(), 7);
    assert_eq!(r.end_effectors.len(), 2);
}
