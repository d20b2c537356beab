use manyhands::kinematics::{FkModel, Frame};
use manyhands::model::{data_root, load_robot_dir};
fn main() {
    let lib = load_robot_dir(&data_root().join("robots")).unwrap();
    let r = &lib["armar"];
    let m = FkModel::new(r);
    let mut out = vec![Frame::identity(); r.links.len()];
    let q = r.named_config("home").unwrap();
    let n = 2_000_000;
    let t = std::time::Instant::now();
    let mut qq = q.clone();
    for i in 0..n {
        qq[16] = -(i % 100) as f64 * 0.01;
        m.compute(&Frame::identity(), &qq, &mut out);
        std::hint::black_box(&out);
    }
    println!("FkModel {:.1} ns", t.elapsed().as_nanos() as f64 / n as f64);
}
